"""`ctrkin predict`: run a trained model over a dataset and write a CSV of predictions.

    ctrkin predict models/fk --data data/quick --out fk_pred.csv
    ctrkin predict models/ik --data data/quick --out ik_pred.csv     # adds in_workspace, reason

FK writes pred_x .. pred_qy; IK writes pred_alpha_1 .. pred_beta_N, in_workspace and reason, beside
sequence_id and step. The dataset must come from the model's robot.
"""

from __future__ import annotations

import click

from ctrkin.cli.common import check_output, overwrite_option
from ctrkin.util.files import atomic_path


@click.command("predict")
@click.argument("model_dir", type=click.Path(exists=True, file_okay=False))
@click.option("--data", "data_dir", required=True, type=click.Path(exists=True, file_okay=False))
@click.option("--out", "out_file", required=True, type=click.Path(dir_okay=False), help="CSV file.")
@overwrite_option()
def predict_cmd(model_dir: str, data_dir: str, out_file: str, overwrite: bool) -> None:
    """Predict every sample of a dataset with MODEL_DIR."""
    from ctrkin.data import Dataset
    from ctrkin.inference import Kinematics

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
    with atomic_path(out_file) as tmp:
        table.to_csv(tmp, index=False)
    msg = f"wrote {len(table)} predictions to {out_file}"
    if kin.task == "ik":
        msg += f" ({int((~res.in_workspace).sum())} targets outside the trained workspace)"
    click.echo(msg)
