"""The float32 logistic function in compiled loops, shared by batch predict's one-LSTM pass
(ctrkin.models.batch) and the training's window LSTM (ctrkin.models.window_lstm); its own module so
that neither imports the other's dependencies (the window LSTM would otherwise import batch, which
imports seqnet, which uses the window LSTM)."""

from __future__ import annotations

import numba
import numpy as np

# ln 2 in two float32 parts (Cody-Waite: k·ln2_hi is exact for |k| ≤ 126) and 1/ln 2
_LN2_HI, _LN2_LO = np.float32(0.693359375), np.float32(-2.12194440e-4)
_INV_LN2 = np.float32(1.4426950408889634)
_F32 = np.float32


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def _sigmoid32(x: np.ndarray, bits: np.ndarray, two_k: np.ndarray) -> None:
    """x <- 1 / (1 + exp(−x)) in float32, in place on a 1-D array, in loops LLVM vectorises (the
    float64 kernel's method, ctrkin.models.engine._sigmoid_inplace): exp by Cody-Waite reduction to
    |r| ≤ ln2/2, a degree-6 Taylor polynomial (relative error < 1e-7, float32 round-off) and 2^k
    built in the exponent bits (k within ±126: σ is 0 or 1 to float32 beyond). bits: int32 scratch at
    least x's size, two_k: its float32 view (made once by the caller: a view made here per call cost
    more than the arithmetic). error_model="numpy": no per-division zero check (1 + e^−x ≥ 1)."""
    n = x.size
    for j in range(n):
        v = min(max(-x[j], _F32(-87.0)), _F32(87.0))
        k = np.floor(v * _INV_LN2 + _F32(0.5))
        r = (v - k * _LN2_HI) - k * _LN2_LO
        x[j] = _F32(1.0) + r * (_F32(1.0) + r * (_F32(1 / 2) + r * (_F32(1 / 6) + r * (_F32(1 / 24) + r * (
            _F32(1 / 120) + r * _F32(1 / 720))))))
        bits[j] = (np.int32(k) + np.int32(127)) << np.int32(23)
    for j in range(n):
        x[j] = _F32(1.0) / (_F32(1.0) + x[j] * two_k[j])
