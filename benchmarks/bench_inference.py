"""Inference speed of learned kinematics: streaming single-step latency and batch throughput.

    python benchmarks/bench_inference.py                                  # default architectures
    python benchmarks/bench_inference.py --fk models/fk --ik models/ik    # trained model folders

Without model folders it trains the default FK and IK architectures (paper LSTM-MLP, IB = 2,
LSTM 128, Dense 64) for one epoch on a small TCM dataset: latency depends on the architecture, not on
the weight values. Goals (issue 4): streaming median <= 50 µs on one core (paper: 0.831 ms FK,
0.816 ms IK); batch >= 500,000 predictions/s.

Streaming: Kinematics.step() (features, normalisation, numba engine, denormalisation), one thread.
For reference also one torch module call on a (1, IB, F) window. Batch: Kinematics.predict() on one
long sequence (features, chain batch path in torch under inference_mode, IK workspace check), 1 and 2
threads, and the network alone (chain batch path on ready features).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ctrkin.inference import Kinematics
from ctrkin.models import SeqNet
from ctrkin.models.batch import padded_rows, seqnet_predict


def _latency(fn: Any, inputs: np.ndarray, warmup: int = 500) -> dict[str, float]:
    for x in inputs[:warmup]:
        fn(x)
    ns = np.empty(len(inputs))
    clock = time.perf_counter_ns
    for k, x in enumerate(inputs):
        t0 = clock()
        fn(x)
        ns[k] = clock() - t0
    us = ns / 1e3
    return {"median_us": float(np.median(us)), "p95_us": float(np.quantile(us, 0.95)),
            "mean_us": float(us.mean()), "std_us": float(us.std()), "n": len(us)}


def _default_models(root: Path) -> tuple[Path, Path]:
    from ctrkin.acquisition.demo import sweep_dataset
    from ctrkin.robots import paper_robot
    from ctrkin.training import TrainConfig, train

    ds = sweep_dataset(paper_robot(), translations=(8, 14, 20), outer_alphas=(0, 120, 240), step_deg=4)
    for task in ("fk", "ik"):
        train(ds, TrainConfig(task=task, max_epochs=1, threads=1), root / task, progress=False)
    return root / "fk", root / "ik"


def _inputs(kin: Kinematics, n: int) -> np.ndarray:
    """A long continuous input sequence. FK: a full inner rotation back and forth at 1°, repeated;
    IK: the model's training targets in recorded order (continuous paths inside the workspace)."""
    t = np.arange(n)
    a1 = 180.0 - 180.0 * np.cos(2 * np.pi * t / 720.0)
    if kin.task == "fk":
        q = np.zeros((n, 4))
        q[:, 0], q[:, 2] = a1, -14.0
        return q
    ws = kin.workspace                          # IK targets: the training targets, in recorded order
    assert ws is not None
    pts = ws.norm.inverse(ws.points)
    return pts[np.arange(n) % len(pts)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fk", type=Path)
    ap.add_argument("--ik", type=Path)
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--batch", type=int, default=200_000, help="sequence length for throughput")
    ap.add_argument("--out", type=Path, help="write the report as JSON")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        fk_dir, ik_dir = (args.fk, args.ik) if args.fk and args.ik else _default_models(Path(tmp))
        report: dict[str, Any] = {}
        for name, path in (("fk", fk_dir), ("ik", ik_dir)):
            kin = Kinematics.load(path)
            torch.set_num_threads(1)
            xs = _inputs(kin, args.steps)
            kin.reset()
            r: dict[str, Any] = {"model": kin.config["model"], "structure": kin.config["options"],
                                 "ib": kin.ib}
            r["stream_step"] = _latency(kin.step, xs)
            if name == "ik":
                kin.reset()
                r["stream_step_no_workspace_check"] = _latency(lambda x, k=kin: k.step(x, check=False), xs)
                far = xs.copy()
                far[:, 0] += 3.0 * kin.bundle.x_norm.span[0]     # far outside: flagged by the range test
                kin.reset()
                r["stream_step_outside_workspace"] = _latency(kin.step, far[:3000])
            win = torch.rand(1, kin.ib, kin.layout.n_inputs)
            with torch.inference_mode():
                r["torch_module_single_window"] = _latency(lambda _x, w=win, k=kin: k.net(w), xs[:3000])
            big = _inputs(kin, args.batch)
            if isinstance(kin.net, SeqNet):    # the network alone (chain batch path), no features/checks
                feats = np.random.default_rng(0).random((args.batch, kin.layout.n_inputs))
                padded, starts = padded_rows(feats, [(0, args.batch)], kin.ib)
                for threads in (1, 2):
                    torch.set_num_threads(threads)
                    seqnet_predict(kin.net, padded[:5000], starts[:4000])
                    t0 = time.perf_counter()
                    seqnet_predict(kin.net, padded, starts)
                    r[f"network_only_per_s_{threads}_threads"] = args.batch / (time.perf_counter() - t0)
            for threads in (1, 2):
                torch.set_num_threads(threads)
                kin.predict(big[:5000])
                t0 = time.perf_counter()
                kin.predict(big)
                dt = time.perf_counter() - t0
                r[f"batch_predictions_per_s_{threads}_threads"] = args.batch / dt
            report[name] = r
    torch.set_num_threads(1)
    for name, r in report.items():
        s = r["stream_step"]
        print(f"{name.upper()} streaming step: median {s['median_us']:.1f} µs, p95 {s['p95_us']:.1f} µs, "
              f"mean {s['mean_us']:.1f} ± {s['std_us']:.1f} µs (one core)")
        if "stream_step_no_workspace_check" in r:
            s2 = r["stream_step_no_workspace_check"]
            print(f"   without workspace check: median {s2['median_us']:.1f} µs, p95 {s2['p95_us']:.1f} µs")
            s3 = r["stream_step_outside_workspace"]
            print(f"   target outside the workspace: median {s3['median_us']:.1f} µs, "
                  f"p95 {s3['p95_us']:.1f} µs")
        t = r["torch_module_single_window"]
        print(f"   torch module call on one window: median {t['median_us']:.1f} µs")
        print(f"   batch predict(): {r['batch_predictions_per_s_1_threads']:,.0f} /s (1 thread), "
              f"{r['batch_predictions_per_s_2_threads']:,.0f} /s (2 threads)")
        if "network_only_per_s_1_threads" in r:
            print(f"   network only: {r['network_only_per_s_1_threads']:,.0f} /s (1 thread), "
                  f"{r['network_only_per_s_2_threads']:,.0f} /s (2 threads)")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
