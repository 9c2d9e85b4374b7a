"""The floor of one TCM integration pass: a bare numba RK4 pass (issue 26, goal 1).

`bare_pass` does the arithmetic of one shooting pass of `ctrkin.mechanics.kernels._integrate` with
the variation (what a Newton iteration integrates): the base conditions (M4), RK4 steps of (M2)
and its variation on the same grid, the residuals uz(tip) and their Jacobian, and the minimum of
det H (conjugate-point test, sampled on straight stretches as the library does), in the same
floating-point order, so its residuals, Jacobian and det H are bit for bit those of the library.
What it leaves out is everything around the arithmetic: no allocation (the caller passes every
array), no tuples of arrays, no optional body, records or contact stations, one function with
flat loops. It supports one to three tubes (det H in closed form) and is a measuring stick for
benchmarks/bench_mechanics.py, not library code. It still hands row views and arrays to an
inlined right-hand side, which numba pays for in reference counting; the library's Newton pass
(mechanics.passes.flat_pass, issue 26) no longer does and is faster than it: `real_passes` times
that pass.

`real_passes` / `bare_passes` run R passes inside one compiled call, so the figure is the pass
itself, not the Python call around it (a Newton solve runs its passes inside one kernel call).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ctrkin.mechanics import kernels

S_TOL = kernels.S_TOL


@njit(inline="always")
def _rhs(y, phi, kap, kapy, pres, k, gj, dy, dphi, vx, vy):
    """(M1), (M2) and the variation dΦ = A(y) Φ at one stretch's precurvature (kernels._deriv)."""
    n = k.shape[0]
    ksum = 0.0
    ux = 0.0
    uy = 0.0
    for i in range(n):
        if pres[i] > 0.0:
            c = math.cos(y[i])
            s = math.sin(y[i])
            ax = kap[i] * c - kapy[i] * s
            ay = kap[i] * s + kapy[i] * c
            vx[i] = ax
            vy[i] = ay
            ksum += k[i]
            ux += k[i] * ax
            uy += k[i] * ay
    if ksum > 0.0:
        ux /= ksum
        uy /= ksum
    for i in range(n):
        if pres[i] > 0.0:
            dy[i] = y[n + i]
            dy[n + i] = k[i] / gj[i] * (ux * vy[i] - uy * vx[i])
            for c in range(n):
                dphi[i, c] = phi[n + i, c]
                dphi[n + i, c] = 0.0
            if kap[i] == 0.0 and kapy[i] == 0.0:
                continue
            a = k[i] / gj[i]
            for j in range(n):
                if pres[j] > 0.0 and (kap[j] != 0.0 or kapy[j] != 0.0):
                    m = -a * k[j] * (vx[i] * vx[j] + vy[i] * vy[j]) / ksum
                    if i == j:
                        m += a * (ux * vx[i] + uy * vy[i])
                    for c in range(n):
                        dphi[n + i, c] += m * phi[j, c]
        else:
            dy[i] = 0.0
            dy[n + i] = 0.0
            for c in range(n):
                dphi[i, c] = 0.0
                dphi[n + i, c] = 0.0


@njit(inline="always")
def _det_h(phi, gj, f, phi_b):
    """det H at Φ + f (Φb − Φ) (kernels._relative_det, f = 0: at Φ), one to three tubes."""
    n = gj.shape[0]
    gsum = 0.0
    for i in range(n):
        gsum += gj[i]
    if n == 2:
        acc = 0.0
        for r in range(n):
            p0 = phi[0, r] + f * (phi_b[0, r] - phi[0, r])
            p1 = phi[1, r] + f * (phi_b[1, r] - phi[1, r])
            acc += (p0 - p1) * ((1.0 if r == 0 else 0.0) - gj[0] / gsum)
        return acc
    h00 = 0.0
    h01 = 0.0
    h10 = 0.0
    h11 = 0.0
    for r in range(n):
        p0 = phi[0, r] + f * (phi_b[0, r] - phi[0, r])
        p1 = phi[1, r] + f * (phi_b[1, r] - phi[1, r])
        p2 = phi[2, r] + f * (phi_b[2, r] - phi[2, r])
        d0 = (1.0 if r == 0 else 0.0) - gj[0] / gsum
        d1 = (1.0 if r == 1 else 0.0) - gj[1] / gsum
        h00 += (p0 - p2) * d0
        h01 += (p0 - p2) * d1
        h10 += (p1 - p2) * d0
        h11 += (p1 - p2) * d1
    return h00 * h11 - h01 * h10


@njit(inline="always")
def _straight_min(phi_a, phi_b, gj, m):
    """kernels._straight_min_det: min det H at f = j/m, 0 < j < m, on an affine stretch."""
    best = np.inf
    if m < 2:
        return best
    if gj.shape[0] == 2:
        return _det_h(phi_a, gj, 1.0 / m, phi_b)
    d0 = _det_h(phi_a, gj, 0.0, phi_b)
    dh = _det_h(phi_a, gj, 0.5, phi_b)
    d1 = _det_h(phi_a, gj, 1.0, phi_b)
    c2 = 2.0 * (d1 - 2.0 * dh + d0)
    c1 = d1 - d0 - c2
    best = _det_h(phi_a, gj, 1.0 / m, phi_b)
    if c2 > 0.0:
        j0 = math.floor(-c1 / (2.0 * c2) * m)
        for j in (j0, j0 + 1):
            if 1 < j < m:
                best = min(best, _det_h(phi_a, gj, j / m, phi_b))
    return best


@njit
def bare_pass(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
              r, jac, y, phi, ks, qs, yt, pt, phi_a, vx, vy):
    """One pass with the variation from uz(0) = x (N,) rad/mm: writes r (N,) and jac (N, N),
    returns min det H. Work: y (2N,), phi (2N, N), ks (4, 2N), qs (4, 2N, N), yt (2N,),
    pt (2N, N), phi_a (2N, N), vx, vy (N,)."""
    n = k.shape[0]
    n2 = 2 * n
    for u in range(n2):
        for c in range(n):
            phi[u, c] = 0.0
    for i in range(n):  # (M4)
        y[n + i] = x[i]
        y[i] = alpha[i] if rigid else alpha[i] - beta[i] * x[i]
        phi[n + i, i] = 1.0
        if not rigid:
            phi[i, i] = -beta[i]
    min_tip = tips.min()
    min_det = np.inf
    check = n > 1
    done = 0  # bit i: tube i's residual is read
    for i in range(n):
        if tips[i] <= S_TOL:
            done |= 1 << i
            r[i] = y[n + i]
            for c in range(n):
                jac[i, c] = phi[n + i, c]
    for seg in range(bounds.shape[0] - 1):
        a = bounds[seg]
        b = bounds[seg + 1]
        ns = nsteps[seg]
        h = (b - a) / ns
        sampled = check and ns < nsample[seg]
        if sampled:
            for u in range(n2):
                for c in range(n):
                    phi_a[u, c] = phi[u, c]
        kp = kap[seg]
        kpy = kapy[seg]
        pr = present[seg]
        for st in range(ns):
            _rhs(y, phi, kp, kpy, pr, k, gj, ks[0], qs[0], vx, vy)
            for stage, f in ((1, 0.5 * h), (2, 0.5 * h), (3, h)):
                for u in range(n2):
                    yt[u] = y[u] + f * ks[stage - 1, u]
                    for c in range(n):
                        pt[u, c] = phi[u, c] + f * qs[stage - 1, u, c]
                _rhs(yt, pt, kp, kpy, pr, k, gj, ks[stage], qs[stage], vx, vy)
            h6 = h / 6.0
            for u in range(n2):
                y[u] += h6 * (ks[0, u] + 2.0 * ks[1, u] + 2.0 * ks[2, u] + ks[3, u])
                for c in range(n):
                    phi[u, c] += h6 * (qs[0, u, c] + 2.0 * qs[1, u, c] + 2.0 * qs[2, u, c]
                                       + qs[3, u, c])
            if check and a + (st + 1) * h <= min_tip + S_TOL:
                d = _det_h(phi, gj, 0.0, phi)
                if d < min_det:
                    min_det = d
        if sampled and b <= min_tip + S_TOL:
            d = _straight_min(phi_a, phi, gj, nsample[seg])
            if d < min_det:
                min_det = d
        for i in range(n):
            if not (done >> i) & 1 and tips[i] <= b + S_TOL:
                done |= 1 << i
                r[i] = y[n + i]
                for c in range(n):
                    jac[i, c] = phi[n + i, c]
    return min_det


@njit
def bare_passes(reps, x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                nsample, r, jac, y, phi, ks, qs, yt, pt, phi_a, vx, vy):
    """reps bare passes in one call; returns the last min det H."""
    d = 0.0
    for _ in range(reps):
        d = bare_pass(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                      nsample, r, jac, y, phi, ks, qs, yt, pt, phi_a, vx, vy)
    return d


try:  # the library's pass as a Newton solve makes it: flat (issue 26), or _integrate before it
    from ctrkin.mechanics.passes import flat_pass, flat_work
except ImportError:  # an older tree (bench_mechanics --baseline)
    flat_pass = None

if flat_pass is not None:
    @njit
    def real_passes(reps, x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                    nsample, r, jac):
        """reps library passes in one call, as kernels.newton makes them without contact effects
        (passes.flat_pass, its work allocated once per solve, the variation on, no body); returns
        the last min det H."""
        fw = flat_work(k.shape[0])
        d = 0.0
        for _ in range(reps):
            d = flat_pass(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                          nsample, True, False, fw, r, jac)
        return d
else:
    @njit
    def real_passes(reps, x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                    nsample, r, jac):
        """reps library passes in one call, as kernels.newton makes them (work arrays allocated
        once per solve, the variation on, no body, no records, no contact); returns the last min
        det H."""
        n = k.shape[0]
        y = np.empty(2 * n)
        phi = np.empty((2 * n, n))
        zb = np.empty(kernels.NB)
        w = kernels._work(n)
        rs, ps, qs, us = np.empty(1), np.empty((1, 3)), np.empty((1, 1)), np.empty((1, 1))
        d = 0.0
        for _ in range(reps):
            d = kernels._integrate(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present,
                                   nsteps, nsample, True, False, y, phi, zb, w, r, jac, False, rs,
                                   ps, qs, us, None, None, None, None, None)
        return d


def bare_work(n: int) -> tuple[np.ndarray, ...]:
    """The work arrays bare_pass takes after jac, for N tubes."""
    return (np.empty(2 * n), np.empty((2 * n, n)), np.empty((4, 2 * n)), np.empty((4, 2 * n, n)),
            np.empty(2 * n), np.empty((2 * n, n)), np.empty((2 * n, n)), np.empty(n), np.empty(n))
