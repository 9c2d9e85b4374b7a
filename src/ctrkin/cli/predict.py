"""`ctrkin predict`: run a trained model over a dataset; a table of predictions on stdout or in a file.

    ctrkin predict models/fk --data data/quick                         # CSV on stdout
    ctrkin predict models/fk --data data/quick --out fk_pred.parquet   # .csv, .parquet or .json
    ctrkin predict models/ik --data data/quick --out ik_pred.csv       # adds in_workspace, reason

FK writes pred_x .. pred_qy; IK writes pred_alpha_1 .. pred_beta_N, in_workspace and reason, beside
sequence_id and step. The dataset must come from the model's robot.
"""

from __future__ import annotations

from pathlib import Path

import click
import pandas as pd

from ctrkin.cli.common import check_output, overwrite_option, say
from ctrkin.util.files import atomic_path

FORMATS = (".csv", ".parquet", ".json")


def write_table(table: pd.DataFrame, path: Path) -> None:
    """Write `table` atomically in the format of the extension of `path` (one of FORMATS); JSON is a
    list of rows."""
    suffix = path.suffix.lower()
    with atomic_path(path) as tmp:
        if suffix == ".csv":
            table.to_csv(tmp, index=False)
        elif suffix == ".parquet":
            table.to_parquet(tmp, index=False)
        elif suffix == ".json":
            table.to_json(tmp, orient="records", indent=1)
        else:
            raise ValueError(f"unsupported extension {suffix!r}")


def _check_format(_ctx: click.Context, _param: click.Parameter, value: str | None) -> str | None:
    if value is not None and Path(value).suffix.lower() not in FORMATS:
        raise click.BadParameter(f"{value!r}: the extension chooses the format, one of {', '.join(FORMATS)}")
    return value


@click.command("predict", epilog="""\b
Examples:
  ctrkin predict models/fk --data data/paper > fk.csv
  ctrkin predict models/fk --data data/paper --out fk.parquet""")
@click.argument("model_dir", type=click.Path(exists=True, file_okay=False))
@click.option("--data", "data_dir", required=True, type=click.Path(exists=True, file_okay=False),
              help="Dataset folder (from the model's robot).")
@click.option("--out", "out_file", default=None, type=click.Path(dir_okay=False), callback=_check_format,
              help="File to write, format by extension: .csv, .parquet or .json (a list of rows). "
              "Default: CSV on stdout.")
@overwrite_option()
def predict_cmd(model_dir: str, data_dir: str, out_file: str | None, overwrite: bool) -> None:
    """Predict every sample of a dataset with MODEL_DIR."""
    from ctrkin.data import Dataset
    from ctrkin.inference import Kinematics

    if out_file is not None:
        check_output(out_file, overwrite)
    kin = Kinematics.load(model_dir)
    ds = Dataset.load(data_dir)
    res = kin.predict(ds)
    table = ds.frame[["sequence_id", "step"]].copy()
    y = res if kin.task == "fk" else res.joints
    for k, name in enumerate(kin.layout.output_names):
        table[f"pred_{name}"] = y[:, k]
    if kin.task == "ik":
        table["in_workspace"] = res.in_workspace
        table["reason"] = res.reasons
    if out_file is None:
        click.echo(table.to_csv(index=False), nl=False)
        msg = f"{len(table)} predictions"
    else:
        write_table(table, Path(out_file))
        msg = f"wrote {len(table)} predictions to {out_file}"
    if kin.task == "ik":
        msg += f" ({int((~res.in_workspace).sum())} targets outside the trained workspace)"
    say(msg, err=out_file is None)
