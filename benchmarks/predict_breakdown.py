"""Where a batch `predict` call's time goes (issue 26, goal 2: B = 1,024 against ONNX Runtime), by
measurement: `python benchmarks/bench_streaming.py --breakdown-predict 1024` (this tree's code only).

`Kinematics.predict` on one sequence of B joints is timed whole, and beside it each of its pieces
alone, on the inputs the call itself gives that piece (computed once before the timing):

    the face               Kinematics.predict less FKPredictor.predict
    inputs and guards      raw_inputs: check_raw, the joint checks, the whole-turn shifts, the range check
    frame angles           the outer frame's angle per row (m_N, λ(β)) and the network's joints
    features … padding     batch.fk_padded_rows: features (eq. 1, 2), the step changes clipped,
                           x_norm.transform, each sequence's start padded, float32, in one numba pass
    the network            seqnet_predict, as a whole, and split into its chunks' pieces:
      input projection       W_ih x + b of every padded row (torch)
      recurrent products     W_hh h of position 1..IB−1 (torch)
      gates and cells        the numba pass over the gate values (`_lstm_position`)
      Dense layer            the head's Dense product (torch)
      ReLU and output        ReLU, the output layer and its activation (`_relu_dense`)
    poses                  batch.fk_poses: y_norm.inverse and unit quaternions in one numba pass
    to the tracker frame   frame.to_world

(Before issue 26's B = 1,024 pass, commit 4d79f9b, the features, clipping, normalisation, padding,
float32 conversion, de-normalisation and quaternion were separate numpy passes, and the head ran
torch's head_out: that commit's version of this script times those pieces.)

every variant in the thread's CPU time, in alternating blocks of BLOCK calls (a load burst falls on every variant alike), each
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
    """A timer of one call of fn in the thread's CPU time (ns): on this shared machine a call of
    milliseconds is often descheduled mid-way, which the wall clock's median counts against long
    calls more than against their short pieces."""
    clock = time.thread_time_ns

    def timed() -> float:
        t0 = clock()
        fn()
        return float(clock() - t0)

    return timed


def variants(kin: Any, rows: np.ndarray) -> dict[str, Callable[[], float]]:
    """The timed pieces (module docstring) of `kin.predict(rows)`: rows (B, 2N) one sequence of joints;
    a model whose network is a SeqNet with one LSTM layer (the fused batch pass)."""
    from ctrkin.models import batch

    pred = kin.predictor
    net = pred._seqnet
    if net is None or len(net.seq) != 1 or not isinstance(net.seq[0], torch.nn.LSTM) or not pred._chains_fast:
        raise SystemExit("--breakdown-predict needs an FK model whose network is one LSTM layer and a head")
    raw, bounds = pred.raw_inputs(rows, None)
    net_raw, angles = pred._network_joints(rows, raw, bounds)
    starts = pred._sequence_starts(bounds, len(raw))
    x, d = pred._x_norm, (float(pred._dlo[0]), float(pred._dhi[0]))
    layout = pred.layout

    def features() -> tuple[np.ndarray, np.ndarray]:
        phase = layout.angle_encoding == "phase"
        return batch.fk_padded_rows(net_raw, starts, pred.ib, layout.n_tubes, phase, layout.delta,
                                    x.lo, x.span, *d)

    padded, wins = features()
    yn = batch.seqnet_predict(net, padded, wins)
    yp = batch.fk_poses(yn, pred._y_norm.lo, pred._y_norm.span)
    x32 = torch.from_numpy(padded)
    w_ih, w_hh, bias = batch._scaled_lstm_weights(net.seq[0])
    head = batch._one_dense_head(net)
    assert head is not None
    w1t, b1, w2, b2 = head
    hid, ib, n_rows = w_hh.shape[1], net.ib, len(wins)
    chunk = batch.FUSED_CHUNK
    spans = [(lo, min(lo + chunk, n_rows)) for lo in range(0, n_rows, chunk)]
    gx = {lo: torch.addmm(bias, x32[lo:hi + ib - 1], w_ih.t()).numpy() for lo, hi in spans}
    window = np.ascontiguousarray(np.random.default_rng(0).random((chunk, ib * hid)), np.float32)
    rec, c = np.empty((chunk, 4 * hid), np.float32), np.zeros((chunk, hid), np.float32)
    dense = np.empty((chunk, w1t.shape[1]), np.float32)
    out = np.empty((n_rows, net.n_outputs), np.float32)
    relu_out = net.output_activation == "relu"

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

    def dense_layer() -> None:
        with torch.inference_mode():
            for lo, hi in spans:
                d_out = torch.from_numpy(dense[:hi - lo])
                torch.addmm(b1, torch.from_numpy(window[:hi - lo]), w1t, out=d_out)

    def relu_output() -> None:
        for lo, hi in spans:
            batch._relu_dense(dense[:hi - lo], w2, b2, relu_out, out[lo:hi])

    frame = pred.frame
    framed = frame is not None and angles is not None
    to_world = (lambda: frame.to_world(yp, angles)) if framed else (lambda: None)
    return {
        "Kinematics.predict": _timer(lambda: kin.predict(rows)),
        "FKPredictor.predict": _timer(lambda: pred.predict(rows)),
        "inputs and guards": _timer(lambda: pred.raw_inputs(rows, None)),
        "frame angles": _timer(lambda: pred._network_joints(rows, raw, bounds)),
        "features … padding (one pass)": _timer(features),
        "the network": _timer(lambda: batch.seqnet_predict(net, padded, wins)),
        "  input projection": _timer(projection),
        "  recurrent products": _timer(recurrent),
        "  gates and cells": _timer(gates),
        "  Dense layer": _timer(dense_layer),
        "  ReLU and output": _timer(relu_output),
        "poses (one pass)": _timer(lambda: batch.fk_poses(yn, pred._y_norm.lo, pred._y_norm.span)),
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
