"""Streaming step latency of a reproduction's learned models (issue 8, goal 4): the paper's LSTM-MLP
FK and IK, the snap-aware FK (lstm_mlp_branch), the IK refined on it (ik_lstm_mlp_refined) and the
follow IK (ik_follow_mlp, the recommended IK; a step includes its sub-steps and the workspace check).

    python benchmarks/bench_streaming.py --run out/reproduce      # after `ctrkin reproduce`

Inputs are the held-out test sequences of the run's paper dataset, fed one step a call (the
control-loop case), one thread. Goals: FK step median <= 30 µs; IK step including the refinement
<= 300 µs (paper: 0.831 ms FK, 0.816 ms IK). For the FK models also the cost of the face: the step
through `Kinematics.step` and directly on its family's predictor (`kin.predictor.step`), in
alternating rounds (`--rounds`), and the median of the rounds' differences. Prints a table and ends
with one JSON line.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ctrkin.data.dataset import Dataset
from ctrkin.inference import Kinematics

MODELS = {"fk_paper": "fk_lstm_mlp", "fk_branch": "fk_lstm_mlp_branch", "ik_paper": "ik_lstm_mlp",
          "ik_refined": "ik_lstm_mlp_refined", "ik_follow": "ik_follow_mlp"}


def _latency_us(kin: Kinematics, xs: np.ndarray, warmup: int = 200, step: Any = None) -> np.ndarray:
    """Per-step times (µs) of `step` (default kin.step) over xs, after a warm-up."""
    step = step or kin.step
    kin.reset()
    for x in xs[:warmup]:
        step(x)
    kin.reset()
    ns = np.empty(len(xs))
    clock = time.perf_counter_ns
    for k, x in enumerate(xs):
        t0 = clock()
        step(x)
        ns[k] = clock() - t0
    return ns / 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", type=Path, default=Path("out/reproduce"), help="a `ctrkin reproduce` folder")
    ap.add_argument("--steps", type=int, default=3000, help="steps per model (IK refined: a fifth)")
    ap.add_argument("--rounds", type=int, default=5, help="face / predictor rounds (FK; 0: none)")
    args = ap.parse_args()
    if not (args.run / "models").is_dir():
        raise SystemExit(f"{args.run}/models not found: run `ctrkin reproduce --out {args.run}` first")
    torch.set_num_threads(1)
    ds = Dataset.load(args.run / "data" / "paper")
    test = ds.get_split().test
    inputs = {"fk": ds.joints()[test], "ik": ds.poses()[test]}
    figures: dict[str, float] = {}
    print(f"{'model':28s} {'median µs':>10s} {'p95 µs':>10s} {'steps':>7s}")
    for key, folder in MODELS.items():
        if not (args.run / "models" / folder).is_dir():
            print(f"{folder:28s} (not in this run)")
            continue
        kin = Kinematics.load(args.run / "models" / folder)
        n = args.steps // 5 if key == "ik_refined" else args.steps
        us = _latency_us(kin, inputs[kin.task][:n])
        figures[f"{key}_step_us_median"] = float(np.median(us))
        figures[f"{key}_step_us_p95"] = float(np.quantile(us, 0.95))
        print(f"{folder:28s} {np.median(us):10.1f} {np.quantile(us, 0.95):10.1f} {n:7d}")
        if kin.task == "fk" and args.rounds and hasattr(kin, "predictor"):   # the face vs the predictor
            diffs = [float(np.median(_latency_us(kin, inputs["fk"][:n]))
                           - np.median(_latency_us(kin, inputs["fk"][:n], step=kin.predictor.step)))
                     for _ in range(args.rounds)]
            figures[f"{key}_face_us_median"] = float(np.median(diffs))
            print(f"{'':28s} through Kinematics: {np.median(diffs):+.2f} µs (median of {args.rounds} rounds)")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
