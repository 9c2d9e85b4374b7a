"""Split-conformal intervals against a small deep ensemble (issue 24, goal 2: "measured against each
other"), on the learned FK of the paper robot.

    python benchmarks/bench_uncertainty_ensemble.py            # 5 members
    python benchmarks/bench_uncertainty_ensemble.py --members 3 --quick

The data and model of benchmarks/learned_loop.py (random joint walks on the virtual robot; the FK in
the outer tube's frame, L64|D64), trained `--members` times with seeds 0.. on the same rows. On the
held-out walks (calibrated on a random half of the walks, tested on the other, 200 halvings):

- conformal: member 0 alone, the ball of the pooled conformal radius (ctrkin.models.uncertainty);
- ensemble, raw: the members' mean, a ball of radius σ·√χ²₃(0.9) = 2.50·σ (σ the members' spread per
  axis, RMS over the axes): what an ensemble's spread says uncalibrated;
- ensemble, conformal: the members' mean, the ball of radius r·σ with r the pooled conformal
  quantile of ‖error‖/σ on the calibration half (normalised conformal: a width per input).

Prints coverage (mean, 5-95 %), the median ball radius (mm), the streaming cost of one step (µs: one
model with the OOD score, against `--members` models) and ends with one JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np
import pandas as pd

import learned_loop  # benchmarks/, beside this file
from ctrkin import Kinematics
from ctrkin.data.dataset import Dataset
from ctrkin.inference.uncertainty import calibrate, predict_rows, row_runs
from ctrkin.models.uncertainty import grouped_radius
from ctrkin.robots import paper_robot
from ctrkin.training import TrainConfig, train
from ctrkin.virtual.robot import VirtualRobot

CHI2_3_90 = 2.5003        # √ of the χ² quantile, 3 degrees of freedom, 0.9


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--members", type=int, default=5)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    robot = paper_robot()
    vr = VirtualRobot(robot, seed=args.seed)
    rng = np.random.default_rng(args.seed)
    reg = learned_loop.regions(robot)
    n_train, steps, n_held, short = (24, 120, 48, 40) if args.quick else (60, 150, 120, 50)
    walks = learned_loop.region_walks
    train_ds = learned_loop.record_walks(vr, walks(robot, rng, reg["train"], n_train, steps), args.seed + 1)
    held = learned_loop.record_walks(vr, walks(robot, rng, reg["train"], n_held, short), args.seed + 2,
                                     first_id=10_000)
    both = Dataset(pd.concat([train_ds.frame, held.frame], ignore_index=True), robot, {"protocol": "walks"})
    held_rows = np.arange(len(train_ds.frame), len(both.frame))
    sid = both.frame["sequence_id"].to_numpy()
    preds, kins = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for m in range(args.members):
            cfg = TrainConfig(task="fk", max_epochs=30 if args.quick else 60, threads=1, batch_size=128,
                              lr=2e-3, seed=m, target_frame="outer", angle_encoding="phase",
                              options={"structure": "L64|D64"})
            train(train_ds, cfg, Path(tmp) / f"m{m}", progress=False)
            kins.append(Kinematics.load(Path(tmp) / f"m{m}"))
            p, truth = predict_rows(kins[-1], both)
            preds.append(p)
        P = np.stack(preds)[:, held_rows]                       # (M, H, 3)
        truth = truth[held_rows]
        mean, sigma = P.mean(axis=0), np.sqrt(np.mean(P.var(axis=0), axis=1)) + 1e-9
        err0 = np.linalg.norm(P[0] - truth, axis=1)
        err_m = np.linalg.norm(mean - truth, axis=1)
        cov = {"conformal": [], "ensemble_raw": [], "ensemble_conformal": []}
        rad = {k: [] for k in cov}
        halves = np.random.default_rng(args.seed)
        seqs = np.unique(sid[held_rows])
        for _ in range(200):
            cal = np.isin(sid[held_rows], halves.permutation(seqs)[:len(seqs) // 2])
            runs = row_runs(sid[held_rows], np.flatnonzero(cal))
            r0 = grouped_radius(err0[cal], runs, 0.9)
            rn = grouped_radius(err_m[cal] / sigma[cal], runs, 0.9)
            for name, ok, r in (("conformal", err0[~cal] <= r0, np.full((~cal).sum(), r0)),
                                ("ensemble_raw", err_m[~cal] <= CHI2_3_90 * sigma[~cal],
                                 CHI2_3_90 * sigma[~cal]),
                                ("ensemble_conformal", err_m[~cal] <= rn * sigma[~cal], rn * sigma[~cal])):
                cov[name].append(float(np.mean(ok)))
                rad[name].append(float(np.median(r)))
        # streaming: one model with its OOD score against every member stepping
        unc = calibrate(kins[0], both, np.arange(len(train_ds.frame)), held_rows[cal])
        kins[0].uncertainty = unc
        xs = both.joints()[held_rows[sid[held_rows] == sid[held_rows][0]]]
        one, many = [], []
        clock = time.perf_counter
        for _ in range(5):
            kins[0].reset()
            for x in xs:
                t0 = clock()
                kins[0].step_uncertain(x)
                one.append(clock() - t0)
            for k in kins:
                k.reset()
            for x in xs:
                t0 = clock()
                for k in kins:
                    k.step(x)
                many.append(clock() - t0)
    print(f"paper robot FK, {args.members} members, {len(seqs)} held-out walks "
          f"(load {os.getloadavg()[0]:.1f})")
    print(f"{'':20s} {'coverage 90 %':>13s} {'5-95 %':>13s} {'median radius mm':>17s}")
    out = {}
    for name in cov:
        lo, hi = np.quantile(cov[name], [0.05, 0.95])
        print(f"{name:20s} {np.mean(cov[name]):13.3f} {lo:6.3f}-{hi:6.3f} {np.median(rad[name]):17.3f}")
        out[name] = {"coverage_90": float(np.mean(cov[name])),
                     "median_radius_mm": float(np.median(rad[name]))}
    step_one, step_many = float(np.median(one)) * 1e6, float(np.median(many)) * 1e6
    print(f"step: one model with its OOD score {step_one:.1f} µs; {args.members} members {step_many:.1f} µs")
    print(json.dumps({**out, "step_conformal_us": step_one, "step_ensemble_us": step_many,
                      "members": args.members, "held_out_walks": len(seqs)}))


if __name__ == "__main__":
    main()
