"""Fast batch prediction of a SeqNet over whole sequences, by chains instead of windows.

The windows of consecutive steps overlap: the window ending at t is the chain of cell updates started
at step t−IB+1 from zero state. Evaluating all chains position by position turns the work into a few
large matrix products: the input projection of the first LSTM is computed once per step (not once per
window position), and position 0 of every chain needs no recurrent product (zero state). For the
paper's IB = 2 this halves the LSTM work of running nn.LSTM on (T, IB, F) windows, and avoids its
per-call overhead. Equal to `net(windows)` up to float32 round-off (tested).

A network whose per-step layers are one LSTM (the paper's L128|D64) keeps torch for the products (float32
BLAS) and does each position's gates and cell update in one float32 numba pass (`_lstm_position`),
in chunks of FUSED_CHUNK rows with buffers each thread keeps: about ten torch operations over the
gate values, each a pass over memory, and fresh buffers' page faults cost more than the products at
mid-size batches (issue 26; docs/learned_kinematics.md: Against the floor).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from typing import TypeVar, cast

import numba
import numpy as np
import torch
from torch import nn

from ctrkin.models.feature_row import paper_feature_row
from ctrkin.models.seqnet import SeqNet
from ctrkin.models.sigmoid32 import _sigmoid32

_F32 = np.float32
_T = TypeVar("_T")
FUSED_CHUNK = 256      # rows per chunk of the one-LSTM pass: its gate buffers (0.5 MB) stay in L2


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def _lstm_position(rec: np.ndarray, gx: np.ndarray, first: bool, c: np.ndarray, out: np.ndarray,
                   col: int) -> None:
    """One LSTM position for n chains, elementwise in one pass per chain (float32): gates = gx (n, 4H)
    (the input projections with the bias) + rec (n, 4H) (the recurrent products; not read if
    `first`: zero state), gate order i, f, g, o with the g rows doubled (tanh(g) = 2σ(2g) − 1, as
    `_scaled`); c (n, H) the cell states, updated; h (n, H) written to out[:, col:col + H]."""
    n, four_h = gx.shape
    hid = four_h // 4
    g = np.empty(four_h, np.float32)
    t = np.empty(hid, np.float32)
    bits = np.empty(four_h, np.int32)
    two_k = bits.view(np.float32)
    for r in range(n):
        if first:
            for k in range(four_h):
                g[k] = gx[r, k]
        else:
            for k in range(four_h):
                g[k] = gx[r, k] + rec[r, k]
        _sigmoid32(g, bits, two_k)
        for u in range(hid):
            cc = g[u] * (_F32(2.0) * g[2 * hid + u] - _F32(1.0))           # σ(i)·tanh(g)
            if not first:
                cc += g[hid + u] * c[r, u]                                  # + σ(f)·c
            c[r, u] = cc
            t[u] = _F32(2.0) * cc
        _sigmoid32(t, bits, two_k)
        for u in range(hid):
            out[r, col + u] = g[3 * hid + u] * (_F32(2.0) * t[u] - _F32(1.0))   # σ(o)·tanh(c)


@numba.njit(cache=True)
def fk_padded_rows(raw: np.ndarray, starts: np.ndarray, ib: int, n: int, phase: bool, delta: bool,
                   lo: np.ndarray, span: np.ndarray, dlo: float, dhi: float) -> tuple[np.ndarray, np.ndarray]:
    """`padded_rows` of an FK model's normalised features in one pass, float32: raw (T, 2N) the joints
    the network sees (deg, mm), starts (S + 1,) the sequences' first rows and T; the paper's features
    (eq. 1, 2: α1..αN, β1..βN, α0, [sin α0, cos α0 with phase], [Δα0 clipped to [dlo, dhi]]), each
    column (x − lo) / span (MinMax.transform). The same float64 arithmetic as sequence_features,
    clip_deltas and MinMax.transform, rounded once to float32. Returns (padded (T + (IB−1)·S, F),
    window starts (T,))."""
    t_rows = raw.shape[0]
    n_seq = starts.size - 1
    f = lo.size
    out = np.empty((t_rows + (ib - 1) * n_seq, f), np.float32)
    win = np.empty(t_rows, np.int64)
    feat = np.empty(f)
    kd = 2 * n + 3 if phase else 2 * n + 1                                 # Δα0's column
    pos = 0
    for s in range(n_seq):
        a, b = starts[s], starts[s + 1]
        for t in range(a, b):
            p = t - 1 if t > a else t
            paper_feature_row(raw[t], n, raw[p, 0] - raw[p, n - 1], t > a, phase, delta, feat)
            if delta:
                feat[kd] = min(max(feat[kd], dlo), dhi)
            row = pos + (t - a) + ib - 1
            for j in range(f):
                out[row, j] = (feat[j] - lo[j]) / span[j]
            if t == a:                                                       # the start's padding
                for q in range(ib - 1):
                    out[pos + q] = out[row]
            win[t] = pos + (t - a)
        pos += b - a + ib - 1
    return out, win


@numba.njit(cache=True)
def fk_poses(yn: np.ndarray, lo: np.ndarray, span: np.ndarray) -> np.ndarray:
    """(T, 6) float64 poses of the network's normalised outputs yn (T, 6): yn · span + lo
    (MinMax.inverse) and the quaternion (q0, qx, qy) rescaled to unit length (features.postprocess),
    in one pass."""
    y = np.empty((yn.shape[0], 6))
    for t in range(yn.shape[0]):
        for j in range(6):
            y[t, j] = np.float64(yn[t, j]) * span[j] + lo[j]
        nq = np.sqrt(y[t, 3] * y[t, 3] + y[t, 4] * y[t, 4] + y[t, 5] * y[t, 5])
        if nq > 1e-12:
            for j in range(3, 6):
                y[t, j] /= nq
    return y


def padded_rows(features: np.ndarray, bounds: list[tuple[int, int]], ib: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """features (T, F) -> padded (T + (IB−1)·S, F), each sequence preceded by IB−1 copies of its first
    step, and starts (T,): where in the padded rows each step's window begins."""
    parts, starts, pos = [], [], 0
    for a, b in bounds:
        parts.append(np.repeat(features[a:a + 1], ib - 1, axis=0))
        parts.append(features[a:b])
        starts.append(pos + np.arange(b - a))
        pos += b - a + ib - 1
    if not parts:
        return np.zeros((0, features.shape[1])), np.zeros(0, dtype=np.int64)
    return np.concatenate(parts), np.concatenate(starts)


def _scaled_lstm_weights(layer: nn.LSTM) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(W_ih, W_hh, b) with the cell-candidate rows doubled, so one in-place sigmoid over all four
    gates also gives tanh(g) = 2·σ(2g) − 1 (fewer passes over memory than sigmoid + tanh). Kept on
    the layer while its parameters are unchanged (`_kept`): building them cost ~30 µs of a predict
    call."""
    return _kept(layer, "_ctrkin_scaled", [getattr(layer, n) for n in _LSTM_PARAMS], lambda: _scaled(layer))


def _pass_weights(layer: nn.LSTM) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(W_ihᵀ, W_hhᵀ, b) of `_scaled_lstm_weights` as the one-LSTM pass multiplies them, kept with
    them (each torch call costs microseconds: transposes made per chunk add up)."""
    scaled = _scaled_lstm_weights(layer)                 # the same tuple while it is kept
    cached = layer.__dict__.get("_ctrkin_pass")
    if cached is None or cached[0] is not scaled:
        cached = layer.__dict__["_ctrkin_pass"] = (scaled, (scaled[0].t(), scaled[1].t(), scaled[2]))
    return cast(tuple[torch.Tensor, torch.Tensor, torch.Tensor], cached[1])


_LSTM_PARAMS = ("weight_ih_l0", "weight_hh_l0", "bias_ih_l0", "bias_hh_l0")


def _kept(owner: nn.Module, name: str, params: list[torch.Tensor], build: Callable[[], _T]) -> _T:
    """build(), made once and kept on `owner` under `name` while `params` are the same tensors at
    the same versions (an optimiser's in-place step or a new tensor makes it again)."""
    key = tuple((id(p), p._version) for p in params)
    cached = owner.__dict__.get(name)
    if cached is not None and cached[0] == key:
        return cast(_T, cached[1])
    value = build()
    owner.__dict__[name] = (key, value)
    return value


def _scaled(layer: nn.LSTM) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    hid = layer.hidden_size
    scale = torch.ones(4 * hid, 1)
    scale[2 * hid:3 * hid] = 2.0
    w_ih, w_hh, b_ih, b_hh = (_tensor(getattr(layer, n)) for n in
                              ("weight_ih_l0", "weight_hh_l0", "bias_ih_l0", "bias_hh_l0"))
    return w_ih * scale, w_hh * scale, (b_ih + b_hh) * scale[:, 0]


def _tensor(t: object) -> torch.Tensor:
    assert isinstance(t, torch.Tensor)
    return t


def _lstm_positions(weights: tuple[torch.Tensor, torch.Tensor, torch.Tensor], inputs: list[torch.Tensor],
                    gx_shared: torch.Tensor | None) -> list[torch.Tensor]:
    """Run every chain through one LSTM layer. inputs[k]: (C, in) the k-th input of each chain (or
    gx_shared (C + IB − 1, 4H): input projections of consecutive rows, chain c at position k uses row
    c + k). Returns the outputs (C, H) per position. Gate order i, f, g, o (torch)."""
    w_ih, w_hh, bias = weights
    n = inputs[0].shape[0] if gx_shared is None else gx_shared.shape[0] - len(inputs) + 1
    outs = []
    h: torch.Tensor | None = None
    c: torch.Tensor | None = None
    for k in range(len(inputs)):
        if gx_shared is not None:
            g = gx_shared[k:k + n] if h is None else torch.addmm(gx_shared[k:k + n], h, w_hh.t())
        else:
            g = torch.addmm(bias, inputs[k], w_ih.t())
            if h is not None:
                g = g.addmm_(h, w_hh.t())
        g = torch.sigmoid(g) if gx_shared is not None and h is None else g.sigmoid_()
        i, f, gg, o = g.chunk(4, dim=1)
        c_new = i * gg.mul_(2.0).sub_(1.0)                 # σ(i)·tanh(g)
        if c is not None:
            c_new.addcmul_(f, c)                           # + σ(f)·c
        c = c_new
        h = torch.mul(c, 2.0).sigmoid_().mul_(2.0).sub_(1.0).mul_(o)   # σ(o)·tanh(c)
        outs.append(h)
    return outs


@torch.inference_mode()
def seqnet_predict(net: SeqNet, padded: np.ndarray, starts: np.ndarray, chunk: int = 1024) -> np.ndarray:
    """padded: (P, F) normalised features with sequence-start padding; starts: (T,) window starts.
    Returns (T, O) normalised outputs, equal to net(windows)."""
    out = np.empty((len(starts), net.n_outputs), dtype=np.float32)
    head = _one_dense_head(net)
    relu_out = net.output_activation == "relu"
    for sl, h in _trunk_chunks(net, padded, starts, chunk):
        if head is None:
            out[sl] = net.head_out(h).numpy()
            continue
        w1t, b1, w2, b2 = head                          # Dense + ReLU by torch, the output layer here
        hid, hid_t = _scratch_t("hid", (h.shape[0], w1t.shape[1]))
        torch.addmm(b1, h, w1t, out=hid_t)
        _relu_dense(hid, w2, b2, relu_out, out[sl])
    return out


def _one_dense_head(net: SeqNet) -> tuple[torch.Tensor, torch.Tensor, np.ndarray, np.ndarray] | None:
    """(W1ᵀ (in, H1) contiguous, b1, W2 (O, H1), b2) of a SeqNet's head of one Dense layer (the paper's
    D64), kept on the net while its parameters are unchanged; None for any other head or a net whose
    head_out differs (a state-carrying net)."""
    if type(net).head_out is not SeqNet.head_out or len(net.head) != 1:
        return None
    dense, out = net.head[0], net.out
    assert isinstance(dense, nn.Linear)
    return _kept(net, "_ctrkin_head", [dense.weight, dense.bias, out.weight, out.bias],
                 lambda: (dense.weight.detach().t().contiguous(), dense.bias.detach().clone(),
                          np.ascontiguousarray(out.weight.detach().numpy()),
                          np.ascontiguousarray(out.bias.detach().numpy())))


@numba.njit(cache=True, fastmath=True)
def _relu_dense(hid: np.ndarray, w: np.ndarray, b: np.ndarray, relu_out: bool, out: np.ndarray) -> None:
    """out (n, O) = act(W · ReLU(hid) + b) per row (eq. 6, 7): hid (n, H1) the Dense layer's
    pre-activations, w (O, H1), act ReLU if relu_out (the output activation) else identity."""
    n, h1 = hid.shape
    for r in range(n):
        for j in range(h1):
            hid[r, j] = max(hid[r, j], np.float32(0.0))
        for o in range(w.shape[0]):
            s = b[o]
            for j in range(h1):
                s += w[o, j] * hid[r, j]
            out[r, o] = max(s, np.float32(0.0)) if relu_out else s


@torch.inference_mode()
def seqnet_trunk(net: SeqNet, padded: np.ndarray, starts: np.ndarray, chunk: int = 1024) -> torch.Tensor:
    """(T, trunk_width) trunk features (net.trunk of every window), by chains; arguments as
    `seqnet_predict`."""
    parts = [h.clone() for _, h in _trunk_chunks(net, padded, starts, chunk)]   # a chunk may be a buffer
    return torch.cat(parts) if parts else torch.zeros((0, net.trunk_width))


def _trunk_chunks(net: SeqNet, padded: np.ndarray, starts: np.ndarray, chunk: int
                  ) -> Iterator[tuple[slice, torch.Tensor]]:
    """Yield (slice of rows, trunk features (rows, W)) chunk by chunk; the features may be a view of
    a buffer the next chunk overwrites (`_one_lstm`): use them before asking for the next."""
    ib = net.ib
    x_all = torch.from_numpy(np.ascontiguousarray(padded, dtype=np.float32))
    s_all = torch.from_numpy(np.asarray(starts, dtype=np.int64))
    # one LSTM layer (the paper's L128|D64): its elementwise work in one numba pass per position
    fused = net.seq[0] if len(net.seq) == 1 and isinstance(net.seq[0], nn.LSTM) else None
    weights = {} if fused is not None else {id(m): _scaled_lstm_weights(m) for m in net.seq
                                            if isinstance(m, nn.LSTM)}
    if fused is not None:
        chunk = min(chunk, FUSED_CHUNK)
    done = 0
    while done < len(starts):
        lo = int(starts[done])
        hi = min(lo + chunk, len(padded) - ib + 1)                 # chains starting in [lo, hi)
        n_here = int(np.searchsorted(starts, hi, side="left")) - done
        rows = x_all[lo:hi + ib - 1]
        n = hi - lo
        if fused is not None:
            h = _one_lstm(fused, rows, n, ib, net.pooling)          # this thread's buffer
            yield slice(done, done + n_here), h if n_here == n else h[s_all[done:done + n_here] - lo]
            done += n_here
            continue
        inputs = [rows[k:k + n] for k in range(ib)]
        first = True
        for layer in net.seq:
            if isinstance(layer, nn.LSTM):
                w = weights[id(layer)]
                gx = torch.addmm(w[2], rows, w[0].t()) if first else None   # shared rows: project once
                inputs = _lstm_positions(w, inputs, gx)
            else:
                assert isinstance(layer, nn.Linear)
                if first:
                    z = torch.relu(layer(rows))
                    inputs = [z[k:k + n] for k in range(ib)]
                else:
                    inputs = [torch.relu(layer(v)) for v in inputs]
            first = False
        h = torch.cat(inputs, dim=1) if net.pooling == "flatten" else inputs[-1]
        sel = s_all[done:done + n_here] - lo
        yield slice(done, done + n_here), h[sel]
        done += n_here


def _one_lstm(layer: nn.LSTM, rows: torch.Tensor, n: int, ib: int, pooling: str) -> torch.Tensor:
    """The trunk features (n, IB·H | H) of the n chains starting at rows[0..n) (rows: (n + IB − 1, F))
    of a network whose per-step layers are one LSTM: the products by torch (float32 BLAS), the gates
    and cell updates by `_lstm_position` (one pass, instead of about ten torch operations over the
    gate values: issue 26, B = 1,024), in buffers this thread keeps (valid until its next call)."""
    w_ih_t, w_hh_t, bias = _pass_weights(layer)
    hid = w_hh_t.shape[0]
    gx, gx_t = _scratch_t("gx", (n + ib - 1, 4 * hid))
    torch.addmm(bias, rows, w_ih_t, out=gx_t)                          # each row's projection once
    window, win_t = _scratch_t("window", (n, ib * hid))
    rec, rec_t = _scratch_t("rec", (n, 4 * hid))
    c = _scratch("c", (n, hid))
    for k in range(ib):
        if k > 0:
            h_prev = _scratch_t("window", (n, ib * hid), ((k - 1) * hid, k * hid))[1]
            torch.mm(h_prev, w_hh_t, out=rec_t)
        _lstm_position(rec, gx[k:k + n], k == 0, c, window, k * hid)
    if pooling == "flatten":
        return win_t
    return _scratch_t("window", (n, ib * hid), ((ib - 1) * hid, ib * hid))[1]


_SCRATCH = threading.local()


def _scratch(name: str, shape: tuple[int, int]) -> np.ndarray:
    """A float32 array of `shape` that this thread keeps between calls under `name` (one allocated
    afresh each call cost its page faults: ~0.5 ms of a 1,024-row call)."""
    size = shape[0] * shape[1]
    buf = _SCRATCH.__dict__.get(name)
    if buf is None or buf.size < size:
        buf = _SCRATCH.__dict__[name] = np.empty(size, np.float32)
    return buf[:size].reshape(shape)


MAX_VIEWS = 64     # torch views of the scratch buffers kept per thread (then made anew)


def _scratch_t(name: str, shape: tuple[int, int], cols: tuple[int, int] | None = None
               ) -> tuple[np.ndarray, torch.Tensor]:
    """`_scratch(name, shape)` and a torch tensor on it (of its columns cols[0]:cols[1], if given),
    kept while the buffer is: a torch call or view costs microseconds, and a chunk of the one-LSTM
    pass asks for about ten."""
    views = _SCRATCH.__dict__.setdefault("views", {})
    key = (name, shape, cols)
    got = views.get(key)
    arr = _scratch(name, shape)
    if got is not None and got[2] is _SCRATCH.__dict__[name]:
        return got[0], got[1]
    if len(views) >= MAX_VIEWS:
        views.clear()
    tensor = torch.from_numpy(arr if cols is None else arr[:, cols[0]:cols[1]])
    views[key] = (arr, tensor, _SCRATCH.__dict__[name])
    return arr, tensor
