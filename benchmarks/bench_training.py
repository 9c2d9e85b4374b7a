"""Training throughput and accuracy at matched wall time: the loop up to issue 11 (per-batch gathers,
plain Adam, the paper's batch 32 and lr 1e-3) against the current one (whole-epoch gather, fused
Adam, the fused window LSTM of issue 26, a larger batch with the square-root learning-rate rule,
early stopping on a smoothed val loss), both training the default FK model (the paper's LSTM-MLP) in
one run; `--nn-lstm` adds the current recipe on torch's nn.LSTM (`--no-fused-lstm`, the loop before
issue 26) as a third run, `--seed` seeds all of them.

    ctrkin collect --protocol paper --scale quick --out data/paper-quick
    OMP_NUM_THREADS=1 python benchmarks/bench_training.py data/paper-quick --seconds 240
    OMP_NUM_THREADS=1 python benchmarks/bench_training.py data/paper-quick --seconds 120 --rounds 3 --nn-lstm

Both runs get the same training-time budget (`TrainConfig.max_seconds`), spent in alternating
rounds (each round resumes its run from the checkpoint), so both see the same load from other jobs
on a shared machine. samples/s = training samples x epochs / training seconds (validation included,
one thread); per CPU s: the same over the process's CPU time in those epochs (what one core does
when it gets the core; less exposed to other jobs' load than wall time). Held-out error: position
RMSE on the test sequences against the truth as the tracker
sees it without noise (and against the measurement). Prints a table and ends with one JSON line.

    OMP_NUM_THREADS=1 python benchmarks/bench_training.py data/paper-quick --profile 5

`--profile EPOCHS`: instead, where an epoch's time goes: each loop trains EPOCHS epochs under
cProfile (one thread, no early stop), and the table splits the epochs' time by the functions the
engine calls (the recipe's forward and loss, backward, the optimiser's step, zero_grad, the rest of
the epoch loop: the shuffle's gather, batch views, the loss sum; the validation loss; checkpoints),
in ms per epoch and share (cProfile's own cost inflates the Python-heavy rows).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import tempfile
import time
from pathlib import Path
from typing import Any

from ctrkin.data import Dataset
from ctrkin.training import TrainConfig, train
from ctrkin.training.config import scaled_lr


def configs(batch: int, seconds: float, threads: int, nn_lstm: bool = False, seed: int = 0
            ) -> dict[str, TrainConfig]:
    """old: the paper's recipe on the loop up to issue 11; new: the current loop and recipe; with
    nn_lstm also "lstm": the new one with torch's nn.LSTM (fused_lstm off, the loop before issue 26)."""
    common = {"task": "fk", "threads": threads, "max_epochs": 10_000, "max_seconds": seconds, "seed": seed}
    new = {"loop": "epoch", "batch_size": batch, "lr": scaled_lr(batch), "val_smoothing": 0.5, **common}
    return {
        "old": TrainConfig(loop="batch", batch_size=32, lr=1e-3, **common),
        "new": TrainConfig(**new),
        **({"lstm": TrainConfig(**new, fused_lstm=False)} if nn_lstm else {}),
    }


def run(ds: Dataset, cfgs: dict[str, TrainConfig], out: Path, rounds: int) -> dict[str, dict[str, Any]]:
    """Train every config in `rounds` alternating slices of its time budget; the metrics of each."""
    metrics: dict[str, dict[str, Any]] = {}
    for k in range(1, rounds + 1):
        for name, cfg in cfgs.items():
            assert cfg.max_seconds is not None
            step = TrainConfig.from_dict({**cfg.to_dict(), "max_seconds": cfg.max_seconds * k / rounds})
            t0 = time.perf_counter()
            metrics[name] = train(ds, step, out / name, progress=False).metrics
            tr = metrics[name]["training"]
            print(f"round {k}/{rounds} {name}: epoch {tr['epochs']}, {tr['seconds']:.0f} s trained "
                  f"({time.perf_counter() - t0:.0f} s with evaluation)", flush=True)
    return metrics


PIECES = (("forward + loss (recipe.loss)", "recipe.py", "loss"), ("backward", "_tensor.py", "backward"),
          ("optimiser step (Adam)", "adam.py", "step"), ("zero_grad", "optimizer.py", "zero_grad"),
          ("validation loss", "recipe.py", "val_loss"), ("checkpoints", "engine.py", "_checkpoint"),
          ("epoch tensors (recipe)", "recipe.py", "epoch_tensors"))
LOOPS = (("engine.py", "_epoch_gathered"), ("engine.py", "_epoch"))


def _cumulative(stats: dict[Any, Any], file: str, func: str) -> float:
    """Seconds of cProfile's cumulative time in the functions `func` of files ending in `file`."""
    return float(sum(v[3] for (f, _, fn), v in stats.items() if fn == func and f.endswith(file)))


def profile(ds: Dataset, cfgs: dict[str, TrainConfig], out: Path, epochs: int) -> dict[str, dict[str, float]]:
    """ms per epoch of each piece (PIECES; "rest of the epoch loop": the loop's time less its calls)
    of each config trained `epochs` epochs under cProfile."""
    figures: dict[str, dict[str, float]] = {}
    for name, cfg in cfgs.items():
        run_cfg = TrainConfig.from_dict({**cfg.to_dict(), "max_epochs": epochs, "max_seconds": None,
                                         "patience": epochs + 1})
        prof = cProfile.Profile()
        prof.enable()
        train(ds, run_cfg, out / name, progress=False)
        prof.disable()
        stats = pstats.Stats(prof).stats        # type: ignore[attr-defined]
        got = {label: _cumulative(stats, file, func) / epochs * 1e3 for label, file, func in PIECES}
        loop = sum(_cumulative(stats, file, func) for file, func in LOOPS) / epochs * 1e3
        inner = sum(got[k] for k in ("forward + loss (recipe.loss)", "backward", "optimiser step (Adam)",
                                     "zero_grad"))
        got["rest of the epoch loop (gather, views, loss sum)"] = loop - inner
        got["the epochs (engine.epochs)"] = _cumulative(stats, "engine.py", "epochs") / epochs * 1e3
        figures[name] = got
    return figures


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", type=Path, help="a paper-protocol dataset (ctrkin collect --protocol paper)")
    ap.add_argument("--seconds", type=float, default=240.0, help="training-time budget of each run")
    ap.add_argument("--rounds", type=int, default=4, help="alternating slices of the budget")
    ap.add_argument("--batch", type=int, default=1024, help="batch size of the new recipe")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0, help="TrainConfig.seed of every run (weights, batches)")
    ap.add_argument("--nn-lstm", action="store_true",
                    help="also the new recipe with torch's nn.LSTM (row 'lstm': --no-fused-lstm)")
    ap.add_argument("--out", type=Path, default=None, help="model folders (default: a temporary folder)")
    ap.add_argument("--profile", type=int, default=None, metavar="EPOCHS",
                    help="where an epoch's time goes instead (module docstring)")
    args = ap.parse_args()
    ds = Dataset.load(args.data)
    cfgs = configs(args.batch, args.seconds, args.threads, args.nn_lstm, args.seed)
    if args.profile is not None:
        with tempfile.TemporaryDirectory() as tmp:
            prof = profile(ds, cfgs, args.out or Path(tmp), args.profile)
        whole = {n: p["the epochs (engine.epochs)"] for n, p in prof.items()}
        print(f"ms per epoch ({args.profile} epochs under cProfile, {args.threads} thread(s))"
              + "".join(f" {n + ' (batch ' + str(cfgs[n].batch_size) + ')':>22s}" for n in prof))
        for label in prof["new"]:
            print(f"{label:50s}" + "".join(f" {p[label]:12.1f} ({p[label] / whole[n]:5.1%})"
                                           for n, p in prof.items()))
        print(json.dumps({"profile_ms_per_epoch": prof}))
        return
    with tempfile.TemporaryDirectory() as tmp:
        m = run(ds, cfgs, args.out or Path(tmp), args.rounds)
    rows = {}
    for name, cfg in cfgs.items():
        tr, test = m[name]["training"], m[name]["test"]
        rows[name] = {"batch": cfg.batch_size, "lr": cfg.lr, "epochs": tr["epochs"], "best": tr["best_epoch"],
                      "seconds": tr["seconds"], "samples_per_s": tr["samples_per_s"],
                      "samples_per_cpu_s": tr["samples_per_cpu_s"],
                      "mm_true": test["vs_true"]["position_mm_rmse"],
                      "mm_meas": test["vs_measured"]["position_mm_rmse"],
                      "deg_true": test["vs_true"]["orientation_deg_rmse"]}
    print(f"\n{len(ds.frame)} samples; FK lstm_mlp; {args.threads} thread(s); "
          f"{args.seconds:.0f} s of training each; test sequences")
    head = f"{'loop':4s} {'batch':>5s} {'lr':>8s} {'epochs':>6s} {'best':>4s} {'train s':>7s} " \
           f"{'samples/s':>9s} {'/ CPU s':>7s} {'mm vs truth':>11s} {'mm vs meas':>10s} {'deg vs truth':>12s}"
    print(head)
    for name, r in rows.items():
        print(f"{name:4s} {r['batch']:5d} {r['lr']:8.2e} {r['epochs']:6d} {r['best']:4d} {r['seconds']:7.0f} "
              f"{r['samples_per_s']:9.0f} {r['samples_per_cpu_s']:7.0f} {r['mm_true']:11.3f} "
              f"{r['mm_meas']:10.3f} {r['deg_true']:12.2f}")
    for key, label in (("samples_per_s", "samples/s"), ("samples_per_cpu_s", "samples per CPU s")):
        print(f"speed-up {rows['new'][key] / rows['old'][key]:.2f}x {label}"
              + (f" (nn.LSTM: {rows['lstm'][key] / rows['old'][key]:.2f}x)" if "lstm" in rows else ""))
    print(json.dumps({f"{key}_{name}": round(rows[name][field], digits) for name in rows
                      for key, field, digits in (("samples_per_s", "samples_per_s", 1),
                                                 ("samples_per_cpu_s", "samples_per_cpu_s", 1),
                                                 ("heldout_mm", "mm_true", 4))}))


if __name__ == "__main__":
    main()
