"""`ctrkin predict`: run a trained model over a dataset, an FK model over a file of joints, or an IK
model over a file of target poses; a table of predictions on stdout or in a file.

    ctrkin predict models/fk --data data/quick                         # CSV on stdout
    ctrkin predict models/fk --data data/quick --out fk_pred.parquet   # .csv, .parquet or .json
    ctrkin predict models/fk --joints joints.csv --out tips.csv        # FK for a file of joints
    ctrkin predict models/ik --data data/quick --out ik_pred.csv       # adds the IK flags
    ctrkin predict models/ik --poses targets.csv --out joints.csv      # IK for target poses
    ctrkin predict models/ik_follow --poses targets.csv --start-joints 0,0,-20,-5

FK writes pred_x .. pred_qy; every IK family writes pred_alpha_1 .. pred_beta_N (the absolute joints,
deg and mm; the follow IK too, whose network learns joint steps) and per target in_workspace, reason,
projected (the network's joints were outside the joint limits and were moved onto them) and jump (an
α changed by more than 20° for a target less than 1 mm away), plus residual_mm for a refined IK;
beside sequence_id and step. The dataset must come from the model's robot. A joints file (.csv or
.parquet) has the columns alpha_1 .. alpha_N (deg), beta_1 .. beta_N (mm), one row a configuration in
time order (an FK model's history runs along it); a poses file has the columns x, y, z (mm), q0, qx,
qy (unit quaternion, qz = 0) in the frame of the model's training data, one row a target in time
order; both take an optional sequence_id (a new run where it changes) and step.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click
import numpy as np
import pandas as pd

from ctrkin.cli.common import output_file, overwrite_option, parse_floats, say
from ctrkin.cli.from_config import config_options, option
from ctrkin.data.schema import INDEX_COLUMNS, POSE_COLUMNS
from ctrkin.errors import DatasetError, ModelError
from ctrkin.robots.robot import joint_names
from ctrkin.util.files import atomic_path

FORMATS = (".csv", ".parquet", ".json")
POSE_FORMATS = (".csv", ".parquet")


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


@dataclass(frozen=True, kw_only=True)
class PredictConfig:
    """What `ctrkin predict` runs a model on (the argument and one option per field): one of a
    dataset, a file of joints or a file of target poses. Checked on construction: usage errors."""

    model_dir: str = option("A model folder (ctrkin train).", path="folder", argument=True)
    data: str | None = option("Dataset folder (from the model's robot).", None, path="folder")
    joints: str | None = option(
        "FK model: a .csv or .parquet file of joints, columns alpha_1..alpha_N (deg), beta_1..beta_N (mm) "
        "(optional sequence_id, step), one row a step in time order.", None, path="file")
    poses: str | None = option(
        "IK model: a .csv or .parquet file of target poses, columns x, y, z (mm), q0, qx, qy (optional "
        "sequence_id, step), in the frame of the model's training data.", None, path="file")
    start_joints: str | None = option(
        "Follow IK (follow_mlp) with --poses: the robot's joints (deg, mm) at the start of every sequence "
        "(default: those of the nearest training target).", None, metavar="A1,..,AN,B1,..,BN")
    out: str | None = option("File to write, format by extension: .csv, .parquet or .json (a list of rows). "
                             "Default: CSV on stdout.", None, path="out")

    def __post_init__(self) -> None:
        if self.out is not None and Path(self.out).suffix.lower() not in FORMATS:
            raise click.BadParameter(f"{self.out!r}: the extension chooses the format, one of "
                                     f"{', '.join(FORMATS)}", param_hint=("--out",))
        if sum(x is not None for x in (self.data, self.joints, self.poses)) != 1:
            raise click.UsageError("give either --data (a dataset), --joints (a file of joints, FK) or "
                                   "--poses (a file of IK target poses)")
        if self.start_joints is not None and self.poses is None:
            raise click.UsageError("--start-joints goes with --poses")
        for path, hint in ((self.poses, "--poses"), (self.joints, "--joints")):
            if path is not None and Path(path).suffix.lower() not in POSE_FORMATS:
                raise click.BadParameter(f"{path!r}: a .csv or .parquet file", param_hint=hint)


@click.command("predict", epilog="""\b
Examples:
  ctrkin predict models/fk --data data/paper > fk.csv
  ctrkin predict models/fk --data data/paper --out fk.parquet
  ctrkin predict models/fk --joints joints.csv --out tips.csv
  ctrkin predict models/ik --poses targets.csv --out joints.csv
  ctrkin predict models/ik_follow --poses targets.csv --start-joints 0,0,-20,-5""")
@config_options(PredictConfig)
@overwrite_option()
def predict_cmd(overwrite: bool, **settings: Any) -> None:
    """Predict every sample of a dataset (--data), the tips of a file of joints (--joints, FK), or solve
    IK for a file of target poses (--poses), with MODEL_DIR."""
    from ctrkin.inference import Kinematics

    cfg = PredictConfig(**settings)
    model_dir, data_dir, joints_file, poses_file = cfg.model_dir, cfg.data, cfg.joints, cfg.poses
    out_file = cfg.out
    start = None if cfg.start_joints is None else np.array(parse_floats(cfg.start_joints, "--start-joints"))
    if out_file is not None:
        output_file(out_file, "predictions", overwrite, inputs=[model_dir, data_dir, poses_file, joints_file])
    kin = Kinematics.load(model_dir)
    if joints_file is not None:
        if kin.task != "fk":
            raise ModelError(f"--joints needs an FK model; {model_dir} is an IK model (use --poses)")
        joints, table = read_rows(joints_file, joint_names(kin.robot.n_tubes), "joint",
                                  "alpha_i deg, beta_i mm, innermost tube first")
        res: Any = kin.forward(joints, table["sequence_id"].to_numpy() if "sequence_id" in table else None)
    elif poses_file is not None:
        if kin.task != "ik":
            raise ModelError(f"--poses needs an IK model; {model_dir} is an FK model (use --data or "
                             "--joints)")
        poses, table = read_poses(poses_file)
        if start is not None:
            kin.robot.check_joints(start)
        sid = table["sequence_id"].to_numpy() if "sequence_id" in table else None
        res = kin.inverse(poses, sid, start_joints=start)
    else:
        from ctrkin.data import Dataset

        ds = Dataset.load(str(data_dir))
        res = kin.predict(ds)
        table = ds.frame[INDEX_COLUMNS].copy()
    # IK: the absolute joints under their dataset names, whatever the network learns (the follow IK's
    # outputs are joint steps, step_alpha_i: its predictor adds them up)
    fk = kin.task == "fk"
    y, names = (res, kin.layout.output_names) if fk else (res.joints, joint_names(kin.robot.n_tubes))
    for k, name in enumerate(names):
        table[f"pred_{name}"] = y[:, k]
    flags = ""
    if kin.task == "ik":
        table["in_workspace"] = res.in_workspace
        table["reason"] = res.reasons
        table["projected"] = res.projected
        table["jump"] = res.jump
        if res.residual_mm is not None and np.isfinite(res.residual_mm).any():     # a refined IK
            table["residual_mm"] = res.residual_mm
        flags = (f" ({int((~res.in_workspace).sum())} targets outside the trained workspace, "
                 f"{int(np.sum(res.projected))} projected onto the joint limits, "
                 f"{int(np.sum(res.jump))} jumps)")
    if out_file is None:
        click.echo(table.to_csv(index=False), nl=False)
        msg = f"{len(table)} predictions"
    else:
        write_table(table, Path(out_file))
        msg = f"wrote {len(table)} predictions to {out_file}"
    say(msg + flags, err=out_file is None)


def read_poses(path: str) -> tuple[np.ndarray, pd.DataFrame]:
    """A file of IK targets -> (poses (T, 6) mm / unit quaternion, the table of its index columns)
    (read_rows)."""
    return read_rows(path, list(POSE_COLUMNS), "pose", "x, y, z mm; q0, qx, qy the unit quaternion with "
                     "qz = 0")


def read_rows(path: str, columns: list[str], what: str, units: str) -> tuple[np.ndarray, pd.DataFrame]:
    """A .csv or .parquet file of `what` ("pose", "joint") rows -> (its `columns` as (T, C) floats, the
    table of its index columns: sequence_id and step where given, step = row number otherwise).
    Missing columns and non-finite values are refused (DatasetError) with the rows and columns at
    fault; `units` is said beside the columns a file lacks."""
    try:
        frame = pd.read_parquet(path) if path.lower().endswith(".parquet") else pd.read_csv(path)
    except (OSError, ValueError) as e:
        raise DatasetError(f"cannot read the {what}s file {path}: {e}") from None
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise DatasetError(f"{path} lacks {what} column(s) {missing}; it needs {columns} ({units}), found "
                           f"{list(frame.columns)}")
    if frame.empty:
        raise DatasetError(f"{path} has no {what} rows")
    try:
        values = frame[columns].to_numpy(dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise DatasetError(f"{path}: the {what} columns must hold numbers: {e}") from None
    bad = ~np.isfinite(values)
    if bad.any():
        rows = np.nonzero(bad.any(axis=1))[0]
        cols = [c for c, b in zip(columns, bad.any(axis=0), strict=True) if b]
        raise DatasetError(f"{path}: {len(rows)} row(s) with NaN, empty or infinite {what} values, first at "
                           f"data row {rows[0] + 1} (columns {cols}); remove or fill them")
    index = pd.DataFrame({"step": frame["step"] if "step" in frame else np.arange(len(frame))})
    if "sequence_id" in frame:
        index.insert(0, "sequence_id", frame["sequence_id"])
    return values, index
