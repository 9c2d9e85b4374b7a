"""A one-layer LSTM over (B, IB, F) windows from zero state, for training: forward and a hand-written
backward (torch.autograd.Function), the gate math of each position fused into one float32 numba pass.

Why (issue 26, goal 3): at batch 1024 torch's nn.LSTM (oneDNN) took 87 % of a training step of the
paper's LSTM-MLP, most of it not in the matrix products: ~10 elementwise passes over the (B, 4H) gate
values per position and direction, and torch's float32 tanh costs ~8 ns an element on this machine.
Here each position is one product (torch, MKL) and one pass that reads the gate pre-activations and
writes everything the backward needs. Two savings come from the zero initial state (paper eq. 3, 4:
every window starts from h = c = 0): position 0 has no recurrent product (nn.LSTM multiplies W_hh by
zeros) and no forget-gate gradient; at the paper's IB = 2 this removes half the recurrent work.

Equations (gate order i, f, g, o as torch):
  forward   a_t = x_t W_ihᵀ + b_ih + b_hh + h_{t−1} W_hhᵀ   (no product at t = 0)
            i, f, o = σ(a_i, a_f, a_o); g = tanh(a_g); c_t = f·c_{t−1} + i·g; h_t = o·tanh(c_t)
  backward  dc_t = dh_t·o·(1 − tanh²c_t) + dc_{t+1}·f_{t+1}
            da_o = dh_t·tanh(c_t)·o(1 − o); da_i = dc_t·g·i(1 − i); da_g = dc_t·i(1 − g²);
            da_f = dc_t·c_{t−1}·f(1 − f) (0 at t = 0); dh_{t−1} += da_t W_hh
            dW_ih = Σ_t da_tᵀ x_t; dW_hh = Σ_{t≥1} da_tᵀ h_{t−1}; db_ih = db_hh = Σ_t da_t
σ and tanh(x) = 2σ(2x) − 1 use sigmoid32's float32 sigmoid (relative error < 1e-7). Equal to nn.LSTM's
outputs and gradients within float32 round-off (tests/models/test_window_lstm.py).
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
import torch
from torch import nn

from ctrkin.models.sigmoid32 import _sigmoid32

_F32 = np.float32


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def _forward_position(gx: np.ndarray, rec: np.ndarray, first: bool, c_prev: np.ndarray, acts: np.ndarray,
                      c: np.ndarray, tc: np.ndarray, h: np.ndarray) -> None:
    """One position for n windows (float32): gx (n, 4H) input projections with both biases, rec (n, 4H)
    the recurrent products (not read if `first`), c_prev (n, H) the previous cell (not read if `first`).
    Writes acts (n, 4H) = σ(a_i), σ(a_f), tanh(a_g), σ(a_o); c (n, H); tc (n, H) = tanh(c); h (n, H)."""
    n, four_h = gx.shape
    hid = four_h // 4
    g = np.empty(four_h, _F32)
    t = np.empty(hid, _F32)
    bits = np.empty(four_h, np.int32)
    two_k = bits.view(_F32)
    for r in range(n):
        if first:
            for k in range(four_h):
                g[k] = gx[r, k]
        else:
            for k in range(four_h):
                g[k] = gx[r, k] + rec[r, k]
        for u in range(2 * hid, 3 * hid):
            g[u] *= _F32(2.0)
        _sigmoid32(g, bits, two_k)
        for u in range(2 * hid, 3 * hid):
            g[u] = _F32(2.0) * g[u] - _F32(1.0)                       # tanh(a_g) = 2σ(2a_g) − 1
        for k in range(four_h):
            acts[r, k] = g[k]
        for u in range(hid):
            cc = g[u] * g[2 * hid + u]                                 # σ(i)·tanh(g)
            if not first:
                cc += g[hid + u] * c_prev[r, u]                        # + σ(f)·c
            c[r, u] = cc
            t[u] = _F32(2.0) * cc
        _sigmoid32(t, bits, two_k)
        for u in range(hid):
            th = _F32(2.0) * t[u] - _F32(1.0)
            tc[r, u] = th
            h[r, u] = g[3 * hid + u] * th                              # σ(o)·tanh(c)


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def _backward_position(acts: np.ndarray, tc: np.ndarray, c_prev: np.ndarray, first: bool, dh: np.ndarray,
                       dh_rec: np.ndarray, has_rec: bool, dc: np.ndarray, da: np.ndarray) -> None:
    """The backward of one position (module docstring): acts, tc, c_prev as `_forward_position` saved
    them; dh (n, H) the gradient of h_t from the layers above, dh_rec (n, H) from position t + 1 (read
    if `has_rec`); dc (n, H) in: dc_{t+1}·f_{t+1} (zeros at the last position), out: dc_t·f_t.
    Writes da (n, 4H), the gradient of the gate pre-activations."""
    n, hid = tc.shape
    for r in range(n):
        for u in range(hid):
            i = acts[r, u]
            f = acts[r, hid + u]
            gg = acts[r, 2 * hid + u]
            o = acts[r, 3 * hid + u]
            th = tc[r, u]
            d_h = dh[r, u]
            if has_rec:
                d_h += dh_rec[r, u]
            d_c = d_h * o * (_F32(1.0) - th * th) + dc[r, u]
            da[r, u] = d_c * gg * i * (_F32(1.0) - i)
            da[r, 2 * hid + u] = d_c * i * (_F32(1.0) - gg * gg)
            da[r, 3 * hid + u] = d_h * th * o * (_F32(1.0) - o)
            if first:
                da[r, hid + u] = _F32(0.0)
            else:
                da[r, hid + u] = d_c * c_prev[r, u] * f * (_F32(1.0) - f)
            dc[r, u] = d_c * f


class _Workspace:
    """The buffers of one forward and its backward, position-major (contiguous per position): gx
    (IB, B, 4H) the input projections, rec (B, 4H) a recurrent product, acts (IB, B, 4H), c and tc
    (IB, B, H); da (IB, B, 4H), dc and dh_rec (B, H) for the backward."""

    def __init__(self, n: int, ib: int, hid: int) -> None:
        self.gx = torch.empty(ib, n, 4 * hid)
        self.acts = torch.empty(ib, n, 4 * hid)
        self.c, self.tc = torch.empty(ib, n, hid), torch.empty(ib, n, hid)
        self.rec = torch.empty(n, 4 * hid)
        self.da = torch.empty(ib, n, 4 * hid)
        self.dc, self.dh_rec = torch.empty(n, hid), torch.empty(n, hid)


_POOL: dict[tuple[int, int, int], list[_Workspace]] = {}
POOL_SHAPES = 4     # workspaces kept for this many (B, IB, H) shapes (a full batch and an epoch's last)


def _take(n: int, ib: int, hid: int) -> _Workspace:
    """A workspace a finished backward gave back, or a new one: fresh buffers of a few MB cost their
    page faults on every call (measured: more than the gate math)."""
    free = _POOL.get((n, ib, hid))
    if free:
        return free.pop()
    with torch.inference_mode(False):   # made in validation, still writable by a training step
        return _Workspace(n, ib, hid)


def _give_back(ws: _Workspace) -> None:
    n, ib, hid = ws.c.shape[1], ws.c.shape[0], ws.c.shape[2]
    if (n, ib, hid) not in _POOL and len(_POOL) >= POOL_SHAPES:
        _POOL.pop(next(iter(_POOL)))
    _POOL.setdefault((n, ib, hid), []).append(ws)


class _WindowLSTM(torch.autograd.Function):
    """x (B, IB, F), the layer's weights -> h (B, IB, H), every window from zero state. The forward's
    buffers go back to a pool once its backward has run (a second backward of the same graph, with
    retain_graph, is refused: they may hold another forward's values by then)."""

    @staticmethod
    def forward(ctx: Any, x: torch.Tensor, w_ih: torch.Tensor, w_hh: torch.Tensor, b_ih: torch.Tensor,
                b_hh: torch.Tensor) -> torch.Tensor:
        n, ib, nf = x.shape
        hid = w_hh.shape[1]
        ws = _take(n, ib, hid)
        xt = x.transpose(0, 1).reshape(ib * n, nf)                       # position-major rows
        torch.addmm(b_ih + b_hh, xt, w_ih.t(), out=ws.gx.view(ib * n, 4 * hid))
        h = torch.empty(n, ib, hid)
        a_np, c_np, tc_np, gx_np = ws.acts.numpy(), ws.c.numpy(), ws.tc.numpy(), ws.gx.numpy()
        h_np = h.numpy()
        rec, w_hh_t = ws.rec, w_hh.t()
        for t in range(ib):
            if t:
                torch.mm(h[:, t - 1], w_hh_t, out=rec)
            _forward_position(gx_np[t], rec.numpy(), t == 0, c_np[max(t - 1, 0)], a_np[t], c_np[t],
                              tc_np[t], h_np[:, t])
        if not any(ctx.needs_input_grad):           # no backward will come
            _give_back(ws)
            return h
        ctx.ws = ws
        ctx.save_for_backward(xt, w_ih, w_hh, h)
        return h

    @staticmethod
    def backward(ctx: Any, dh: torch.Tensor) -> tuple[torch.Tensor | None, ...]:
        ws = ctx.ws
        if ws is None:
            raise RuntimeError("window_lstm: backward through the same graph twice is not supported")
        ctx.ws = None
        xt, w_ih, w_hh, h = ctx.saved_tensors
        n, ib, hid = h.shape
        dh_np = dh.contiguous().numpy()
        da, dc, dh_rec = ws.da, ws.dc, ws.dh_rec
        dc.zero_()
        a_np, c_np, tc_np, da_np = ws.acts.numpy(), ws.c.numpy(), ws.tc.numpy(), da.numpy()
        for t in range(ib - 1, -1, -1):
            _backward_position(a_np[t], tc_np[t], c_np[max(t - 1, 0)], t == 0, dh_np[:, t],
                               dh_rec.numpy(), t < ib - 1, dc.numpy(), da_np[t])
            if t:
                torch.mm(da[t], w_hh, out=dh_rec)
        flat = da.view(ib * n, 4 * hid)
        need = ctx.needs_input_grad
        dx = (flat @ w_ih).view(ib, n, -1).transpose(0, 1) if need[0] else None
        dw_ih = (xt.t() @ flat).t().contiguous() if need[1] else None    # daᵀx: 7x slower in MKL
        dw_hh = None
        if need[2]:
            dw_hh = torch.zeros_like(w_hh) if ib == 1 else da[1].t() @ h[:, 0]
            for t in range(2, ib):
                dw_hh.addmm_(da[t].t(), h[:, t - 1])
        db = flat.sum(0) if need[3] or need[4] else None
        _give_back(ws)
        db_hh = db.clone() if need[3] and need[4] and db is not None else db   # two .grad, never one tensor
        return dx, dw_ih, dw_hh, db if need[3] else None, db_hh if need[4] else None


def fits(layer: nn.Module, x: torch.Tensor) -> bool:
    """Whether `window_lstm` can run `layer` on x: a one-layer, unidirectional, batch-first nn.LSTM with
    biases and no projection, float32 on the CPU (elsewhere, e.g. CUDA, nn.LSTM runs)."""
    return (isinstance(layer, nn.LSTM) and layer.num_layers == 1 and not layer.bidirectional
            and layer.batch_first and layer.bias and layer.proj_size == 0 and x.dim() == 3
            and x.dtype == torch.float32 and x.device.type == "cpu"
            and layer.weight_ih_l0.dtype == torch.float32 and layer.weight_ih_l0.device.type == "cpu")


def window_lstm(layer: nn.LSTM, x: torch.Tensor) -> torch.Tensor:
    """layer(x)[0] for x (B, IB, F) from zero state: the same values within float32 round-off, with the
    fused forward and backward (module docstring). Check `fits(layer, x)` first."""
    out = _WindowLSTM.apply(x, layer.weight_ih_l0, layer.weight_hh_l0, layer.bias_ih_l0, layer.bias_hh_l0)
    assert isinstance(out, torch.Tensor)
    return out


def use_window_lstm(net: nn.Module, on: bool) -> None:
    """Let every SeqNet in `net` run its LSTM with `window_lstm` (SeqNet.fused_lstm), or not (and
    free the pooled buffers). A SeqNet is known by its class attribute `fused_lstm` (seqnet imports
    this module: importing SeqNet here would close a circle)."""
    if not on:
        _POOL.clear()
    for m in net.modules():
        if hasattr(type(m), "fused_lstm"):
            setattr(m, "fused_lstm", on)  # noqa: B010 (nn.Module types its attributes as tensors or modules)
