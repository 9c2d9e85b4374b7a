"""Where a batch `predict` call's time goes (issue 26, goal 2: B = 1,024 against ONNX Runtime), by
measurement: `python benchmarks/bench_streaming.py --breakdown-predict 1024` (the baseline's tree and
this one, each in a worker process, twice in alternation).

`Kinematics.predict` on one sequence of B joints is timed whole, and beside it each of its pieces
alone, on the inputs the call itself gives that piece (computed once before the timing):

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

A tree from before this pass (no batch.fk_padded_rows; main dbab9a8) had separate numpy passes where
the one-pass rows are (features, clip + normalise, padding, to float32; de-normalise, quaternion) and
torch's head_out for the head: `_old_variants` times those.

Every variant in the thread's CPU time (on this shared machine a call of milliseconds is often
descheduled, which the wall clock's median counts against long calls more than against their short
pieces), in alternating blocks of BLOCK calls (a load burst falls on every variant alike), each
figure the median over rounds of the rounds' medians. The pieces' sum need not equal the whole: each
piece alone finds the caches warmer than it does inside the call."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

BLOCK = 5            # calls per variant per block


def _timer(fn: Callable[[], Any]) -> Callable[[], float]:
    """A timer of one call of fn in the thread's CPU time (ns; module docstring)."""
    clock = time.thread_time_ns

    def timed() -> float:
        t0 = clock()
        fn()
        return float(clock() - t0)

    return timed


def _lstm_pieces(batch: Any, net: Any, x32: torch.Tensor, w_ih: torch.Tensor, w_hh: torch.Tensor,
                 bias: torch.Tensor, n_rows: int) -> tuple[list[tuple[int, int]], np.ndarray,
                                                      dict[str, Callable[[], None]]]:
    """The one-LSTM pass's pieces as both trees run them, chunk by chunk (batch.FUSED_CHUNK rows):
    the chunks' spans, the window buffer (chunk, IB·H) the head reads, and the input projection,
    recurrent products and gates/cells as callables."""
    if not hasattr(batch, "FUSED_CHUNK"):
        raise SystemExit("--breakdown-predict splits the fused batch pass: its --baseline must have it "
                         "(dbab9a8 or later)")
    hid, ib = w_hh.shape[1], net.ib
    chunk = batch.FUSED_CHUNK
    spans = [(lo, min(lo + chunk, n_rows)) for lo in range(0, n_rows, chunk)]
    gx = {lo: torch.addmm(bias, x32[lo:hi + ib - 1], w_ih.t()).numpy() for lo, hi in spans}
    window = np.ascontiguousarray(np.random.default_rng(0).random((chunk, ib * hid)), np.float32)
    rec, c = np.empty((chunk, 4 * hid), np.float32), np.zeros((chunk, hid), np.float32)

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

    return spans, window, {"projection": projection, "recurrent": recurrent, "gates": gates}


def variants(kin: Any, rows: np.ndarray) -> dict[str, Callable[[], float]]:
    """The timed pieces (module docstring) of `kin.predict(rows)`: rows (B, 2N) one sequence of joints;
    a model whose network is a SeqNet with one LSTM layer (the fused batch pass). A tree from before
    this pass (no batch.fk_padded_rows) gets its own pieces (`_old_variants`)."""
    from ctrkin.models import batch

    if not hasattr(batch, "fk_padded_rows"):
        return _old_variants(kin, rows)

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
    n_rows = len(wins)
    spans, window, lstm_pieces = _lstm_pieces(batch, net, x32, w_ih, w_hh, bias, n_rows)
    dense = np.empty((window.shape[0], w1t.shape[1]), np.float32)
    out = np.empty((n_rows, net.n_outputs), np.float32)
    relu_out = net.output_activation == "relu"

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
        "inputs and guards": _timer(lambda: pred.raw_inputs(rows, None)),
        "frame angles": _timer(lambda: pred._network_joints(rows, raw, bounds)),
        "features … padding (one pass)": _timer(features),
        "the network": _timer(lambda: batch.seqnet_predict(net, padded, wins)),
        "  input projection": _timer(lstm_pieces["projection"]),
        "  recurrent products": _timer(lstm_pieces["recurrent"]),
        "  gates and cells": _timer(lstm_pieces["gates"]),
        "  Dense layer": _timer(dense_layer),
        "  ReLU and output": _timer(relu_output),
        "poses (one pass)": _timer(lambda: batch.fk_poses(yn, pred._y_norm.lo, pred._y_norm.span)),
        "to the tracker frame": _timer(to_world),
    }


def _old_variants(kin: Any, rows: np.ndarray) -> dict[str, Callable[[], float]]:
    """The pieces of predict before this pass (its numpy passes, torch's head_out): `variants` on a
    tree without batch.fk_padded_rows (bench_streaming.py --breakdown-predict B, the baseline's column)."""
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
    n_rows = len(starts)
    spans, window, lstm_pieces = _lstm_pieces(batch, net, x32, w_ih, w_hh, bias, n_rows)
    out = np.empty((n_rows, net.n_outputs), np.float32)

    def head() -> None:
        with torch.inference_mode():
            for lo, hi in spans:
                out[lo:hi] = net.head_out(torch.from_numpy(window[:hi - lo])).numpy()

    frame = pred.frame
    framed = frame is not None and angles is not None
    to_world = (lambda: frame.to_world(yp, angles)) if framed else (lambda: None)
    return {
        "Kinematics.predict": _timer(lambda: kin.predict(rows)),
        "inputs and guards": _timer(lambda: pred.raw_inputs(rows, None)),
        "frame angles": _timer(lambda: pred._network_joints(rows, raw, bounds)),
        "features": _timer(lambda: sequence_features(pred.layout, net_raw, bounds)),
        "clip + normalise": _timer(lambda: pred._x_norm.transform(pred.clip_deltas(feats.copy()))),
        "padding": _timer(lambda: batch.padded_rows(xn, bounds, pred.ib)),
        "the network": _timer(lambda: batch.seqnet_predict(net, padded, starts)),
        "  to float32": _timer(lambda: torch.from_numpy(np.ascontiguousarray(padded, dtype=np.float32))),
        "  input projection": _timer(lstm_pieces["projection"]),
        "  recurrent products": _timer(lstm_pieces["recurrent"]),
        "  gates and cells": _timer(lstm_pieces["gates"]),
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


ORDER = ("Kinematics.predict (the call as timed)", "inputs and guards", "frame angles", "features",
         "clip + normalise", "padding", "features … padding (one pass)", "the network", "to float32",
         "input projection", "recurrent products", "gates and cells", "head and output", "Dense layer",
         "ReLU and output", "de-normalise", "quaternion", "poses (one pass)", "to the tracker frame",
         "outside the network (sum of its rows)", "predictions/s (the call as timed)")
NETWORK = ("to float32", "input projection", "recurrent products", "gates and cells", "head and output",
           "Dense layer", "ReLU and output")


def table(us: dict[str, dict[str, float]], b: int) -> dict[str, dict[str, float]]:
    """Print the split of each tree (columns; `us`: tree -> piece -> µs) and return its figures."""
    rows: dict[str, dict[str, float]] = {}
    for tree, timed in us.items():
        got = {k.strip(): v for k, v in timed.items()}
        whole = got["Kinematics.predict"]
        mine = {"Kinematics.predict (the call as timed)": whole, **got}
        del mine["Kinematics.predict"]
        mine["outside the network (sum of its rows)"] = sum(
            v for k, v in got.items() if k not in ("Kinematics.predict", "the network", *NETWORK))
        mine["predictions/s (the call as timed)"] = b / whole * 1e6
        rows[tree] = mine
    labels = sorted({k for mine in rows.values() for k in mine}, key=ORDER.index)
    print(f"predict breakdown, B = {b:,}, thread CPU µs (share)"
          + "".join(f" {tree:>18s}" for tree in rows))
    for label in labels:
        cells = []
        for mine in rows.values():
            v, whole = mine.get(label), mine["Kinematics.predict (the call as timed)"]
            cells.append("" if v is None else f"{v:,.0f}" if label.startswith("pred")
                         else f"{v:9.1f} ({v / whole:5.1%})")
        indent = "    " if label in NETWORK else "" if label.startswith(("Kin", "pred")) else "  "
        print(f"{indent + label:48s}" + "".join(f" {c:>18s}" for c in cells))
    return rows
