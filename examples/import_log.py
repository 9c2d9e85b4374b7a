"""Import your own robot's log (a CSV with a header, one row per tracker reading) into a dataset,
clean it as the paper did (average repeated readings, drop encoder glitches) and split it.

    python examples/import_log.py --demo --out data/mylog        # writes a small log first, then imports it
    python examples/import_log.py robot_log.csv --robot my_robot.toml --out data/mylog

The column mapping below is the one of docs/data.md ("Importing your own robot log"): change the
names on the left to your log's. For logs without a header (columns known by position, carriage
travel instead of β, padding rows) write an import profile instead: docs/real_robot.md and
`examples/profiles/`.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

import ctrkin
from ctrkin.data.dataset import Dataset
from ctrkin.data.importer import ImportConfig, import_csv
from ctrkin.data.splits import split_by_sequence

# log column -> ctrkin field (docs/data.md: Columns)
MAPPING = {"enc_rot_inner": "alpha_1", "enc_rot_outer": "alpha_2", "enc_lin_inner": "beta_1",
           "enc_lin_outer": "beta_2", "px": "x", "py": "y", "pz": "z", "stamp": "time", "run": "sequence_id"}


def demo_log(path: Path, robot: ctrkin.Robot, runs: int = 4, steps: int = 30, readings: int = 5) -> Path:
    """A log as a lab might write it: radians and metres, an x, y, z, w quaternion, `readings` tracker
    readings per joint sample, one `run` label per recording (the TCM's tips with 0.02 mm noise)."""
    rng = np.random.default_rng(0)
    parts = []
    for run in range(runs):
        a = 4.0 * np.arange(steps)
        Q = np.c_[a, np.full(steps, 40.0 * run), np.full(steps, -15.0), np.full(steps, -5.0)]
        p = ctrkin.follow(robot, Q).tip_poses
        rep = np.repeat(np.arange(steps), readings)
        parts.append(pd.DataFrame({
            "stamp": run * 100 + rep * 0.5 + np.tile(np.arange(readings) * 0.01, steps), "run": run,
            "enc_rot_inner": np.radians(Q[rep, 0]), "enc_rot_outer": np.radians(Q[rep, 1]),
            "enc_lin_inner": Q[rep, 2] / 1000, "enc_lin_outer": Q[rep, 3] / 1000,
            **{c: (p[rep, k] + rng.normal(scale=0.02, size=len(rep))) / 1000
               for k, c in enumerate(("px", "py", "pz"))},
            "ox": p[rep, 4], "oy": p[rep, 5], "oz": 0.0, "ow": p[rep, 3]}))
    pd.concat(parts).to_csv(path, index=False, float_format="%.12g")
    return path


def main(argv: list[str] | None = None) -> dict[str, object]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", nargs="?", help="the log (CSV with a header)")
    ap.add_argument("--robot", default="paper", help="robot TOML file, or a built-in robot's name")
    ap.add_argument("--demo", action="store_true", help="write a small demonstration log and import it")
    ap.add_argument("--out", required=True, help="dataset folder to write")
    args = ap.parse_args(argv)
    if bool(args.log) == args.demo:
        ap.error("give a log file or --demo")

    robot = ctrkin.load_robot(args.robot)
    with tempfile.TemporaryDirectory() as tmp:
        log = demo_log(Path(tmp) / "robot_log.csv", robot) if args.demo else Path(args.log)
        config = ImportConfig.from_mapping(MAPPING, quaternion_columns=("ox", "oy", "oz", "ow"),
                                           quaternion_order="xyzw", angle_unit="rad", beta_unit="m",
                                           position_unit="m")
        ds = import_csv(log, robot, config)
    ds.split = split_by_sequence(ds.frame["sequence_id"].to_numpy(), seed=0)   # whole sequences
    ds.save(args.out)
    back = Dataset.load(args.out)
    cleaning = back.meta["cleaning"]
    print(f"imported {len(back.frame)} samples in {back.frame['sequence_id'].nunique()} sequences -> "
          f"{args.out}; {cleaning.get('samples_averaged', 0)} readings averaged, "
          f"{cleaning.get('joint_glitches', 0)} encoder glitches, {cleaning.get('snaps', 0)} snaps")
    noise = back.meta.get("noise", {}).get("position_std_mm")
    if noise is not None:
        print(f"tracker noise from the repeated readings: {np.round(noise, 3).tolist()} mm")
    split = back.get_split()
    print(f"split by sequence: {len(split.train)} / {len(split.val)} / {len(split.test)} rows")
    return {"samples": len(back.frame), "sequences": int(back.frame["sequence_id"].nunique()),
            "noise_mm": noise}


if __name__ == "__main__":
    main()
