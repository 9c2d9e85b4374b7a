"""Numba kernels of the torsionally compliant model (TCM), DESIGN.md: Mechanics.

State along the arc length s ≥ 0, in a non-twisting (Bishop) backbone frame:
    y = (ψ1..ψN, u1z..uNz)     material angle and torsional curvature of each tube
    Φ = ∂y/∂x                  variational matrix (2N, N), x = uz(0) the shooting unknowns
Equations (eq. M1–M4 below are cited in the code):
    (M1) u_xy = Σ_{i∈P} ki κi (cos ψi, sin ψi) / Σ_{i∈P} ki          backbone bending
    (M2) ψi' = uiz,   uiz' = (ki / GJi) κi (sin ψi ux − cos ψi uy)     torsion (= ki/GJi (uix ûiy − uiy ûix))
    (M3) p' = R e3,   R' = R [ux, uy, 0]^                              backbone
    (M4) ψi(0) = αi − βi uiz(0) (compliant) or αi (rigid);  uiz(βi + Li) = 0
The RK4 map is differentiated stage by stage, so the Jacobian is exact for the discrete residual
(no finite differences). All angles here are radians.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

S_TOL = 1e-9  # mm: two breakpoints closer than this are the same point


@njit(cache=True)
def build_grid(beta, tube_len, sec_len, sec_kap, n_sec, h_max):
    """Split [0, s_end] at every tube tip and precurvature change.

    beta (N,) mm; tube_len (N,) mm; sec_len, sec_kap (N, S) section lengths (mm) and curvatures
    (1/mm) from base to tip, n_sec (N,) sections used; h_max: largest RK4 step (mm).
    Returns bounds (M+1,), kap (M, N), present (M, N) as 0/1, nsteps (M,).
    """
    n = beta.shape[0]
    tips = beta + tube_len
    s_end = max(tips.max(), 0.0)
    pts = np.empty(2 + n * (sec_len.shape[1] + 1))
    cnt = 1
    pts[0] = 0.0
    for i in range(n):
        b = beta[i]
        for j in range(n_sec[i]):
            b += sec_len[i, j]
            if S_TOL < b < s_end - S_TOL:
                pts[cnt] = b
                cnt += 1
    if s_end > S_TOL:
        pts[cnt] = s_end
        cnt += 1
    srt = np.sort(pts[:cnt])
    bounds = np.empty(cnt)
    nb = 0
    for v in srt:
        if nb == 0 or v - bounds[nb - 1] > S_TOL:
            bounds[nb] = v
            nb += 1
    bounds = bounds[:nb].copy()
    m = max(nb - 1, 0)
    kap = np.zeros((m, n))
    present = np.zeros((m, n))
    nsteps = np.ones(m, dtype=np.int64)
    for k in range(m):
        a, b = bounds[k], bounds[k + 1]
        mid = 0.5 * (a + b)
        nsteps[k] = max(1, math.ceil((b - a) / h_max - 1e-12))
        for i in range(n):
            if tips[i] > mid:
                present[k, i] = 1.0
                sigma = mid - beta[i]  # position along tube i from its base
                cum = 0.0
                for j in range(n_sec[i]):
                    cum += sec_len[i, j]
                    if sigma < cum:
                        kap[k, i] = sec_kap[i, j]
                        break
    return bounds, kap, present, nsteps


@njit(cache=True)
def _bending(psi, kap, pres, k, cs, sn):
    """(M1): backbone curvature (ux, uy) 1/mm and the bending stiffness sum of present tubes.
    Also writes cs, sn = cos ψi, sin ψi of present tubes (reused by the callers)."""
    ksum = 0.0
    ux = 0.0
    uy = 0.0
    for i in range(k.shape[0]):
        if pres[i] > 0.0:
            c = math.cos(psi[i])
            s = math.sin(psi[i])
            cs[i] = c
            sn[i] = s
            ksum += k[i]
            ux += k[i] * kap[i] * c
            uy += k[i] * kap[i] * s
    if ksum > 0.0:
        ux /= ksum
        uy /= ksum
    return ux, uy, ksum


@njit(cache=True)
def _deriv(y, phi, kap, pres, k, gj, dy, dphi, with_var, cs, sn):
    """(M2) and its variation dΦ = A(y) Φ; writes into dy (2N,) and dphi (2N, N).

    ∂uiz'/∂ψj = ai [δij (cos ψi ux + sin ψi uy) − kj κj cos(ψi − ψj) / Σk],  ai = ki κi / GJi."""
    n = k.shape[0]
    ux, uy, ksum = _bending(y, kap, pres, k, cs, sn)
    for i in range(n):
        if pres[i] > 0.0:
            dy[i] = y[n + i]
            dy[n + i] = k[i] / gj[i] * kap[i] * (sn[i] * ux - cs[i] * uy)
        else:
            dy[i] = 0.0
            dy[n + i] = 0.0
    if not with_var:
        return
    nc = phi.shape[1]
    for i in range(n):
        if pres[i] > 0.0:
            for c in range(nc):
                dphi[i, c] = phi[n + i, c]
            a = k[i] / gj[i] * kap[i]
            if a != 0.0:
                diag = cs[i] * ux + sn[i] * uy
                for c in range(nc):
                    acc = diag * phi[i, c]
                    for j in range(n):
                        if pres[j] > 0.0 and kap[j] != 0.0:
                            cij = cs[i] * cs[j] + sn[i] * sn[j]  # cos(ψi − ψj)
                            acc -= k[j] * kap[j] * cij / ksum * phi[j, c]
                    dphi[n + i, c] = a * acc
            else:
                for c in range(nc):
                    dphi[n + i, c] = 0.0
        else:
            for c in range(nc):
                dphi[i, c] = 0.0
                dphi[n + i, c] = 0.0


@njit(cache=True)
def _relative_det(phi, gj):
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
    h = np.empty((m, m))
    for i in range(m):
        for j in range(m):
            acc = 0.0
            for r in range(n):
                d = (1.0 if r == j else 0.0) - gj[j] / gsum
                acc += (phi[i, r] - phi[n - 1, r]) * d
            h[i, j] = acc
    if m == 1:
        return h[0, 0]
    if m == 2:
        return h[0, 0] * h[1, 1] - h[0, 1] * h[1, 0]
    return np.linalg.det(h)


@njit(cache=True)
def _init_state(x, alpha, beta, rigid, y, phi):
    """(M4) base conditions: ψi(0) = αi − βi xi (compliant) or αi (rigid), uiz(0) = xi."""
    n = x.shape[0]
    phi[:, :] = 0.0
    for i in range(n):
        y[n + i] = x[i]
        y[i] = alpha[i] if rigid else alpha[i] - beta[i] * x[i]
        phi[n + i, i] = 1.0
        if not rigid:
            phi[i, i] = -beta[i]


@njit(cache=True)
def _rk4_step(y, phi, h, kp, pr, k, gj, with_var, w):
    """One RK4 step of (M2) and, differentiated stage by stage, of its variation.
    w: work arrays (k1..k4, q1..q4, yt, pt)."""
    k1, k2, k3, k4, q1, q2, q3, q4, yt, pt, cs, sn = w
    n2 = y.shape[0]
    nc = phi.shape[1]
    _deriv(y, phi, kp, pr, k, gj, k1, q1, with_var, cs, sn)
    for j in range(n2):
        yt[j] = y[j] + 0.5 * h * k1[j]
        if with_var:
            for c in range(nc):
                pt[j, c] = phi[j, c] + 0.5 * h * q1[j, c]
    _deriv(yt, pt, kp, pr, k, gj, k2, q2, with_var, cs, sn)
    for j in range(n2):
        yt[j] = y[j] + 0.5 * h * k2[j]
        if with_var:
            for c in range(nc):
                pt[j, c] = phi[j, c] + 0.5 * h * q2[j, c]
    _deriv(yt, pt, kp, pr, k, gj, k3, q3, with_var, cs, sn)
    for j in range(n2):
        yt[j] = y[j] + h * k3[j]
        if with_var:
            for c in range(nc):
                pt[j, c] = phi[j, c] + h * q3[j, c]
    _deriv(yt, pt, kp, pr, k, gj, k4, q4, with_var, cs, sn)
    for j in range(n2):
        y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        if with_var:
            for c in range(nc):
                phi[j, c] += h / 6.0 * (q1[j, c] + 2.0 * q2[j, c] + 2.0 * q3[j, c] + q4[j, c])


@njit(cache=True)
def _work(n):
    n2 = 2 * n
    return (np.empty(n2), np.empty(n2), np.empty(n2), np.empty(n2),
            np.empty((n2, n)), np.empty((n2, n)), np.empty((n2, n)), np.empty((n2, n)),
            np.empty(n2), np.empty((n2, n)), np.empty(n), np.empty(n))


@njit(cache=True)
def shoot(x, alpha, beta, tips, rigid, k, gj, bounds, kap, present, nsteps, r, jac, with_var):
    """Integrate (M2) from s = 0 with uz(0) = x; write residuals r_i = uiz(tip_i) (M4) and, if
    with_var, their exact Jacobian jac = ∂r/∂x (N, N).

    x, alpha (rad), beta (mm), tips (mm): (N,). Returns min over s ∈ (0, min tip] of det H
    (see _relative_det; +inf for one tube or without the variation).
    """
    n = k.shape[0]
    y = np.empty(2 * n)
    phi = np.zeros((2 * n, n))
    _init_state(x, alpha, beta, rigid, y, phi)
    w = _work(n)
    done = np.zeros(n, dtype=np.bool_)
    min_tip = tips.min()
    min_det = np.inf
    for i in range(n):  # a tube flush with the front plate ends at s = 0
        if tips[i] <= S_TOL:
            done[i] = True
            r[i] = y[n + i]
            for c in range(n):
                jac[i, c] = phi[n + i, c]
    for seg in range(bounds.shape[0] - 1):
        a, b = bounds[seg], bounds[seg + 1]
        ns = nsteps[seg]
        h = (b - a) / ns
        for st in range(ns):
            _rk4_step(y, phi, h, kap[seg], present[seg], k, gj, with_var, w)
            if with_var and n > 1 and a + (st + 1) * h <= min_tip + S_TOL:
                d = _relative_det(phi, gj)
                if d < min_det:
                    min_det = d
        for i in range(n):
            if not done[i] and tips[i] <= b + S_TOL:
                done[i] = True
                r[i] = y[n + i]
                for c in range(n):
                    jac[i, c] = phi[n + i, c]
    return min_det


@njit(cache=True)
def _solve_linear(a, b, out):
    """Gaussian elimination with partial pivoting on copies; False if (near-)singular."""
    n = b.shape[0]
    m = a.copy()
    v = b.copy()
    scale = 0.0
    for i in range(n):
        for j in range(n):
            scale = max(scale, abs(m[i, j]))
    if scale == 0.0:
        return False
    for col in range(n):
        piv = col
        for row in range(col + 1, n):
            if abs(m[row, col]) > abs(m[piv, col]):
                piv = row
        if abs(m[piv, col]) < 1e-13 * scale:
            return False
        if piv != col:
            for j in range(n):
                tmp = m[col, j]
                m[col, j] = m[piv, j]
                m[piv, j] = tmp
            tmp = v[col]
            v[col] = v[piv]
            v[piv] = tmp
        for row in range(col + 1, n):
            f = m[row, col] / m[col, col]
            for j in range(col, n):
                m[row, j] -= f * m[col, j]
            v[row] -= f * v[col]
    for row in range(n - 1, -1, -1):
        acc = v[row]
        for j in range(row + 1, n):
            acc -= m[row, j] * out[j]
        out[row] = acc / m[row, row]
    return True


@njit(cache=True)
def _det(a):
    n = a.shape[0]
    if n == 1:
        return a[0, 0]
    if n == 2:
        return a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    return np.linalg.det(a)


@njit(cache=True)
def newton(x0, alpha, beta, tips, rigid, k, gj, bounds, kap, present, nsteps,
           tol, max_iter, max_step, x_out):
    """Damped Newton on the shooting residual from x0 (rad/mm).

    Writes the root to x_out. Returns (converged, iterations, |r|∞, det J, min det H, shoots) where
    J = ∂r/∂x at the root (Gilbert et al. 2016 stability measure) and det H is the conjugate-point
    test (see shoot) and shoots the number of integrations (the work, backtracking included).
    max_step bounds |Δx|∞ per iteration (rad/mm).
    """
    n = x0.shape[0]
    x = x0.copy()
    r = np.empty(n)
    jac = np.empty((n, n))
    dx = np.empty(n)
    xt = np.empty(n)
    rt = np.empty(n)
    jt = np.empty((n, n))
    mdet = shoot(x, alpha, beta, tips, rigid, k, gj, bounds, kap, present, nsteps, r, jac, True)
    rn = np.abs(r).max()
    it = 0
    shoots = 1
    converged = rn < tol
    while not converged and it < max_iter:
        it += 1
        if not _solve_linear(jac, -r, dx):
            break
        big = np.abs(dx).max()
        if big > max_step:
            dx *= max_step / big
        t = 1.0
        accepted = False
        for _ in range(12):  # backtracking line search on |r|∞
            for i in range(n):
                xt[i] = x[i] + t * dx[i]
            md = shoot(xt, alpha, beta, tips, rigid, k, gj, bounds, kap, present, nsteps,
                       rt, jt, True)
            shoots += 1
            rnt = np.abs(rt).max()
            if rnt < (1.0 - 1e-4 * t) * rn or rnt < tol:
                accepted = True
                break
            t *= 0.5
        if not accepted:
            break
        x[:] = xt
        r[:] = rt
        jac[:, :] = jt
        rn = rnt
        mdet = md
        converged = rn < tol
    x_out[:] = x
    return converged, it, rn, _det(jac), mdet, shoots


@njit(cache=True)
def _deriv_full(z, kp, pr, k, gj, dz, dummy_phi, cs, sn):
    """Augmented state z = (ψ, uz (2N), p (3), R row-major (9), energy (1)): (M2), (M3), energy."""
    n = k.shape[0]
    n2 = 2 * n
    _deriv(z[:n2], dummy_phi, kp, pr, k, gj, dz[:n2], dummy_phi, False, cs, sn)
    ux, uy, _ = _bending(z[:n2], kp, pr, k, cs, sn)
    # p' = R e3 ; R' = R [u]^ with u = (ux, uy, 0): columns c0' = −uy c2, c1' = ux c2,
    # c2' = uy c0 − ux c1 (R stored row-major at z[n2+3 : n2+12])
    o = n2 + 3
    for row in range(3):
        c0 = z[o + 3 * row]
        c1 = z[o + 3 * row + 1]
        c2 = z[o + 3 * row + 2]
        dz[n2 + row] = c2
        dz[o + 3 * row] = -uy * c2
        dz[o + 3 * row + 1] = ux * c2
        dz[o + 3 * row + 2] = uy * c0 - ux * c1
    e = 0.0
    for i in range(n):
        if pr[i] > 0.0:
            bx = ux - kp[i] * cs[i]
            by = uy - kp[i] * sn[i]
            e += 0.5 * k[i] * (bx * bx + by * by) + 0.5 * gj[i] * z[n + i] * z[n + i]
    dz[n2 + 12] = e


@njit(cache=True)
def integrate_full(x, alpha, beta, tips, rigid, k, gj, bounds, kap, present, nsteps,
                   record, s_rec, p_rec, psi_rec, uz_rec):
    """Integrate (M2), (M3) and the elastic energy at the solution x.

    If record, every grid point is written to s_rec (K,), p_rec (K, 3) mm, psi_rec (K, N) rad and
    uz_rec (K, N) rad/mm, K = 1 + Σ nsteps; tubes not present there are NaN. Returns
    (tip position (3,) mm, unit tip tangent (3,), energy N·mm). Energy = Σ ∫ ½ ki |u − Rz(ψi) ûi|²
    + ½ GJi uiz² ds, plus ½ GJi xi² (−βi) stored in the compliant transmission.
    """
    n = k.shape[0]
    n2 = 2 * n
    nz = n2 + 13
    z = np.zeros(nz)
    phi = np.zeros((n2, n))
    _init_state(x, alpha, beta, rigid, z[:n2], phi)
    for d in range(3):
        z[n2 + 3 + 4 * d] = 1.0  # R = I
    if not rigid:
        for i in range(n):
            z[n2 + 12] += 0.5 * gj[i] * x[i] * x[i] * (-beta[i])
    k1 = np.empty(nz)
    k2 = np.empty(nz)
    k3 = np.empty(nz)
    k4 = np.empty(nz)
    zt = np.empty(nz)
    dummy = np.zeros((n2, n))
    cs = np.empty(n)
    sn = np.empty(n)
    rec = 0
    if record:
        s_rec[0] = 0.0
        p_rec[0, :] = 0.0
        for i in range(n):
            on = tips[i] > S_TOL
            psi_rec[0, i] = z[i] if on else np.nan
            uz_rec[0, i] = z[n + i] if on else np.nan
    for seg in range(bounds.shape[0] - 1):
        a, b = bounds[seg], bounds[seg + 1]
        ns = nsteps[seg]
        h = (b - a) / ns
        kp = kap[seg]
        pr = present[seg]
        for st in range(ns):
            _deriv_full(z, kp, pr, k, gj, k1, dummy, cs, sn)
            for j in range(nz):
                zt[j] = z[j] + 0.5 * h * k1[j]
            _deriv_full(zt, kp, pr, k, gj, k2, dummy, cs, sn)
            for j in range(nz):
                zt[j] = z[j] + 0.5 * h * k2[j]
            _deriv_full(zt, kp, pr, k, gj, k3, dummy, cs, sn)
            for j in range(nz):
                zt[j] = z[j] + h * k3[j]
            _deriv_full(zt, kp, pr, k, gj, k4, dummy, cs, sn)
            for j in range(nz):
                z[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
            if not record:
                continue
            rec += 1
            s_rec[rec] = a + (st + 1) * h
            for d in range(3):
                p_rec[rec, d] = z[n2 + d]
            for i in range(n):
                on = pr[i] > 0.0
                psi_rec[rec, i] = z[i] if on else np.nan
                uz_rec[rec, i] = z[n + i] if on else np.nan
    tip = z[n2:n2 + 3].copy()
    tan = np.array([z[n2 + 5], z[n2 + 8], z[n2 + 11]])  # third column of R
    tan /= np.sqrt((tan * tan).sum())
    return tip, tan, z[n2 + 12]
