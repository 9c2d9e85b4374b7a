"""A small real set under `ctrkin train`'s defaults (issue 22): the comet-lab NDI logs (63 samples in
four files, two-tube nylon robot), imported with the documented profile and trained as
`ctrkin train --task fk --data data/ndi` trains them (TrainConfig's defaults, the dataset's split by
whole files), then every part predicted by the saved model. Prints how training ended (epochs,
optimiser steps, why it stopped) and the mean tip distance on the training, validation and test
files, so a budget that under-fits shows as a training error near the held-out one.

    python benchmarks/bench_small_set.py                        # logs in ../shared/realdata/comet-lab
    python benchmarks/bench_small_set.py --data DIR --seeds 0 1 2

The logs are read from --data at run time (docs/real_robot.md says where to get them); nothing is
copied. Runs on any ctrkin version with the same API (older ones lack the fit summary: shown "-").
Ends with one JSON line of its figures.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ctrkin.data.profile import load_profile
from ctrkin.data.profile_import import import_with_profile
from ctrkin.data.splits import Split
from ctrkin.inference import Kinematics
from ctrkin.robots.robot import Robot
from ctrkin.training import TrainConfig, train

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO.parent / "shared" / "realdata" / "comet-lab"


def part_errors(model: Path, ds) -> dict[str, float]:
    """Mean tip distance (mm) of the saved model on each part of its own split."""
    kin = Kinematics.load(model)
    pred = np.asarray(kin.predict(ds))
    err = np.linalg.norm(pred[:, :3] - ds.poses()[:, :3], axis=1)
    split = Split.load(model / "split.json")
    return {part: float(np.mean(err[split.part(part)])) for part in ("train", "val", "test")
            if len(split.part(part))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder holding ndi-2tube/")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    files = sorted((args.data / "ndi-2tube").glob("*.csv"))
    if not files:
        print(f"skipped: no NDI logs in {args.data / 'ndi-2tube'} (pass --data)")
        sys.exit(0)
    robot = Robot.from_toml(REPO / "examples" / "robots" / "comet_nylon_ndi.toml")
    ds = import_with_profile(files, load_profile(REPO / "examples" / "profiles" / "comet_ndi.toml",
                                                 robot.n_tubes), robot)
    rows, res = [], {"samples": len(ds.frame)}
    print(f"NDI set: {len(ds.frame)} samples in {len(files)} files; TrainConfig defaults, task fk")
    print(f"{'seed':>4s} {'epochs':>6s} {'steps':>6s} {'stopped by':>12s} {'train mm':>9s} {'val mm':>8s} "
          f"{'test mm':>8s} {'s':>6s}  verdict")
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            out = Path(tmp) / f"fk{seed}"
            t0 = time.perf_counter()
            result = train(ds, TrainConfig(task="fk", seed=seed, threads=args.threads), out, progress=False)
            secs = time.perf_counter() - t0
            tr = result.metrics["training"]
            fit = tr.get("fit", {})
            errs = part_errors(out, ds)
            stopped = tr.get("stopped_by", "patience" if tr["early_stopped"] else "max_epochs")
            rows.append({"seed": seed, "epochs": tr["epochs"], "steps": tr.get("steps"),
                         "stopped_by": stopped,
                         **{f"{k}_mm": round(v, 3) for k, v in errs.items()}, "seconds": round(secs, 1),
                         "verdict": fit.get("verdict", "-")})
            r = rows[-1]
            print(f"{seed:4d} {r['epochs']:6d} {r['steps'] or '-'!s:>6s} {r['stopped_by']:>12s} "
                  f"{r.get('train_mm', float('nan')):9.3f} {r.get('val_mm', float('nan')):8.3f} "
                  f"{r.get('test_mm', float('nan')):8.3f} {secs:6.1f}  {r['verdict']}")
    for key in ("train_mm", "val_mm", "test_mm", "epochs"):
        vals = [r[key] for r in rows if key in r]
        if vals:
            res[f"median_{key}"] = round(statistics.median(vals), 3)
    res["seeds"] = len(rows)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
