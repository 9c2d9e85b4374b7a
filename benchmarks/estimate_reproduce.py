"""Estimate the training stage of `ctrkin reproduce --scale SCALE` from one timed epoch per run.

    ctrkin collect --protocol paper --scale full --out data/paper-full
    OMP_NUM_THREADS=1 python benchmarks/estimate_reproduce.py data/paper-full --scale full

For every training the reproduction plans (evaluation.training_runs.plan_runs), times one epoch on
`--rows` training rows and one validation pass, scales both to the dataset's split, and multiplies
by the run's epoch cap (an upper bound: early stopping only shortens it). Prints per run and the
wall time with `--workers` single-threaded workers (longest-first scheduling).
"""

from __future__ import annotations

import argparse
import heapq
import time
from dataclasses import replace
from pathlib import Path

import torch

from ctrkin.data import Dataset
from ctrkin.evaluation.scales import get_scale
from ctrkin.evaluation.training_runs import plan_runs
from ctrkin.families.registry import build_net, recipe
from ctrkin.models.recipe import TrainingData
from ctrkin.models.store import ModelBundle
from ctrkin.models.window_lstm import use_window_lstm
from ctrkin.training.data import split_rows
from ctrkin.training.engine import _epoch_gathered, _optimizer


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", type=Path)
    ap.add_argument("--scale", default="full")
    ap.add_argument("--rows", type=int, default=20_000, help="training rows timed per run")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--fused-lstm", choices=("budget", "on", "off"), default="budget",
                    help="the fused window LSTM (TrainConfig.fused_lstm) as each budget sets it, or forced")
    args = ap.parse_args()
    torch.set_num_threads(1)
    ds = Dataset.load(args.data)
    costs = []
    for run in plan_runs(get_scale(args.scale)):
        cfg = run.config
        if args.fused_lstm != "budget":
            cfg = replace(cfg, fused_lstm=args.fused_lstm == "on")
        rec = recipe(cfg)                      # the family's: its features, loss and validation
        split, rows = split_rows(ds, cfg)
        prepared = rec.prepare(TrainingData(ds, cfg, split, rows))
        bundle = ModelBundle.create(cfg.to_dict(), prepared.layout, prepared.x_norm, prepared.y_norm,
                                    ds.robot, {}, frame=prepared.frame, build=build_net)
        net = bundle.net
        use_window_lstm(net, cfg.loop == "epoch" and cfg.fused_lstm)      # as the engine's epochs
        opt, gen = _optimizer(net, cfg), torch.Generator().manual_seed(0)
        X, Y = rec.epoch_tensors(0, bundle)
        n_train = len(X)
        X, Y = X[: args.rows], Y[: args.rows]
        _epoch_gathered(net, opt, X[:2048], Y[:2048], cfg.batch_size, gen, rec.loss)   # warm-up
        t0 = time.perf_counter()
        _epoch_gathered(net, opt, X, Y, cfg.batch_size, gen, rec.loss)
        t_train = (time.perf_counter() - t0) * n_train / len(X)
        t0 = time.perf_counter()
        rec.val_loss(net)
        t_val = time.perf_counter() - t0
        total = cfg.max_epochs * (t_train + t_val)
        costs.append((total, run.name))
        print(f"{run.name:24s} batch {cfg.batch_size:5d} epochs <= {cfg.max_epochs:3d}: "
              f"{t_train:6.1f} s + val {t_val:4.1f} s per epoch ({n_train} rows) -> {total:6.0f} s",
              flush=True)
    loads = [0.0] * args.workers
    for total, _ in sorted(costs, reverse=True):
        heapq.heapreplace(loads, loads[0] + total)
    print(f"training stage: {sum(c for c, _ in costs):.0f} worker-s; with {args.workers} workers "
          f"<= {max(loads):.0f} s ({max(loads) / 60:.1f} min)")


if __name__ == "__main__":
    main()
