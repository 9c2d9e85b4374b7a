"""Why the IK's out-of-distribution AUROC is short (issue 24, goal 2): which input features separate
held-out in-range walks from the out-of-distribution kinds at all.

    python benchmarks/bench_ik_ood.py                 # paper robot, quick walks (~1 min)

The walks, regions and AUROC are benchmarks/learned_loop.py's (quick sizes: 24 training walks of 120
steps, 48 held-out walks of 40, 12 of each OOD kind), recorded on the virtual robot at its defaults.
The OOD score is ctrkin.models.uncertainty's own (k-NN distance of the configuration part and of the
history part, over their calibration medians, plus the excess beyond the trained range), fitted with
the IK's task (the raw input is the configuration, its last two changes the history) on different
inputs:

- pose (the IK's score now): the measured pose (x, y, z, q0, qx, qy);
- position: its position only;
- pose + joints (recorded): the pose and the joints that made it (cos, sin of α1 − α2, β / 10 mm):
  what a score could see with a perfect IK's answer beside the pose, the ceiling of scoring the
  IK's predicted joints too;
- position + joints (recorded): the same without the orientation;
- with `--ik`: pose + joints (predicted): the pose and the joints the paper's LSTM-MLP IK (trained
  here as learned_loop.py trains it, 30 epochs on the training walks) answers for it: what scoring
  the IK's own answer beside its input gives with this IK.

Calibrated on the first half of the held-out walks, AUROC against the second half. No model is
trained (but with `--ik`): the question is what the inputs can tell apart. Ends with one JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path
from typing import Any

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

import learned_loop  # benchmarks/, beside this file
from ctrkin.data.dataset import Dataset
from ctrkin.inference.uncertainty import predict_rows, row_runs
from ctrkin.models.uncertainty import Uncertainty
from ctrkin.robots import load_robot, paper_robot
from ctrkin.virtual.robot import VirtualRobot

KINDS = ("range", "combination", "steps", "reversals")


def bounds(ds: Dataset) -> list[tuple[int, int]]:
    return row_runs(ds.frame["sequence_id"].to_numpy(), np.arange(len(ds.frame)))


def joint_features(q: np.ndarray, n: int) -> np.ndarray:
    """(T, 2 + N): cos, sin of α1 − αN and β / 10 mm of joints q (T, 2N)."""
    rel = np.radians(q[:, 0] - q[:, n - 1])
    return np.c_[np.cos(rel), np.sin(rel), q[:, n:] / 10.0]


def inputs(ds: Dataset, ik: Any = None) -> dict[str, np.ndarray]:
    """The scored inputs of every row (module docstring), two tubes or more (α1 against αN); with
    ik (a Kinematics) also the pose with its predicted joints."""
    pose, q = ds.poses(), ds.joints()
    joints = joint_features(q, ds.n_tubes)
    out = {"pose": pose, "position": pose[:, :3], "pose + joints (recorded)": np.c_[pose, joints],
           "position + joints (recorded)": np.c_[pose[:, :3], joints]}
    if ik is not None:
        out["pose + joints (predicted)"] = np.c_[pose, joint_features(predict_rows(ik, ds)[0], ds.n_tubes)]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="paper")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--ik", action="store_true", help="also train the IK and score its predicted joints")
    args = ap.parse_args()
    robot = paper_robot() if args.robot == "paper" else load_robot(args.robot)
    vr = VirtualRobot(robot, seed=args.seed)
    rng = np.random.default_rng(args.seed)
    reg = learned_loop.regions(robot)
    train = learned_loop.record_walks(vr, learned_loop.region_walks(robot, rng, reg["train"], 24, 120),
                                      args.seed + 1)
    held = learned_loop.record_walks(vr, learned_loop.region_walks(robot, rng, reg["train"], 48, 40),
                                     args.seed + 2, first_id=10_000)
    ood = {k: learned_loop.record_walks(vr, learned_loop.region_walks(robot, rng, reg[k], 12, 40),
                                        args.seed + 3 + i) for i, k in enumerate(KINDS)}
    hb = bounds(held)
    half = len(hb) // 2
    cut = hb[half][0]
    test_bounds = [(a - cut, b - cut) for a, b in hb[half:]]
    ik = None
    with tempfile.TemporaryDirectory() as tmp:
        if args.ik:
            from ctrkin import Kinematics
            from ctrkin.training import TrainConfig
            from ctrkin.training import train as train_model

            cfg = TrainConfig(task="ik", max_epochs=30, threads=1, batch_size=128, lr=2e-3,
                              options={"structure": "L64|D64"})
            train_model(train, cfg, Path(tmp) / "ik", progress=False)
            ik = Kinematics.load(Path(tmp) / "ik")
        x_train, x_held = inputs(train, ik), inputs(held, ik)
        x_ood = {k: inputs(d, ik) for k, d in ood.items()}
    out: dict[str, dict[str, float]] = {}
    print(f"IK OOD score on the {robot.name} robot (virtual, defaults, seed {args.seed}): AUROC, held-out "
          f"in-range walks against each kind")
    print(f"{'scored input':30s} {'all':>6s} " + " ".join(f"{k:>11s}" for k in KINDS))
    for name in x_train:
        unc = Uncertainty.fit("ik", robot.n_tubes, x_train[name], bounds(train), x_held[name][:cut],
                              hb[:half], np.zeros((cut, robot.n_joints)))
        inside = unc.ood_scores(x_held[name][cut:], test_bounds)
        outside = {k: unc.ood_scores(x_ood[k][name], bounds(d)) for k, d in ood.items()}
        row = {"all": learned_loop.auroc(inside, np.concatenate(list(outside.values())))}
        row |= {k: learned_loop.auroc(inside, v) for k, v in outside.items()}
        out[name] = row
        print(f"{name:30s} {row['all']:6.3f} " + " ".join(f"{row[k]:11.3f}" for k in KINDS))
    print(json.dumps({"robot": robot.name, "seed": args.seed, "auroc": out}))


if __name__ == "__main__":
    main()
