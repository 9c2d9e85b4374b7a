"""The one joint-validity check of ctrkin.robots.robot.Robot, a numba kernel over rows (its own module
so that importing a robot does not load numba)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ctrkin.robots.robot import JOINT_TOL


@njit(cache=True)
def joint_violations(rows: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, int]:
    """The one joint-validity check. rows (T, 2N) joints (deg, mm), lengths (N,) mm ->
    codes (T,): −1 valid, 0 NaN or inf, else the first inequality violated, in this order:
    1 βN ≤ 0, 2 βN + LN ≥ 0, then for i = 1..N−1: 2i + 1 βi ≤ βi+1, 2i + 2 βi + Li ≥ βi+1 + Li+1
    (each with JOINT_TOL slack); and the smallest code ≥ 0 of any row (−1 if all are valid): the
    condition to report first."""
    t, m = rows.shape
    n = m // 2
    codes = np.full(t, -1, dtype=np.int64)
    first = -1
    for r in range(t):
        code = -1
        for j in range(m):
            if not math.isfinite(rows[r, j]):
                code = 0
        if code < 0:
            b = rows[r, m - 1]
            if b > JOINT_TOL:
                code = 1
            elif b + lengths[n - 1] < -JOINT_TOL:
                code = 2
            else:
                for i in range(n - 1):
                    b, b1 = rows[r, n + i], rows[r, n + i + 1]
                    if b > b1 + JOINT_TOL:
                        code = 2 * i + 3
                        break
                    if b + lengths[i] < b1 + lengths[i + 1] - JOINT_TOL:
                        code = 2 * i + 4
                        break
        codes[r] = code
        if code >= 0 and (first < 0 or code < first):
            first = code
    return codes, first
