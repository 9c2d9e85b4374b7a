"""Streaming engine: a trained SeqNet (LSTM-MLP, LSTM, MLP) run one step at a time in numba.

Why: a torch module call costs tens of µs of dispatch alone; control loops want one prediction in a few.

How: the network sees windows of the IB latest steps, and each LSTM starts every window from zero
state. The window ending at step t is the chain of cell updates started at step t−IB+1. So we keep IB
chains alive: chain j (j = 0..IB−1) started j steps ago and has consumed j+1 inputs. A new step
advances every chain by one cell update (chain j−1 -> j, a fresh chain 0 starts from zero state) and
retires chain IB−1, whose outputs at its IB positions are exactly the flattened window. Each step
therefore costs IB cell updates per LSTM layer, with the weights read once (the chains are stacked
as rows of one matrix), instead of IB² for recomputing the window.

The start of a sequence is the batch path's padding (the first step repeated): `reset()` marks it and
the first `step()` feeds that step IB times.

All arithmetic is float64, so the engine matches the float32 torch batch path to float32 round-off.
The weight matrices are kept as the float32 numbers torch trained (`_f32`; the LSTM's doubled
cell-candidate rows too, a power of two): each converts to float64 exactly, so the products are
those of float64 weights, and a step reads half the bytes. The products go four weight rows at a
time over the input vector (`_matvec`), which loads each input once for four rows (issue 26: the
paper FK's LSTM cell updates 11.5 → 9.1 µs a step; docs/learned_kinematics.md).
"""

from __future__ import annotations

import numba
import numpy as np
import torch
from torch import nn

from ctrkin.errors import ModelError
from ctrkin.models.seqnet import UNKNOWN_STATE, SeqNet

_LN2_HI, _LN2_LO, _INV_LN2 = 0.693147180369123816490, 1.90821492927058770002e-10, 1.4426950408889634


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def _sigmoid_inplace(x: np.ndarray, bits: np.ndarray) -> None:
    """x <- 1 / (1 + exp(-x)), elementwise on a 1-D array, in loops LLVM vectorises.

    numba's scalar np.exp calls libm one value at a time (no SVML here), which cost more than the
    matrix products; this exp uses Cody-Waite reduction, a degree-11 Taylor polynomial on |r| <= ln2/2
    (relative error < 1e-14) and 2^k built in the exponent bits. bits: int64 scratch of x's size.
    error_model="numpy": numba's default checks each division for zero (Python's ZeroDivisionError),
    a branch that keeps LLVM from vectorising the division loop (issue 26: the scalar divisions were
    half the sigmoid's time); 1 + e^−x ≥ 1 is never zero, and a vector division rounds as a scalar one.
    """
    n = x.size
    for j in range(n):
        v = min(max(-x[j], -700.0), 700.0)
        k = np.floor(v * _INV_LN2 + 0.5)
        r = (v - k * _LN2_HI) - k * _LN2_LO
        p = 1.0 + r * (1.0 + r * (1.0 / 2 + r * (1.0 / 6 + r * (1.0 / 24 + r * (1.0 / 120 + r * (
            1.0 / 720 + r * (1.0 / 5040 + r * (1.0 / 40320 + r * (1.0 / 362880 + r * (
                1.0 / 3628800 + r * (1.0 / 39916800)))))))))))
        x[j] = p
        bits[j] = (np.int64(k) + 1023) << 52
    two_k = bits[:n].view(np.float64)
    for j in range(n):
        x[j] = 1.0 / (1.0 + x[j] * two_k[j])


@numba.njit(cache=True, fastmath=True)
def _matvec(w: np.ndarray, v: np.ndarray, out: np.ndarray, add: bool) -> None:
    """out[k] = Σ_m w[k, m]·v[m] (added to out[k] if `add`) for the rows k of w (K, M), four rows a
    pass over v: each v[m] is loaded once for four rows, and four sums run side by side."""
    rows, cols = w.shape
    top = rows - rows % 4
    for k in range(0, top, 4):
        s0 = s1 = s2 = s3 = 0.0
        for m in range(cols):
            vm = v[m]
            s0 += w[k, m] * vm
            s1 += w[k + 1, m] * vm
            s2 += w[k + 2, m] * vm
            s3 += w[k + 3, m] * vm
        if add:
            out[k] += s0
            out[k + 1] += s1
            out[k + 2] += s2
            out[k + 3] += s3
        else:
            out[k], out[k + 1], out[k + 2], out[k + 3] = s0, s1, s2, s3
    for k in range(top, rows):
        s = 0.0
        for m in range(cols):
            s += w[k, m] * v[m]
        out[k] = out[k] + s if add else s


@numba.njit(cache=True, fastmath=True)
def _lstm_rows(inp: np.ndarray, shared: bool, w_ih: np.ndarray, w_hh: np.ndarray, b: np.ndarray,
               h_prev: np.ndarray, c_prev: np.ndarray, h_new: np.ndarray, c_new: np.ndarray,
               g: np.ndarray, t: np.ndarray, bits: np.ndarray, live: int) -> None:
    """One LSTM cell update for each of the first `live` of R chains (torch gate order i, f, g, o), in
    place.

    inp: (R, in) inputs (row 0 only if `shared`); h_prev, c_prev: (R, H) chain states, row j is the
    chain that becomes row j+1; row 0 of the result starts from zero state. The result is computed
    in h_new, c_new (scratch) and copied back into h_prev, c_prev, so the state arrays keep their
    identity (the fused FK step, ctrkin.models.fused, holds them). Rows from `live` on are left as
    they are: at a sequence's start they are chains begun before it, which no window reads
    (StreamingEngine._advance).
    w_ih, w_hh, b have the cell-candidate rows doubled, so that tanh(g) = 2·σ(2g) − 1 comes out of
    one sigmoid pass over all gates. Scratch: g (R, 4H), t (R, H), bits (R·4H,) int64.
    """
    hid = h_new.shape[1]
    r_count = live
    for r in range(r_count):
        if shared and r > 0:        # same input for every chain: reuse row 0's projection
            for k in range(4 * hid):
                g[r, k] = g[0, k]
        else:
            _matvec(w_ih, inp[r], g[r], False)
            for k in range(4 * hid):
                g[r, k] += b[k]
    for r in range(1, r_count):
        _matvec(w_hh, h_prev[r - 1], g[r], True)
    _sigmoid_inplace(g[:r_count].reshape(-1), bits)
    for r in range(r_count):
        for u in range(hid):
            c = g[r, u] * (2.0 * g[r, 2 * hid + u] - 1.0)       # σ(i)·tanh(g)
            if r > 0:
                c += g[r, hid + u] * c_prev[r - 1, u]          # + σ(f)·c
            c_new[r, u] = c
            t[r, u] = 2.0 * c
    _sigmoid_inplace(t[:r_count].reshape(-1), bits)
    for r in range(r_count):
        for u in range(hid):
            h_new[r, u] = g[r, 3 * hid + u] * (2.0 * t[r, u] - 1.0)    # σ(o)·tanh(c)
    h_prev[:r_count, :] = h_new[:r_count]
    c_prev[:r_count, :] = c_new[:r_count]


@numba.njit(cache=True)
def _push_history(hist: np.ndarray, rows: np.ndarray, shared: bool) -> None:
    """hist (IB, IB, W): chain j's outputs at its positions 0..j. Chain j−1 becomes chain j and each
    chain j appends its new output rows[j] (rows[0] for all if `shared`)."""
    for j in range(hist.shape[0] - 1, 0, -1):
        hist[j] = hist[j - 1]
    for j in range(hist.shape[0]):
        hist[j, j] = rows[0] if shared else rows[j]


@numba.njit(cache=True, fastmath=True)
def _lstm_from(inp: np.ndarray, w_ih: np.ndarray, w_hh: np.ndarray, b: np.ndarray, h0: np.ndarray,
               c0: np.ndarray, fresh: bool, h_new: np.ndarray, g: np.ndarray, t: np.ndarray,
               bits: np.ndarray) -> None:
    """One LSTM cell update of K candidate inputs inp (K, in) from one shared state (h0, c0) (H,), or
    from zero state if `fresh`; weights as in _lstm_rows. Writes h_new (K, H); scratch g (K, 4H),
    t (K, H), bits (K·4H,)."""
    k_count, hid = h_new.shape
    base = np.zeros(4 * hid)
    if not fresh:
        _matvec(w_hh, h0, base, False)
    for r in range(k_count):
        _matvec(w_ih, inp[r], g[r], False)
        for k in range(4 * hid):
            g[r, k] += b[k] + base[k]
    _sigmoid_inplace(g.reshape(-1), bits)
    for r in range(k_count):
        for u in range(hid):
            c = g[r, u] * (2.0 * g[r, 2 * hid + u] - 1.0)
            if not fresh:
                c += g[r, hid + u] * c0[u]
            t[r, u] = 2.0 * c
    _sigmoid_inplace(t.reshape(-1), bits)
    for r in range(k_count):
        for u in range(hid):
            h_new[r, u] = g[r, 3 * hid + u] * (2.0 * t[r, u] - 1.0)


@numba.njit(cache=True, fastmath=True)
def _dense_rows(inp: np.ndarray, w: np.ndarray, b: np.ndarray, out: np.ndarray, relu: bool) -> None:
    """out = act(inp @ w.T + b); inp: (R, in), w: (O, in), out: (R, O)."""
    for r in range(inp.shape[0]):
        _matvec(w, inp[r], out[r], False)
        for k in range(w.shape[0]):
            s = out[r, k] + b[k]
            out[r, k] = max(s, 0.0) if relu else s


def _f64(t: object) -> np.ndarray:
    if not isinstance(t, torch.Tensor):
        raise ModelError(f"expected a weight tensor, got {type(t).__name__}")
    return np.ascontiguousarray(t.detach().cpu().numpy(), dtype=np.float64)


def _f32(w: np.ndarray) -> np.ndarray:
    """A weight matrix as float32, where it is exactly representable (a float32 net's weights, or them
    times a power of two); float64 otherwise (a net trained in float64 keeps its numbers)."""
    w32 = np.ascontiguousarray(w, dtype=np.float32)
    return w32 if np.array_equal(w32, w) else np.ascontiguousarray(w, dtype=np.float64)


class StreamingEngine:
    """Step-by-step twin of a SeqNet. step(x: (F,) normalised features) -> (O,) normalised outputs."""

    def __init__(self, net: SeqNet) -> None:
        if not isinstance(net, SeqNet):
            raise ModelError(f"the streaming engine runs SeqNet models, not {type(net).__name__}")
        self.ib = net.ib
        self.pooling = net.pooling
        self.relu_out = net.output_activation == "relu"
        self.seq: list[tuple[str, tuple[np.ndarray, ...]]] = []
        width = net.n_inputs
        for layer in net.seq:
            if isinstance(layer, nn.LSTM):
                hid = layer.hidden_size
                scale = np.ones((4 * hid, 1))
                scale[2 * hid:3 * hid] = 2.0          # see _lstm_rows: tanh(g) = 2σ(2g) − 1
                self.seq.append(("lstm", (_f32(_f64(layer.weight_ih_l0) * scale),
                                          _f32(_f64(layer.weight_hh_l0) * scale),
                                          (_f64(layer.bias_ih_l0) + _f64(layer.bias_hh_l0)) * scale[:, 0])))
                width = hid
            else:
                assert isinstance(layer, nn.Linear)
                self.seq.append(("dense", (_f32(_f64(layer.weight)), _f64(layer.bias))))
                width = layer.out_features
        # one head per state of a net that carries one (SeqNet.heads), and its gate MLP on the trunk
        # features with the previous state appended (SeqNet.gate_layers)
        self.heads = [([(_f32(_f64(lin.weight)), _f64(lin.bias)) for lin in head],
                       (_f32(_f64(out.weight)), _f64(out.bias))) for head, out in net.heads()]
        self.head, self.out = self.heads[0]
        gate = net.gate_layers()
        self.gate = [] if gate is None else [(_f64(lin.weight), _f64(lin.bias)) for lin in gate]
        self.state = UNKNOWN_STATE
        ib = self.ib
        self._h = [np.zeros((ib, w[1].shape[1])) if kind == "lstm" else np.zeros(0)
                   for kind, w in self.seq]
        self._c = [np.zeros_like(h) for h in self._h]
        self._h2 = [np.zeros_like(h) for h in self._h]
        self._c2 = [np.zeros_like(h) for h in self._h]
        self._g = [np.zeros((ib, 4 * h.shape[-1])) if h.ndim == 2 else np.zeros((0, 0)) for h in self._h]
        self._t = [np.zeros_like(h) for h in self._h]
        self._bits = [np.zeros(g.size, dtype=np.int64) for g in self._g]
        self._rows = [np.zeros((ib, w[0].shape[0] if kind == "dense" else w[1].shape[1]))
                      for kind, w in self.seq]
        self._hist = np.zeros((ib, ib, width))    # chain j's outputs at positions 0..j
        self._head_bufs = [np.zeros((1, w.shape[0])) for w, _ in self.head]
        self._gate_bufs = [np.zeros((1, w.shape[0])) for w, _ in self.gate]
        self._y = np.zeros((1, self.out[0].shape[0]))
        self._x = np.zeros((1, net.n_inputs))
        self._fresh = True

    def reset(self) -> None:
        """Start a new sequence: the next step is its first (and is repeated to fill the buffer)."""
        self._fresh = True
        self.state = UNKNOWN_STATE

    def step(self, x: np.ndarray, state: float | None = None) -> np.ndarray:
        """x: (F,) normalised features of the current step -> (O,) normalised outputs. state: a
        state-carrying net's state from outside (a snap-aware model's fold gate) in place of its
        learned gate's."""
        self._x[0, :] = x
        if self._fresh:
            self._fresh = False
            for live in range(1, self.ib):
                self._advance(live)
        return self._head(self._advance(self.ib), state)

    def probe(self, xs: np.ndarray, states: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Outputs (K, O) and branch states (K,) that `step` would return for each of K candidate
        feature rows xs (K, F) at the next step, without changing the engine (IK refinement asks
        the learned FK "where would the tip be if the next joints were these?"). states (K,): the
        branch states from outside, as in `step`."""
        xs = np.ascontiguousarray(xs, dtype=np.float64)
        k_count = len(xs)
        if self._fresh:          # the window would be the candidate repeated: run each one aside
            return self._probe_fresh(xs, states)
        ib, inp = self.ib, xs
        for k, (kind, w) in enumerate(self.seq):
            if kind == "lstm":
                hid = w[1].shape[1]
                out = np.empty((k_count, hid))
                g, t = np.empty((k_count, 4 * hid)), np.empty((k_count, hid))
                row = max(ib - 2, 0)    # the chain that becomes the full window at this step
                _lstm_from(inp, w[0], w[1], w[2], self._h[k][row], self._c[k][row], ib == 1, out, g, t,
                           np.empty(g.size, dtype=np.int64))
            else:
                out = np.empty((k_count, w[0].shape[0]))
                _dense_rows(inp, w[0], w[1], out, True)
            inp = out
        width = inp.shape[1]
        if self.pooling == "flatten":
            h = np.empty((k_count, ib * width))
            h[:, : (ib - 1) * width] = self._hist[ib - 2, : ib - 1].reshape(-1) if ib > 1 else 0.0
            h[:, (ib - 1) * width:] = inp
        else:
            h = inp
        return self._head_rows(h, states)

    def _probe_fresh(self, xs: np.ndarray, states: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        saved = (self._fresh, self.state)
        ys, ss = [], []
        for k, x in enumerate(xs):
            self._fresh, self.state = saved
            keep = [a.copy() for a in (*self._h, *self._c, self._hist)]
            ys.append(self.step(x, None if states is None else float(states[k])))
            ss.append(self.state)
            for dst, src in zip([*self._h, *self._c, self._hist], keep, strict=True):
                dst[...] = src
        self._fresh, self.state = saved
        return np.array(ys), np.array(ss)

    def _head_rows(self, h: np.ndarray, given: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """_head for K rows at once from the current state, without updating it."""
        k_count = len(h)
        states = np.full(k_count, self.state)
        if self.gate and given is not None:
            states = np.asarray(given, dtype=np.float64)
        elif self.gate:
            z = np.empty((k_count, h.shape[1] + 1))
            z[:, :-1] = h
            z[:, -1] = self.state
            g1 = np.empty((k_count, self.gate[0][0].shape[0]))
            g2 = np.empty((k_count, 1))
            _dense_rows(z, self.gate[0][0], self.gate[0][1], g1, True)
            _dense_rows(g1, self.gate[1][0], self.gate[1][1], g2, False)
            states = np.where(g2[:, 0] > 0, 1.0, 0.0)
        y = np.empty((k_count, self.out[0].shape[0]))
        for branch, (head, out) in enumerate(self.heads):
            rows = np.nonzero(states == branch)[0] if self.gate else np.arange(k_count)
            if len(rows) == 0:
                continue
            x = h[rows]
            for hw, hb in head:
                buf = np.empty((len(rows), hw.shape[0]))
                _dense_rows(x, hw, hb, buf, True)
                x = buf
            yb = np.empty((len(rows), out[0].shape[0]))
            _dense_rows(x, out[0], out[1], yb, self.relu_out)
            y[rows] = yb
        return y, states

    def _head(self, h: np.ndarray, state: float | None = None) -> np.ndarray:
        """h: (1, W) trunk features -> (O,) outputs; a net with a state first updates it (from its
        gate, or to `state` when given)."""
        head, out = self.head, self.out
        if self.gate and state is not None:
            self.state = 1.0 if state > 0.5 else 0.0
            head, out = self.heads[int(self.state)]
        elif self.gate:
            z = np.empty((1, h.shape[1] + 1))
            z[0, :-1] = h[0]
            z[0, -1] = self.state
            _dense_rows(z, self.gate[0][0], self.gate[0][1], self._gate_bufs[0], True)
            _dense_rows(self._gate_bufs[0], self.gate[1][0], self.gate[1][1], self._gate_bufs[1], False)
            self.state = 1.0 if self._gate_bufs[1][0, 0] > 0 else 0.0
            head, out = self.heads[int(self.state)]
        for (hw, hb), buf in zip(head, self._head_bufs, strict=True):
            _dense_rows(h, hw, hb, buf, True)
            h = buf
        _dense_rows(h, out[0], out[1], self._y, self.relu_out)
        return self._y[0].copy()

    def _advance(self, live: int) -> np.ndarray:
        """Every chain one cell update on: the first `live` of them (at a sequence's start, the
        chains begun within it; _lstm_rows), the others as they are."""
        inp: np.ndarray = self._x
        shared = True
        for k, (kind, w) in enumerate(self.seq):
            if kind == "lstm":
                _lstm_rows(inp, shared, w[0], w[1], w[2], self._h[k], self._c[k], self._h2[k], self._c2[k],
                           self._g[k], self._t[k], self._bits[k], live)
                inp = self._h[k]
            else:
                if shared:  # a Dense first layer on identical rows: compute once, copy
                    _dense_rows(inp, w[0], w[1], self._rows[k][:1], True)
                    self._rows[k][1:] = self._rows[k][0]
                else:
                    _dense_rows(inp, w[0], w[1], self._rows[k], True)
                inp = self._rows[k]
            shared = False
        _push_history(self._hist, inp, shared)
        window = self._hist[self.ib - 1]                 # retiring chain: the full window
        return window.reshape(1, -1) if self.pooling == "flatten" else window[-1:].copy()
