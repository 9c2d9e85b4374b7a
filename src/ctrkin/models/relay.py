"""A hysteresis relay whose thresholds are tabulated over the translations: the numba kernels a
state-carrying FK model's streaming step runs (ctrkin.models.fused) and its batch path scans.

    θ+ = φ+(β) + w − κ·m_N ,  θ− = φ−(β) − w − κ·m_N        (thresholds from tables φ±(β), deg;
                                                             w = c, less a slide memory's term)
    s_t = 1 if φ_t > band, 0 if φ_t < −band                 (outside the band one state exists)
        = 1 if s_{t−1} = 0 and θ+ ≤ φ_t and θ+ < band ;  0 if s_{t−1} = 1 and φ_t < θ−
        = s_{t−1} otherwise;  at a sequence start 1[φ > 0]
    a table entry |φ±| < MIN_FOLD_DEG is "none": that threshold is the band's edge. A θ+ at or
    beyond the band's edge never switches inside the band, so at φ = +band exactly the state is held,
    as the branch labels hold it there (ctrkin.families.snap_aware.labels: forced only at |φ| > band).

with φ = α0 − 180° wrapped. What the tables hold and how c and κ are fitted is the snap-aware
family's fold gate (ctrkin.families.snap_aware.fold_gate, docs/learned_kinematics.md: The fold
gate); here are only the grid, its multilinear interpolation (clamped at the edges) and the relay.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numba import njit

MIN_FOLD_DEG = 1.0          # a smaller interpolated threshold is taken as none


class _Tabulated(Protocol):
    """Threshold tables φ± (deg) on a grid of translations (one axis per tube, mm)."""

    @property
    def axes(self) -> tuple[np.ndarray, ...]:
        ...

    @property
    def forward(self) -> np.ndarray:
        ...

    @property
    def backward(self) -> np.ndarray:
        ...


@dataclass(frozen=True, eq=False)
class GateTables:
    """A relay's grid for numba: axes: the β axes concatenated, axis d at start[d]:start[d]+size[d];
    forward, backward: the fold tables flattened in C order."""

    axes: np.ndarray
    start: np.ndarray
    size: np.ndarray
    forward: np.ndarray
    backward: np.ndarray

    @classmethod
    def of(cls, gate: _Tabulated, scale: float = 1.0) -> GateTables:
        """The gate's grid; scale: a factor on both fold tables (the fold gate's g; 1: as tabulated)."""
        size = np.array([len(a) for a in gate.axes], dtype=np.int64)
        start = np.concatenate([[0], np.cumsum(size)[:-1]]).astype(np.int64)
        fwd, bwd = np.asarray(gate.forward, np.float64), np.asarray(gate.backward, np.float64)
        if scale != 1.0:
            fwd, bwd = scale * fwd, scale * bwd
        return cls(np.ascontiguousarray(np.concatenate(gate.axes), dtype=np.float64), start, size,
                   np.ascontiguousarray(fwd).ravel(), np.ascontiguousarray(bwd).ravel())


# The kernels below are compiled without fastmath on purpose: batch (`states`) and streaming
# (`step`, the fused FK step) must take the same decisions at a threshold to the last bit.

@njit(cache=True)
def _interpolate_point(axes: np.ndarray, start: np.ndarray, size: np.ndarray, table: np.ndarray,
                       x: np.ndarray) -> float:
    """Multilinear interpolation of a flattened table on the grid (GateTables) at x (D,), clamped."""
    dims = len(size)
    idx = np.zeros(dims, dtype=np.int64)
    frac = np.zeros(dims)
    for d in range(dims):
        a, m = start[d], size[d]
        if m == 1:
            continue
        xd = min(max(x[d], axes[a]), axes[a + m - 1])
        i = 0
        while i < m and axes[a + i] <= xd:       # searchsorted(side="right")
            i += 1
        i = min(max(i - 1, 0), m - 2)
        idx[d] = i
        frac[d] = (xd - axes[a + i]) / (axes[a + i + 1] - axes[a + i])
    out = 0.0
    for corner in range(2 ** dims):
        w, flat = 1.0, 0
        for d in range(dims):
            bit = (corner >> d) & 1
            if size[d] == 1 and bit:
                w = w * 0.0
                pos = idx[d]
            else:
                w = w * (frac[d] if bit else 1.0 - frac[d])
                pos = idx[d] + bit
            flat = flat * size[d] + pos
        out += w * table[flat]
    return out


@njit(cache=True)
def interpolate_rows(axes: np.ndarray, start: np.ndarray, size: np.ndarray, table: np.ndarray,
                      x: np.ndarray) -> np.ndarray:
    """_interpolate_point at each row of x (T, D) -> (T,)."""
    out = np.empty(x.shape[0])
    for r in range(x.shape[0]):
        out[r] = _interpolate_point(axes, start, size, table, x[r])
    return out


@njit(cache=True)
def _threshold_pair(fwd: float, bwd: float, motion: float, widen: float, lag: float, band: float
                    ) -> tuple[float, float]:
    """θ+, θ− (deg) from the folds φ± at one translation and m_N (module docstring)."""
    shift = lag * motion
    hi = fwd + widen - shift if fwd >= MIN_FOLD_DEG else band
    lo = bwd - widen - shift if bwd <= -MIN_FOLD_DEG else -band
    return max(hi, lo), lo


@njit(cache=True)
def threshold_rows(fwd: np.ndarray, bwd: np.ndarray, motion: np.ndarray, widen: np.ndarray, lag: float,
                    band: float) -> tuple[np.ndarray, np.ndarray]:
    """θ+, θ− (T,) at each row; widen (T,): the half-width term of each row (c, less a fold gate's
    slide memory)."""
    hi, lo = np.empty(len(fwd)), np.empty(len(fwd))
    for r in range(len(fwd)):
        hi[r], lo[r] = _threshold_pair(fwd[r], bwd[r], motion[r], widen[r], lag, band)
    return hi, lo


@njit(cache=True)
def _relay(cur: int, phi: float, hi: float, lo: float, band: float) -> int:
    """The relay of the module docstring: the state after a step at phase phi from `cur`."""
    if phi > band:
        return 1
    if phi < -band:
        return 0
    if cur < 0:
        return 1 if phi > 0.0 else 0
    if cur == 0 and phi >= hi and hi < band:
        return 1
    if cur == 1 and phi < lo:
        return 0
    return cur


@njit(cache=True)
def relay_scan(phi: np.ndarray, hi: np.ndarray, lo: np.ndarray, bounds: np.ndarray, keep: np.ndarray,
               band: float) -> np.ndarray:
    """States (T,) int8 along sequences bounds (S, 2); keep (S,): carry the state from the one before."""
    s = np.zeros(len(phi), dtype=np.int8)
    cur = -1
    for k in range(bounds.shape[0]):
        if not keep[k]:
            cur = -1
        for t in range(bounds[k, 0], bounds[k, 1]):
            cur = _relay(cur, phi[t], hi[t], lo[t], band)
            s[t] = cur
    return s


@njit(cache=True)
def gate_step(state: int, alpha0: float, betas: np.ndarray, motion: float, axes: np.ndarray,
              start: np.ndarray, size: np.ndarray, forward: np.ndarray, backward: np.ndarray,
              widen: float, lag: float, band: float) -> int:
    """The relay's state on its GateTables after one step at α0 (deg, α1 − αN), betas (N,) mm
    and m_N, from `state` (−1: a sequence start)."""
    fwd = _interpolate_point(axes, start, size, forward, betas)
    bwd = _interpolate_point(axes, start, size, backward, betas)
    hi, lo = _threshold_pair(fwd, bwd, motion, widen, lag, band)
    return _relay(state, alpha0 % 360.0 - 180.0, hi, lo, band)     # φ = α0 − 180° wrapped, scalar
