"""Where a batch `predict` call's time goes (issue 26, goal 2: B = 1,024 against ONNX Runtime), by
measurement: `python benchmarks/bench_streaming.py --breakdown-predict 1024` (this tree's code only).

`Kinematics.predict` on one sequence of B joints is timed whole, and beside it each of its pieces
alone, on the inputs the call itself gives that piece (computed once before the timing):

    the face               Kinematics.predict less FKPredictor.predict
    inputs and guards      raw_inputs: check_raw, the joint checks, the whole-turn shifts, the range check
    frame angles           the outer frame's angle per row (m_N, λ(β)) and the network's joints
    features               sequence_features (eq. 1, 2)
    clip + normalise       the step changes clipped, x_norm.transform
    padding                padded_rows: each sequence's start padded, the window starts
    the network            seqnet_predict, as a whole, and split into its chunks' pieces:
      to float32             the padded rows as a float32 tensor
      input projection       W_ih x + b of every padded row
      recurrent products     W_hh h of position 1..IB−1
      gates and cells        the numba pass over the gate values (`_lstm_position`)
      head and output        Dense + ReLU, output layer, output activation, copy out
    de-normalise           y_norm.inverse
    quaternion             postprocess (unit quaternions)
    to the tracker frame   frame.to_world

every variant in alternating blocks of BLOCK calls (a load burst falls on every variant alike), each
figure the median over rounds of the rounds' medians. The pieces' sum need not equal the whole: each
piece alone finds the caches warmer than it does inside the call.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

BLOCK = 5            # calls per variant per block


def _timer(fn: Callable[[], Any]) -> Callable[[], float]:
    clock = time.perf_counter_ns

    def timed() -> float:
        t0 = clock()
        fn()
        return float(clock() - t0)

    return timed


def variants(kin: Any, rows: np.ndarray) -> dict[str, Callable[[], float]]:
    """The timed pieces (module docstring) of `kin.predict(rows)`: rows (B, 2N) one sequence of joints;
    a model whose network is a SeqNet with one LSTM layer (the fused batch pass)."""
    from ctrkin.models import batch
    from ctrkin.models.features import postprocess, sequence_features

    pred = kin.predictor
    net = pred._seqnet
    if net is None or len(net.seq) != 1 or not isinstance(net.seq[0], torch.nn.LSTM):
        raise SystemExit("--breakdown-predict needs an FK model whose network is one LSTM layer and a head")
    raw, bounds = pred.raw_inputs(rows, None)
    net_raw, angles = pred._network_joints(rows, raw, bounds)
    feats = sequence_features(pred.layout, net_raw, bounds)
    xn = pred._x_norm.transform(pred.clip_deltas(feats.copy()))
    padded, starts = batch.padded_rows(xn, bounds, pred.ib)
    yn = batch.seqnet_predict(net, padded, starts)
    y = pred._y_norm.inverse(yn)
    yp = postprocess(pred.layout, y)
    x32 = torch.from_numpy(np.ascontiguousarray(padded, dtype=np.float32))
    weights = batch._scaled_lstm_weights(net.seq[0])
    w_ih, w_hh, bias = weights
    hid, ib, n_rows = w_hh.shape[1], net.ib, len(starts)
    chunk = batch.FUSED_CHUNK
    spans = [(lo, min(lo + chunk, n_rows)) for lo in range(0, n_rows, chunk)]
    gx = {lo: torch.addmm(bias, x32[lo:hi + ib - 1], w_ih.t()).numpy() for lo, hi in spans}
    window = np.ascontiguousarray(np.random.default_rng(0).random((chunk, ib * hid)), np.float32)
    rec, c = np.empty((chunk, 4 * hid), np.float32), np.zeros((chunk, hid), np.float32)
    out = np.empty((n_rows, net.n_outputs), np.float32)

    def projection() -> None:
        for lo, hi in spans:
            g = batch._scratch("bd_gx", (hi - lo + ib - 1, 4 * hid))
            torch.addmm(bias, x32[lo:hi + ib - 1], w_ih.t(), out=torch.from_numpy(g))

    def recurrent() -> None:
        for lo, hi in spans:
            win_t, rec_t = torch.from_numpy(window[:hi - lo]), torch.from_numpy(rec[:hi - lo])
            for k in range(1, ib):
                torch.mm(win_t[:, (k - 1) * hid:k * hid], w_hh.t(), out=rec_t)

    def gates() -> None:
        for lo, hi in spans:
            w = window[:hi - lo]
            for k in range(ib):
                batch._lstm_position(rec[:hi - lo], gx[lo][k:k + hi - lo], k == 0, c[:hi - lo], w, k * hid)

    def head() -> None:
        with torch.inference_mode():
            for lo, hi in spans:
                out[lo:hi] = net.head_out(torch.from_numpy(window[:hi - lo])).numpy()

    frame = pred.frame
    framed = frame is not None and angles is not None
    to_world = (lambda: frame.to_world(yp, angles)) if framed else (lambda: None)
    return {
        "Kinematics.predict": _timer(lambda: kin.predict(rows)),
        "FKPredictor.predict": _timer(lambda: pred.predict(rows)),
        "inputs and guards": _timer(lambda: pred.raw_inputs(rows, None)),
        "frame angles": _timer(lambda: pred._network_joints(rows, raw, bounds)),
        "features": _timer(lambda: sequence_features(pred.layout, net_raw, bounds)),
        "clip + normalise": _timer(lambda: pred._x_norm.transform(pred.clip_deltas(feats.copy()))),
        "padding": _timer(lambda: batch.padded_rows(xn, bounds, pred.ib)),
        "the network": _timer(lambda: batch.seqnet_predict(net, padded, starts)),
        "  to float32": _timer(lambda: torch.from_numpy(np.ascontiguousarray(padded, dtype=np.float32))),
        "  input projection": _timer(projection),
        "  recurrent products": _timer(recurrent),
        "  gates and cells": _timer(gates),
        "  head and output": _timer(head),
        "de-normalise": _timer(lambda: pred._y_norm.inverse(yn)),
        "quaternion": _timer(lambda: postprocess(pred.layout, y)),
        "to the tracker frame": _timer(to_world),
    }


def measure(timers: dict[str, Callable[[], float]], rounds: int) -> dict[str, float]:
    """Median µs of each timer over `rounds` rounds of alternating blocks (order reversed every other
    round)."""
    names = list(timers)
    for name in names:                                       # warm-up
        for _ in range(3):
            timers[name]()
    per_round: dict[str, list[float]] = {n: [] for n in names}
    for r in range(rounds):
        got: dict[str, list[float]] = {n: [] for n in names}
        for _ in range(3):
            for name in (names if r % 2 == 0 else names[::-1]):
                got[name].extend(timers[name]() for _ in range(BLOCK))
        for name in names:
            per_round[name].append(float(np.median(got[name])) / 1e3)
    return {n: float(np.median(v)) for n, v in per_round.items()}


def table(us: dict[str, float], b: int) -> dict[str, float]:
    """Print the split (the face as a difference, every other row as timed) and return its figures."""
    whole = us["Kinematics.predict"]
    rows = {"Kinematics.predict (the call as timed)": whole,
            "  the face": whole - us["FKPredictor.predict"]}
    whole_calls = ("Kinematics.predict", "FKPredictor.predict")
    rows.update({f"  {k}": v for k, v in us.items() if k not in whole_calls})
    outside = sum(v for k, v in us.items()
                  if not k.startswith("  ") and k not in (*whole_calls, "the network"))
    rows["  outside the network (sum of its rows)"] = outside + rows["  the face"]
    print(f"predict breakdown, B = {b:,} {'':20s} {'µs':>9s} {'share':>7s}")
    for label, v in rows.items():
        print(f"{label:48s} {v:9.1f} {v / whole:7.1%}")
    print(f"{'predictions/s (the call as timed)':48s} {b / whole * 1e6:9,.0f}")
    return {k.strip(): v for k, v in rows.items()}
