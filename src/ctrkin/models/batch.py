"""Fast batch prediction of a SeqNet over whole sequences, by chains instead of windows.

The windows of consecutive steps overlap: the window ending at t is the chain of cell updates started
at step t−IB+1 from zero state. Evaluating all chains position by position turns the work into a few
large matrix products: the input projection of the first LSTM is computed once per step (not once per
window position), and position 0 of every chain needs no recurrent product (zero state). For the
paper's IB = 2 this halves the LSTM work of running nn.LSTM on (T, IB, F) windows, and avoids its
per-call overhead. Equal to `net(windows)` up to float32 round-off (tested).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import torch
from torch import nn

from ctrkin.models.seqnet import SeqNet


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
    the layer while its parameters are unchanged (their version counters): building them cost
    ~30 µs of a predict call."""
    key = tuple(p._version for p in layer.parameters())
    cached = layer.__dict__.get("_ctrkin_scaled")
    if cached is not None and cached[0] == key:
        return cached[1]
    weights = _scaled(layer)
    layer.__dict__["_ctrkin_scaled"] = (key, weights)
    return weights


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
    for sl, h in _trunk_chunks(net, padded, starts, chunk):
        out[sl] = net.head_out(h).numpy()
    return out


@torch.inference_mode()
def seqnet_trunk(net: SeqNet, padded: np.ndarray, starts: np.ndarray, chunk: int = 1024) -> torch.Tensor:
    """(T, trunk_width) trunk features (net.trunk of every window), by chains; arguments as
    `seqnet_predict`."""
    parts = [h for _, h in _trunk_chunks(net, padded, starts, chunk)]
    return torch.cat(parts) if parts else torch.zeros((0, net.trunk_width))


def _trunk_chunks(net: SeqNet, padded: np.ndarray, starts: np.ndarray, chunk: int
                  ) -> Iterator[tuple[slice, torch.Tensor]]:
    """Yield (slice of rows, trunk features (rows, W)) chunk by chunk."""
    ib = net.ib
    x_all = torch.from_numpy(np.ascontiguousarray(padded, dtype=np.float32))
    s_all = torch.from_numpy(np.asarray(starts, dtype=np.int64))
    weights = {id(m): _scaled_lstm_weights(m) for m in net.seq if isinstance(m, nn.LSTM)}
    done = 0
    while done < len(starts):
        lo = int(starts[done])
        hi = min(lo + chunk, len(padded) - ib + 1)                 # chains starting in [lo, hi)
        n_here = int(np.searchsorted(starts, hi, side="left")) - done
        rows = x_all[lo:hi + ib - 1]
        n = hi - lo
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
