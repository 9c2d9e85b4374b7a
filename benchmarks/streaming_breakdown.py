"""Where the FK streaming step's distance from its floor goes (issue 26, goal 2), by measurement:
`python benchmarks/bench_streaming.py --breakdown` (the current tree's code only).

The step is timed with its layers peeled off one at a time, each variant a call that does less than the
one above it, all in alternating blocks of `BLOCK` calls (a load burst falls on every variant alike):

    Kinematics.step        the face (thread check) + ...
    FKPredictor.step       the predictor's type checks, shift, lag, state write-back, result copy + ...
    the kernel call        numba's dispatch of the arguments + ...
    the kernel in a loop   the compiled step, called `LOOP` times inside numba (no dispatch)

and inside the kernel, each piece alone in a numba loop on the step's own buffers: the LSTM cell
updates of the IB chains (their multiply-adds, the two sigmoid passes, the cell arithmetic), the
sigmoid passes alone, the Dense head and output layer, the history push; what the kernel takes beyond
them is the guards, the features, the gate and the frame. Beside them the floor (the network's
multiply-adds as a bare chain, `bench_streaming.floor_call`) both as bench_streaming times it (a call
with its 13 arguments) and in a numba loop. Each row: the median over rounds of the rounds' medians,
and of the rounds' ratios to the floor as timed (a call), so that the rows are in the unit the goal
(≤ 1.5×) is stated in.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

BLOCK = 50           # calls per variant per block
LOOP = 50            # kernel iterations per timed call of a numba loop


def _per_call(fn: Callable[[], Any], loops: int) -> Callable[[], float]:
    """A timer of one call of fn, in ns per iteration (fn runs `loops` iterations)."""
    clock = time.perf_counter_ns

    def timed() -> float:
        t0 = clock()
        fn()
        return (clock() - t0) / loops

    return timed


def _loops() -> dict[str, Any]:
    """numba loops over the step's kernels (compiled on first use, not cached)."""
    from ctrkin.models.engine import _dense_rows, _lstm_rows, _push_history, _sigmoid_inplace
    from ctrkin.models.fused import _fk_step

    @njit
    def fk_step(n, raw, shift, prev, consts, weights, state, ints, branch, gate_state, motion, outer_prev,
                lag):
        for _ in range(n):
            _fk_step(raw, shift, prev, consts, weights, state, ints, True, False, branch, gate_state, motion,
                     outer_prev, lag)

    @njit
    def lstm(n, x, w_ih, w_hh, b, h, c, h2, c2, g, t, bits):
        for _ in range(n):
            _lstm_rows(x, True, w_ih, w_hh, b, h, c, h2, c2, g, t, bits, h.shape[0])

    @njit
    def sigmoid(n, g, t, bits):
        for _ in range(n):
            _sigmoid_inplace(g.reshape(-1), bits)
            _sigmoid_inplace(t.reshape(-1), bits)

    @njit
    def head(n, z, w1, b1, hid, w2, b2, y):
        for _ in range(n):
            _dense_rows(z, w1, b1, hid, True)
            _dense_rows(hid, w2, b2, y, False)

    @njit
    def history(n, hist, h):
        for _ in range(n):
            _push_history(hist, h, False)

    return {"fk_step": fk_step, "lstm": lstm, "sigmoid": sigmoid, "head": head, "history": history}


def variants(kin: Any, xs: np.ndarray, floor: Callable[[], Any], floor_args: tuple[Any, ...],
             floor_chain: Any) -> dict[str, Callable[[], float]]:
    """The timed variants (module docstring) of the step of `kin` (a fused FK model, one LSTM layer and
    one Dense layer) on the joints xs (K, 2N), each a zero-argument timer returning ns per step."""
    pred = kin.predictor
    fused = pred._fused
    eng = pred._engine
    if fused is None or len(fused.head_w) != 1:
        raise SystemExit("--breakdown needs an FK model with the fused step and one Dense layer (L|D)")
    kin.reset()
    for x in xs[:10]:
        kin.step(x)
    it = iter(np.tile(xs, (1000, 1)))
    shift, prev = pred._shift, pred._prev.copy()
    consts, weights, state_buf, ints = fused._bufs
    scalars = (eng.state, pred._gate_state, pred._outer_motion, pred._outer_prev, 0.0)
    from ctrkin.models.fused import _fk_step

    loops = _loops()
    kernel_args = (np.ascontiguousarray(xs[0]), shift, prev, consts, weights, state_buf, ints, *scalars)
    w_ih, w_hh, b = fused.lstm
    g, t = eng._g[0].copy(), eng._t[0].copy()
    bits = eng._bits[0].copy()
    h, c = eng._h[0].copy(), eng._c[0].copy()
    lstm_args = (eng._x.copy(), w_ih, w_hh, b, h, c, eng._h2[0].copy(), eng._c2[0].copy(), g, t, bits)
    hw, hb = fused.head_w[0][0], fused.head_b[0][0]
    z = np.ascontiguousarray(eng._hist[eng.ib - 1].reshape(1, -1))
    head_args = (z, hw, hb, np.empty((1, hw.shape[0])), fused.out_w[0], fused.out_b[0], np.empty((1, 6)))
    hist = eng._hist.copy()
    fl = floor_args
    for name, fn in loops.items():                                     # compile outside the timing
        fn(1, *{"fk_step": kernel_args, "lstm": lstm_args, "sigmoid": (g.copy(), t.copy(), bits),
                "head": head_args, "history": (hist, h)}[name])
    state = {"fk_step": kernel_args, "lstm": lstm_args, "sigmoid": (g, t, bits), "head": head_args,
             "history": (hist, h)}
    steps: dict[str, Callable[[], float]] = {
        "Kinematics.step": _per_call(lambda: kin.step(next(it)), 1),
        "FKPredictor.step": _per_call(lambda: pred.step(next(it)), 1),
        "the kernel call": _per_call(lambda: _fk_step(next(it), shift, prev, consts, weights, state_buf, ints,
                                                      True, False, *scalars), 1),
    }
    for name in loops:
        fn, a = loops[name], state[name]
        steps[f"loop:{name}"] = _per_call(lambda fn=fn, a=a: fn(LOOP, *a), LOOP)
    steps["floor (a call)"] = _per_call(floor, 1)
    steps["loop:floor"] = _per_call(lambda: _floor_loop(floor_chain)(LOOP, *fl), LOOP)
    return steps


_FLOOR_LOOP: dict[int, Any] = {}


def _floor_loop(chain: Any) -> Any:
    if id(chain) not in _FLOOR_LOOP:
        @njit
        def loop(n, x, w_ih, w_hh, b, h, w1, b1, w2, b2, gates, z, hid, out):
            for _ in range(n):
                chain(x, w_ih, w_hh, b, h, w1, b1, w2, b2, gates, z, hid, out)
        _FLOOR_LOOP[id(chain)] = loop
    return _FLOOR_LOOP[id(chain)]


def measure(timers: dict[str, Callable[[], float]], rounds: int) -> tuple[dict[str, float], dict[str, float]]:
    """Median µs of each timer and median ratio to "floor (a call)", over `rounds` rounds of
    alternating blocks (the order reversed every other round)."""
    names = list(timers)
    for name in names:                                       # warm-up
        for _ in range(5):
            timers[name]()
    per_round: dict[str, list[float]] = {n: [] for n in names}
    for r in range(rounds):
        got: dict[str, list[float]] = {n: [] for n in names}
        for _ in range(4):
            for name in (names if r % 2 == 0 else names[::-1]):
                got[name].extend(timers[name]() for _ in range(BLOCK))
        for name in names:
            per_round[name].append(float(np.median(got[name])) / 1e3)
    floor = np.array(per_round["floor (a call)"])
    us = {n: float(np.median(v)) for n, v in per_round.items()}
    ratio = {n: float(np.median(np.array(v) / floor)) for n, v in per_round.items()}
    return us, ratio


def table(us: dict[str, float], ratio: dict[str, float]) -> dict[str, float]:
    """Print the breakdown (differences between consecutive layers) and return its figures."""
    rows = [
        ("Kinematics.step (the step as timed)", "Kinematics.step", None),
        ("  the face (thread check)", "Kinematics.step", "FKPredictor.step"),
        ("  FKPredictor.step: checks, shift, state, result", "FKPredictor.step", "the kernel call"),
        ("  numba dispatch of the kernel's arguments", "the kernel call", "loop:fk_step"),
        ("  the kernel (in a numba loop)", "loop:fk_step", None),
        ("    LSTM cell updates of the IB chains", "loop:lstm", None),
        ("      of which the two sigmoid passes", "loop:sigmoid", None),
        ("    Dense head and output layer", "loop:head", None),
        ("    history push", "loop:history", None),
        ("    guards, features, gate, frame (the rest)", "loop:fk_step", "loop:lstm+loop:head+loop:history"),
        ("floor, as timed (a call, 13 arguments)", "floor (a call)", None),
        ("  of which dispatch", "floor (a call)", "loop:floor"),
        ("  the chain (in a numba loop)", "loop:floor", None),
    ]

    def value(d: dict[str, float], key: str | None) -> float:
        return sum(d[k] for k in key.split("+")) if key else 0.0

    print(f"{'step breakdown':48s} {'µs':>7s} {'× floor':>8s}")
    out: dict[str, float] = {}
    for label, a, b in rows:
        v_us, v_ratio = value(us, a) - value(us, b), value(ratio, a) - value(ratio, b)
        print(f"{label:48s} {v_us:7.2f} {v_ratio:8.2f}")
        out[label.strip()] = v_us
    return out
