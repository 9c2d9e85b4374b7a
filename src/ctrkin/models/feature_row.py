"""One step's paper features in compiled code, shared by batch predict (`models.batch.fk_padded_rows`)
and the fused streaming step (`models.fused`): the same float64 arithmetic as
`ctrkin.models.features.sequence_features` (paper III.B, eq. 1-2), before any clip or normalisation
(each caller keeps its own: batch clips Δα0 only, the streaming step every feature)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def paper_feature_row(q: np.ndarray, n: int, a0_prev: float, started: bool, phase: bool, delta: bool,
                      f: np.ndarray) -> float:
    """f[:F] = (α1..αN, β1..βN, α0, [sin α0, cos α0 with phase], [Δα0 with delta]) of the joints q (2N,)
    (deg, mm); a0_prev the previous step's α0, read only when `started` (Δα0 = 0 at a sequence's first
    step). Returns α0."""
    for j in range(2 * n):
        f[j] = q[j]
    a0 = q[0] - q[n - 1]                                             # eq. (1)
    f[2 * n] = a0
    k = 2 * n + 1
    if phase:
        r = math.radians(a0)
        f[k], f[k + 1] = math.sin(r), math.cos(r)
        k += 2
    if delta:
        f[k] = a0 - a0_prev if started else 0.0                      # eq. (2)
    return a0
