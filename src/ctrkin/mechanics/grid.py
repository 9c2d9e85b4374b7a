"""The integration grid of one joint configuration: [0, s_end] split at every tube tip and
precurvature change, with the precurvature vector and the tubes present on each stretch.

Every breakpoint also gets an identity that does not depend on the joints (`code`): the tube boundary
it is (tube j's m-th section end, its tip being the last), or the front plate. The contact model
(mechanics.contact) keys the stuck state of a friction element by it, so a contact keeps its state
while the tubes translate and its arc length changes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

S_TOL = 1e-9  # mm: two breakpoints closer than this are the same point


@njit(cache=True)
def build_grid(beta, tube_len, sec_len, sec_kap, sec_kapy, n_sec, h_max):
    """Split [0, s_end] at every tube tip and precurvature change.

    beta (N,) mm; tube_len (N,) mm; sec_len, sec_kap, sec_kapy (N, S) section lengths (mm) and
    precurvature û = (κx, κy) in the tube's material frame (1/mm), base to tip; n_sec (N,) sections
    used; h_max: largest RK4 step (mm).
    Returns bounds (M+1,), kap (M, N) κx, kapy (M, N) κy, present (M, N) as 0/1, nsteps (M,),
    nsample (M,) and code (M+1,): the identity of each breakpoint, j (S + 1) + m for the m-th
    section end of tube j (m = 1 … n_sec[j], the tip last) and N (S + 1) for the front plate s = 0.
    A stretch where every present tube is straight has u_xy = 0 (M1): ψ is linear, uz, R and the
    variation's uz rows constant, so one RK4 step is exact there (nsteps = 1). nsample is the
    number of points at spacing ≤ h_max where the conjugate-point test samples det H (shoot).
    """
    n = beta.shape[0]
    width = sec_len.shape[1] + 1
    tips = beta + tube_len
    s_end = max(tips.max(), 0.0)
    pts = np.empty(2 + n * width)
    codes = np.empty(2 + n * width, dtype=np.int64)
    cnt = 1
    pts[0] = 0.0
    codes[0] = n * width
    end_code = n * width
    for i in range(n):
        b = beta[i]
        for j in range(n_sec[i]):
            b += sec_len[i, j]
            if S_TOL < b < s_end - S_TOL:
                pts[cnt] = b
                codes[cnt] = i * width + j + 1
                cnt += 1
            elif abs(b - s_end) <= S_TOL and end_code == n * width:
                end_code = i * width + j + 1
    if s_end > S_TOL:
        pts[cnt] = s_end
        codes[cnt] = end_code
        cnt += 1
    order = np.argsort(pts[:cnt], kind="mergesort")  # stable: the first tube owns a shared point
    bounds = np.empty(cnt)
    code = np.empty(cnt, dtype=np.int64)
    nb = 0
    for o in order:
        v = pts[o]
        if nb == 0 or v - bounds[nb - 1] > S_TOL:
            bounds[nb] = v
            code[nb] = codes[o]
            nb += 1
    bounds = bounds[:nb].copy()
    code = code[:nb].copy()
    m = max(nb - 1, 0)
    kap = np.zeros((m, n))
    kapy = np.zeros((m, n))
    present = np.zeros((m, n))
    nsteps = np.ones(m, dtype=np.int64)
    nsample = np.ones(m, dtype=np.int64)
    # per tube, the section holding the stretch midpoint and the cumulative length to its end: the
    # midpoints increase with k, so each cursor only moves forward (O(M + S), not O(M S))
    sec = np.zeros(n, dtype=np.int64)
    cum = np.zeros(n)
    for i in range(n):
        if n_sec[i] > 0:
            cum[i] = sec_len[i, 0]
    for k in range(m):
        a, b = bounds[k], bounds[k + 1]
        mid = 0.5 * (a + b)
        nsample[k] = max(1, math.ceil((b - a) / h_max - 1e-12))
        curved = False
        for i in range(n):
            if tips[i] > mid:
                present[k, i] = 1.0
                sigma = mid - beta[i]  # position along tube i from its base
                while sec[i] < n_sec[i] and not sigma < cum[i]:
                    sec[i] += 1
                    if sec[i] < n_sec[i]:
                        cum[i] += sec_len[i, sec[i]]
                if sec[i] < n_sec[i]:
                    kap[k, i] = sec_kap[i, sec[i]]
                    kapy[k, i] = sec_kapy[i, sec[i]]
                curved = curved or kap[k, i] != 0.0 or kapy[k, i] != 0.0
        nsteps[k] = nsample[k] if curved else 1
    return bounds, kap, kapy, present, nsteps, nsample, code


@njit(cache=True)
def reduced_radians(q, alpha):
    """alpha (N,) = q[:N] (deg) less whole turns, in (−π, π] rad: np.radians of
    pointwise.whole_turns_removed, bit for bit (fmod is exact in floating point, then one ±360°,
    then the product by π/180). The equilibrium depends on α only through its angle, and sin and
    cos of a huge angle lose every digit."""
    for i in range(alpha.shape[0]):
        r = np.fmod(q[i], 360.0)
        if r > 180.0:
            r -= 360.0
        if r <= -180.0:
            r += 360.0
        alpha[i] = math.radians(r)


@njit(cache=True)
def prepare(q, tube_len, extra, sec_len, sec_kap, sec_kapy, n_sec, h_max):
    """Kernel inputs at joints q (2N,) (deg, mm): α (N,) rad less whole turns (reduced_radians),
    the transmission's twisting length as β − extra (N,) mm (M4), tips β + L (N,) mm, the grid of
    build_grid (its first six arrays: bounds, kap, kapy, present, nsteps, nsample) and the
    breakpoint codes."""
    n = tube_len.shape[0]
    beta = q[n:].copy()
    alpha = np.empty(n)
    reduced_radians(q, alpha)
    bounds, kap, kapy, present, nsteps, nsample, code = build_grid(
        beta, tube_len, sec_len, sec_kap, sec_kapy, n_sec, h_max)
    return alpha, beta - extra, beta + tube_len, (bounds, kap, kapy, present, nsteps, nsample), code
