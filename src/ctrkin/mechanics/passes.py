"""The shooting pass of a Newton solve, flat: one compiled loop over preallocated arrays by index
(issue 26), and the conjugate-point test det H it samples (docs/mechanics.md: Near the floor).

`flat_pass` does the arithmetic of `kernels._integrate` without the grid records and the contact
stations: (M4), RK4 steps of (M1, M2) with the variation dΦ = A(y) Φ or the backbone (M3) and the
energy, the residuals uz(tip), their Jacobian and min det H, in the same floating-point order
(bit for bit the same numbers; tests/mechanics/test_passes.py). What it leaves out is numba's
reference counting: every array a helper takes, and every row view (`ks[0]`), costs an atomic
increment and decrement at each use, and in the library pass those were ~70 % of its compiled time
(perf, issue 26). Here every array is bound once, at the top of the pass, and read by index: the
stage states and derivatives are rows of stacked arrays (stage s reads row 0, the step's start,
for s = 0 and row 1, the stage state, after), the right-hand side is written out in the stage
loop. kernels._integrate keeps serving the records (`integrate_full`) and the contact stations.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ctrkin.mechanics.grid import S_TOL

NB = 13  # body state: p (3) mm, R row-major (9), elastic energy (1) N·mm


@njit(cache=True, inline="always")
def det(a):
    """Determinant of a square matrix (M, M): closed form for M ≤ 2 (the shooting Jacobian and H of
    two and three tubes), LU (np.linalg.det) above."""
    n = a.shape[0]
    if n == 1:
        return a[0, 0]
    if n == 2:
        return a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    return np.linalg.det(a)


@njit(cache=True, inline="always")
def relative_det(phi, gj):
    """det H(s): relative angles ψi − ψN (i < N) as functions of the relative base twist rates
    yj = xj − xN under zero net torque Σ GJ x = 0 (x = D y). On a straight robot det H > 0 for
    s > 0; a sign change along s is a conjugate point (Jacobi condition), i.e. instability."""
    n = gj.shape[0]
    m = n - 1
    gsum = gj.sum()
    if m == 1:
        acc = 0.0
        for r in range(n):
            acc += (phi[0, r] - phi[1, r]) * ((1.0 if r == 0 else 0.0) - gj[0] / gsum)
        return acc
    if m == 2:  # three tubes: the 2 × 2 determinant in closed form, no work array per RK4 step
        h00 = 0.0
        h01 = 0.0
        h10 = 0.0
        h11 = 0.0
        for r in range(n):
            d0 = (1.0 if r == 0 else 0.0) - gj[0] / gsum
            d1 = (1.0 if r == 1 else 0.0) - gj[1] / gsum
            h00 += (phi[0, r] - phi[2, r]) * d0
            h01 += (phi[0, r] - phi[2, r]) * d1
            h10 += (phi[1, r] - phi[2, r]) * d0
            h11 += (phi[1, r] - phi[2, r]) * d1
        return h00 * h11 - h01 * h10
    h = np.empty((m, m))
    for i in range(m):
        for j in range(m):
            acc = 0.0
            for r in range(n):
                d = (1.0 if r == j else 0.0) - gj[j] / gsum
                acc += (phi[i, r] - phi[n - 1, r]) * d
            h[i, j] = acc
    return det(h)


@njit(cache=True)
def _det_between(phi_a, phi_b, f, gj, p_int):
    """det H at Φ = Φa + f (Φb − Φa) (Φ is affine in s on a straight stretch)."""
    for u in range(phi_a.shape[0]):
        for c in range(phi_a.shape[1]):
            p_int[u, c] = phi_a[u, c] + f * (phi_b[u, c] - phi_a[u, c])
    return relative_det(p_int, gj)


@njit(cache=True)
def straight_min_det(phi_a, phi_b, gj, m, p_int):
    """Min of det H over the interior sample points f = j/m, 0 < j < m, of a straight stretch taken
    in one step (the end point is checked by the caller). det H is a polynomial of degree N − 1 in
    f: two tubes, linear (min at j = 1 or m); three, quadratic (also the points beside its vertex);
    more, every point."""
    n = gj.shape[0]
    best = np.inf
    if m < 2:
        return best
    if n == 2:
        return _det_between(phi_a, phi_b, 1.0 / m, gj, p_int)
    if n == 3:
        d0 = _det_between(phi_a, phi_b, 0.0, gj, p_int)
        dh = _det_between(phi_a, phi_b, 0.5, gj, p_int)
        d1 = _det_between(phi_a, phi_b, 1.0, gj, p_int)
        c2 = 2.0 * (d1 - 2.0 * dh + d0)  # d(f) = d0 + c1 f + c2 f²
        c1 = d1 - d0 - c2
        best = _det_between(phi_a, phi_b, 1.0 / m, gj, p_int)
        if c2 > 0.0:
            j0 = math.floor(-c1 / (2.0 * c2) * m)
            for j in (j0, j0 + 1):
                if 1 < j < m:
                    best = min(best, _det_between(phi_a, phi_b, j / m, gj, p_int))
        return best
    for j in range(1, m):
        best = min(best, _det_between(phi_a, phi_b, j / m, gj, p_int))
    return best


@njit(cache=True)
def flat_work(n):
    """The work of flat_pass for N tubes, one allocation per solve: ys (2, 2N) the state (row 0)
    and the stage state (row 1), ps (2, 2N, N) Φ likewise, zs (2, NB) the body likewise, ks (4, 2N),
    qs (4, 2N, N), bs (4, NB) the stage derivatives, v (2, N) Rz(ψi) ûi, phi_a (2N, N) Φ at a
    stretch's start, p_int (2N, N) scratch of det H."""
    n2 = 2 * n
    sizes = (2 * n2, 2 * n2 * n, 2 * NB, 4 * n2, 4 * n2 * n, 4 * NB, 2 * n, n2 * n, n2 * n)
    buf = np.zeros(sum(sizes))
    o = np.cumsum(np.array(sizes))
    return (buf[:o[0]].reshape((2, n2)), buf[o[0]:o[1]].reshape((2, n2, n)),
            buf[o[1]:o[2]].reshape((2, NB)), buf[o[2]:o[3]].reshape((4, n2)),
            buf[o[3]:o[4]].reshape((4, n2, n)), buf[o[4]:o[5]].reshape((4, NB)),
            buf[o[5]:o[6]].reshape((2, n)), buf[o[6]:o[7]].reshape((n2, n)),
            buf[o[7]:o[8]].reshape((n2, n)))


@njit(cache=True)
def flat_pass(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
              with_var, with_body, fw, r, jac):
    """One integration pass from s = 0 with uz(0) = x (N,) rad/mm (module docstring): writes the
    residuals r (N,) = uz(tip_i) (M4), with_var: the variation and jac = ∂r/∂x (N, N), with_body:
    the backbone and energy into fw's zs[0] (kernels._tip reads it). fw = flat_work(N). Returns
    min over s ∈ (0, min tip] of det H (+inf for one tube or without the variation); a straight
    stretch taken in one exact step is sampled at its nsample points (kernels._integrate)."""
    ys, ps, zs, ks, qs, bs, v, phi_a, p_int = fw
    n = k.shape[0]
    n2 = 2 * n
    nbnd = bounds.shape[0]
    for u in range(n2):  # (M4), kernels._init_state
        for c in range(n):
            ps[0, u, c] = 0.0
    for j in range(NB):
        zs[0, j] = 0.0
    for d in range(3):
        zs[0, 3 + 4 * d] = 1.0
    for i in range(n):
        ys[0, n + i] = x[i]
        ys[0, i] = alpha[i] if rigid else alpha[i] - beta[i] * x[i]
        ps[0, n + i, i] = 1.0
        if not rigid:
            ps[0, i, i] = -beta[i]
            zs[0, 12] += 0.5 * gj[i] * x[i] * x[i] * (-beta[i])
    min_tip = tips[0]
    for i in range(1, n):
        min_tip = min(min_tip, tips[i])
    min_det = np.inf
    check = with_var and n > 1
    done = 0  # bit i: tube i's residual is read
    for i in range(n):  # a tube flush with the front plate ends at s = 0
        if tips[i] <= S_TOL:
            done |= 1 << i
            r[i] = ys[0, n + i]
            if with_var:
                for c in range(n):
                    jac[i, c] = ps[0, n + i, c]
    for seg in range(nbnd - 1):
        a = bounds[seg]
        b = bounds[seg + 1]
        ns = nsteps[seg]
        h = (b - a) / ns
        sampled = check and ns < nsample[seg]
        if sampled:
            for u in range(n2):
                for c in range(n):
                    phi_a[u, c] = ps[0, u, c]
        for st in range(ns):
            for s in range(4):  # RK4 stage s (mechanics.rk4): input row 0 for s = 0, else row 1
                src = 0
                if s > 0:
                    src = 1
                    f = h if s == 3 else 0.5 * h
                    for j in range(n2):
                        ys[1, j] = ys[0, j] + f * ks[s - 1, j]
                    if with_var:
                        for j in range(n2):
                            for c in range(n):
                                ps[1, j, c] = ps[0, j, c] + f * qs[s - 1, j, c]
                    if with_body:
                        for j in range(NB):
                            zs[1, j] = zs[0, j] + f * bs[s - 1, j]
                ksum = 0.0  # (M1), kernels._rhs
                ux = 0.0
                uy = 0.0
                for i in range(n):
                    if present[seg, i] > 0.0:
                        cs = math.cos(ys[src, i])
                        sn = math.sin(ys[src, i])
                        ax = kap[seg, i] * cs - kapy[seg, i] * sn
                        ay = kap[seg, i] * sn + kapy[seg, i] * cs
                        v[0, i] = ax
                        v[1, i] = ay
                        ksum += k[i]
                        ux += k[i] * ax
                        uy += k[i] * ay
                if ksum > 0.0:
                    ux /= ksum
                    uy /= ksum
                for i in range(n):  # (M2)
                    if present[seg, i] > 0.0:
                        ks[s, i] = ys[src, n + i]
                        ks[s, n + i] = k[i] / gj[i] * (ux * v[1, i] - uy * v[0, i])
                    else:
                        ks[s, i] = 0.0
                        ks[s, n + i] = 0.0
                if with_var:  # dΦ = A(y) Φ, ∂uiz'/∂ψj = (ki/GJi) [δij (u · vi) − kj (vi · vj) / Σk]
                    for i in range(n):
                        if present[seg, i] > 0.0:
                            for c in range(n):
                                qs[s, i, c] = ps[src, n + i, c]
                            for c in range(n):
                                qs[s, n + i, c] = 0.0
                            if kap[seg, i] == 0.0 and kapy[seg, i] == 0.0:
                                continue
                            ai = k[i] / gj[i]
                            for j in range(n):
                                if present[seg, j] > 0.0 and (kap[seg, j] != 0.0 or kapy[seg, j] != 0.0):
                                    m = -ai * k[j] * (v[0, i] * v[0, j] + v[1, i] * v[1, j]) / ksum
                                    if i == j:
                                        m += ai * (ux * v[0, i] + uy * v[1, i])
                                    for c in range(n):
                                        qs[s, n + i, c] += m * ps[src, j, c]
                        else:
                            for c in range(n):
                                qs[s, i, c] = 0.0
                                qs[s, n + i, c] = 0.0
                if with_body:  # (M3) R' = R [u]^, p' = R e3, and the energy density
                    for row in range(3):
                        c0 = zs[src, 3 + 3 * row]
                        c1 = zs[src, 4 + 3 * row]
                        c2 = zs[src, 5 + 3 * row]
                        bs[s, row] = c2
                        bs[s, 3 + 3 * row] = -uy * c2
                        bs[s, 4 + 3 * row] = ux * c2
                        bs[s, 5 + 3 * row] = uy * c0 - ux * c1
                    e = 0.0
                    for i in range(n):
                        if present[seg, i] > 0.0:
                            bx = ux - v[0, i]
                            by = uy - v[1, i]
                            uz = ys[src, n + i]
                            e += 0.5 * k[i] * (bx * bx + by * by) + 0.5 * gj[i] * uz * uz
                    bs[s, 12] = e
            h6 = h / 6.0  # y += h/6 (k1 + 2 k2 + 2 k3 + k4), likewise Φ and zb
            for j in range(n2):
                ys[0, j] += h6 * (ks[0, j] + 2.0 * ks[1, j] + 2.0 * ks[2, j] + ks[3, j])
                if with_var:
                    for c in range(n):
                        ps[0, j, c] += h6 * (qs[0, j, c] + 2.0 * qs[1, j, c] + 2.0 * qs[2, j, c]
                                             + qs[3, j, c])
            if with_body:
                for j in range(NB):
                    zs[0, j] += h6 * (bs[0, j] + 2.0 * bs[1, j] + 2.0 * bs[2, j] + bs[3, j])
            if check and a + (st + 1) * h <= min_tip + S_TOL:
                d = relative_det(ps[0], gj)
                if d < min_det:
                    min_det = d
        if sampled and b <= min_tip + S_TOL:
            d = straight_min_det(phi_a, ps[0], gj, nsample[seg], p_int)
            if d < min_det:
                min_det = d
        for i in range(n):
            if not (done >> i) & 1 and tips[i] <= b + S_TOL:
                done |= 1 << i
                r[i] = ys[0, n + i]
                if with_var:
                    for c in range(n):
                        jac[i, c] = ps[0, n + i, c]
    return min_det
