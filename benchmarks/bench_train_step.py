"""One training step of the paper's FK (LSTM-MLP, IB = 2) at a batch size, with torch's nn.LSTM and
with the fused window LSTM (ctrkin.models.window_lstm, issue 26 goal 3), in alternating steps: CPU
time (time.process_time, less exposed to other jobs than wall time) of the forward with the L1 loss,
the backward, Adam's fused step, and the whole step; the lower quartile over the steps. Also the
step's float32 product floor: its multiply-adds at the rate MKL reaches for the recurrent product's
shape on this core.

    OMP_NUM_THREADS=1 python benchmarks/bench_train_step.py --batch 1024 --steps 40

Random inputs of the paper's shapes (F = 7 features; the arithmetic does not depend on the values).
Ends with one JSON line.
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from collections.abc import Callable

import torch
import torch.nn.functional as F

from ctrkin.families.registry import build_model
from ctrkin.models.window_lstm import use_window_lstm

N_FEATURES, IB = 7, 2
PARTS = ("forward + loss", "backward", "adam", "step")


def _stepper(net: torch.nn.Module, x: torch.Tensor, y: torch.Tensor
             ) -> Callable[[dict[str, list[float]]], None]:
    opt = torch.optim.Adam(net.parameters(), lr=1e-4, fused=True)

    def step(times: dict[str, list[float]]) -> None:
        t0 = time.process_time()
        loss = F.l1_loss(net(x), y)
        t1 = time.process_time()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        t2 = time.process_time()
        opt.step()
        t3 = time.process_time()
        for part, dt in zip(PARTS, (t1 - t0, t2 - t1, t3 - t2, t3 - t0), strict=True):
            times[part].append(dt)
    return step


def product_floor_ms(batch: int) -> tuple[float, float]:
    """(ms, GFLOPS): the step's products (forward 2·IB·F·4H + 4H·H + 2H·64 + 64·6 multiply-adds a
    sample, the backward twice that less the input gradient) at MKL's rate for (B, H)·(H, 4H)."""
    h = 128
    fwd = IB * N_FEATURES * 4 * h + h * 4 * h + IB * h * 64 + 64 * 6
    bwd = 2 * fwd - IB * N_FEATURES * 4 * h
    a, b = torch.rand(batch, h), torch.rand(h, 4 * h)
    ts = []
    for _ in range(30):
        t0 = time.process_time()
        a @ b
        ts.append(time.process_time() - t0)
    ts.sort()
    gflops = 2 * batch * h * 4 * h / ts[len(ts) // 4] / 1e9
    return 2 * (fwd + bwd) * batch / gflops / 1e6, gflops


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--steps", type=int, default=40, help="timed steps of each variant")
    args = ap.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(0)
    base = build_model("lstm_mlp", N_FEATURES, 6, IB)
    x, y = torch.rand(args.batch, IB, N_FEATURES), torch.rand(args.batch, 6)
    steps = {}
    for name, fused in (("nn.LSTM", False), ("window", True)):
        net = copy.deepcopy(base)
        use_window_lstm(net, fused)
        steps[name] = _stepper(net, x, y)
    times = {name: {p: [] for p in PARTS} for name in steps}
    for _ in range(3):                                  # warm-up (numba's cache, the buffer pool)
        for step in steps.values():
            step({p: [] for p in PARTS})
    for _ in range(args.steps):
        for name, step in steps.items():
            step(times[name])
    q25 = {name: {p: sorted(v)[len(v) // 4] * 1e3 for p, v in t.items()} for name, t in times.items()}
    floor, gflops = product_floor_ms(args.batch)
    print(f"batch {args.batch}, IB {IB}, one thread; CPU ms, lower quartile of {args.steps} "
          "alternating steps")
    print(f"{'':16s}" + "".join(f"{n:>10s}" for n in q25))
    for p in PARTS:
        print(f"{p:16s}" + "".join(f"{q25[n][p]:10.2f}" for n in q25))
    print(f"window / nn.LSTM step: {q25['nn.LSTM']['step'] / q25['window']['step']:.2f}x; products' floor "
          f"{floor:.2f} ms ({gflops:.0f} GFLOPS); samples per CPU s: "
          + ", ".join(f"{n} {args.batch / q25[n]['step'] * 1e3:,.0f}" for n in q25))
    print(json.dumps({"batch": args.batch, "step_ms": {n: round(q25[n]["step"], 3) for n in q25},
                      "parts_ms": {n: {p: round(v, 3) for p, v in q25[n].items()} for n in q25},
                      "product_floor_ms": round(floor, 3)}))


if __name__ == "__main__":
    main()
