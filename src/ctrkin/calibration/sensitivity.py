"""Exact parameter Jacobian of the point-wise TCM tip: forward-mode differentiation of the discrete
RK4 map (mechanics.rk4, the step mechanics.kernels takes, on the same grid) plus the implicit function theorem
for the shooting unknowns. No finite differences, one integration per sample.

Parameters per tube i (the "mechanical basis", 5N columns, in this order):
    c_i   relative scale of tube i's precurvature (κ_i → c_i κ_i on every section; d/dc at c = 1)
    ρ_i   bending-to-torsion stiffness ratio k_i / GJ_i = 1 + ν_i                   (M2)
    α_i   base rotation (rad)                                                       (M4)
    β_i   base position (mm): moves the base condition and every grid point of tube i
    e_i   extra transmission length (mm): ψ_i(0) = α_i − (β_i − e_i) x_i            (M4)

Forward mode (tangent Z = ∂z/∂(x, θ) of the state z = (ψ, uz, p, R), 6N columns):
    Z' = (∂f/∂z) Z + ∂f/∂θ                 (tangent of (M1)-(M3), each RK4 stage differentiated)
    a grid point b owned by tube i moves with β_i: the step h = (b − a) / n of the segments on
    either side changes with it (dh = (db − da) / n), so moving tips and section ends are exact.
Shooting (M4): r(x, θ) = uz(tips) = 0, hence dx/dθ = −(∂r/∂x)⁻¹ ∂r/∂θ, and
    d p_tip / dθ = ∂p/∂θ + ∂p/∂x · dx/dθ   (likewise for the tip tangent R e3).
Grid points of two tubes that coincide exactly (a kink of the tip map) are given to the first tube.
The derivative is of the discrete map with the grid's step counts held fixed; finite differences
agree to their own truncation error (tests/calibration/test_sensitivity.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ctrkin.mechanics.kernels import S_TOL
from ctrkin.mechanics.pointwise import Problem
from ctrkin.mechanics.rk4 import rk4_stepper, rk4_work

N_BASIS = 5   # c, ρ, α, β, e per tube


@njit(cache=True, inline="always")
def _tangent_rhs(z, Z, _zb, p, _with_var, _with_body, f, F, _dzb):
    """The tangent system for mechanics.rk4: f = (M1)-(M3) at z (nz,); F = ∂f/∂z Z + ∂f/∂θ
    + (dh/h) f (nz, M). p = (kap (N,) 1/mm and dkap (N, M) its tangent, rho (N,) = k/GJ and drho
    (N, M), pres (N,) 0/1, k (N,) bending stiffness, dux, duy (M,) scratch, dh (M,) the tangent of
    the step h, h). The last term moves the step with the grid: d/dθ (z + h f) = Z + h (F + (dh/h) f),
    so the tangent of the RK4 map with a moving step is the RK4 map of this system."""
    kap, dkap, rho, drho, pres, k, dux, duy, dh, h = p
    n = k.shape[0]
    n2 = 2 * n
    m = Z.shape[1]
    ksum = 0.0
    ux = 0.0
    uy = 0.0
    dux[:] = 0.0
    duy[:] = 0.0
    for j in range(n):
        if pres[j] > 0.0:
            c = np.cos(z[j])
            s = np.sin(z[j])
            ksum += k[j]
            ux += k[j] * kap[j] * c
            uy += k[j] * kap[j] * s
            for col in range(m):   # (M1) differentiated: d(κ cos ψ) = dκ cos ψ − κ sin ψ dψ
                dux[col] += k[j] * (dkap[j, col] * c - kap[j] * s * Z[j, col])
                duy[col] += k[j] * (dkap[j, col] * s + kap[j] * c * Z[j, col])
    if ksum > 0.0:
        ux /= ksum
        uy /= ksum
        for col in range(m):
            dux[col] /= ksum
            duy[col] /= ksum
    for i in range(n):
        if pres[i] > 0.0:
            c = np.cos(z[i])
            s = np.sin(z[i])
            a = rho[i] * kap[i]
            sx = s * ux - c * uy                 # (M2): uiz' = ρi κi (sin ψi ux − cos ψi uy)
            f[i] = z[n + i]
            f[n + i] = a * sx
            for col in range(m):
                F[i, col] = Z[n + i, col]
                dsx = (c * ux + s * uy) * Z[i, col] + s * dux[col] - c * duy[col]
                F[n + i, col] = (drho[i, col] * kap[i] + rho[i] * dkap[i, col]) * sx + a * dsx
        else:
            f[i] = 0.0
            f[n + i] = 0.0
            for col in range(m):
                F[i, col] = 0.0
                F[n + i, col] = 0.0
    o = n2 + 3
    for row in range(3):   # (M3): p' = R e3; columns of R: c0' = −uy c2, c1' = ux c2, c2' = uy c0 − ux c1
        c0 = z[o + 3 * row]
        c1 = z[o + 3 * row + 1]
        c2 = z[o + 3 * row + 2]
        f[n2 + row] = c2
        f[o + 3 * row] = -uy * c2
        f[o + 3 * row + 1] = ux * c2
        f[o + 3 * row + 2] = uy * c0 - ux * c1
        for col in range(m):
            d0 = Z[o + 3 * row, col]
            d1 = Z[o + 3 * row + 1, col]
            d2 = Z[o + 3 * row + 2, col]
            F[n2 + row, col] = d2
            F[o + 3 * row, col] = -duy[col] * c2 - uy * d2
            F[o + 3 * row + 1, col] = dux[col] * c2 + ux * d2
            F[o + 3 * row + 2, col] = duy[col] * c0 + uy * d0 - dux[col] * c1 - ux * d1
    for col in range(m):
        g = dh[col] / h
        if g != 0.0:
            for j in range(f.shape[0]):
                F[j, col] += g * f[j]


_step = rk4_stepper(_tangent_rhs)


@njit(cache=True)
def tangent_shoot(x, alpha, beta, extra, tips, rigid, k, rho, bounds, owner, kap, present, nsteps):
    """Integrate the TCM state and its tangent at shooting unknowns x (N,) rad/mm.

    alpha (N,) rad; beta (N,) mm (the joints, not minus extra); extra (N,) mm; tips (N,) mm;
    k, rho (N,); bounds (M+1,) mm with owner (M+1,) the tube whose grid point each is (−1: fixed);
    kap, present (M, N); nsteps (M,). Columns: x (N), then the basis c, ρ, α, β, e (N each).
    Returns r (N,) = uz(tips), dr (N, 6N), tip (3,) mm, dtip (3, 6N), tangent (3,), dtangent (3, 6N)
    (the tangent is R e3, unit up to RK4 round-off)."""
    n = k.shape[0]
    n2 = 2 * n
    nz = n2 + 12
    m = (1 + N_BASIS) * n
    z = np.zeros(nz)
    Z = np.zeros((nz, m))
    for d in range(3):
        z[n2 + 3 + 4 * d] = 1.0  # R = I
    for i in range(n):   # (M4) and its tangent
        tw = beta[i] - extra[i]
        z[n + i] = x[i]
        Z[n + i, i] = 1.0
        z[i] = alpha[i] if rigid else alpha[i] - tw * x[i]
        Z[i, n + 2 * n + i] = 1.0                 # ∂ψ/∂α
        if not rigid:
            Z[i, i] = -tw                         # ∂ψ/∂x
            Z[i, n + 3 * n + i] = -x[i]           # ∂ψ/∂β
            Z[i, n + 4 * n + i] = x[i]            # ∂ψ/∂e
    r = np.zeros(n)
    dr = np.zeros((n, m))
    done = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        if tips[i] <= S_TOL:
            done[i] = True
            r[i] = z[n + i]
            dr[i, :] = Z[n + i, :]
    kp = np.empty(n)
    dkap = np.zeros((n, m))
    drho = np.zeros((n, m))
    for i in range(n):
        drho[i, n + n + i] = 1.0
    db = np.zeros((bounds.shape[0], m))
    for b in range(bounds.shape[0]):
        if owner[b] >= 0:
            db[b, n + 3 * n + owner[b]] = 1.0
    w = rk4_work(nz, m, 0)  # the step's stage derivatives and stage states (mechanics.rk4)
    no_body = np.empty(0)
    dux = np.empty(m)
    duy = np.empty(m)
    dh = np.empty(m)
    for seg in range(bounds.shape[0] - 1):
        ns = nsteps[seg]
        h = (bounds[seg + 1] - bounds[seg]) / ns
        for col in range(m):
            dh[col] = (db[seg + 1, col] - db[seg, col]) / ns
        for i in range(n):
            kp[i] = kap[seg, i]
            dkap[i, n + i] = kap[seg, i]          # ∂(c κ)/∂c at c = 1
        p = (kp, dkap, rho, drho, present[seg], k, dux, duy, dh, h)
        for _ in range(ns):
            _step(z, Z, no_body, h, p, True, False, w)
        for i in range(n):
            if not done[i] and tips[i] <= bounds[seg + 1] + S_TOL:
                done[i] = True
                r[i] = z[n + i]
                dr[i, :] = Z[n + i, :]
        for i in range(n):
            dkap[i, n + i] = 0.0
    tip = z[n2:n2 + 3].copy()
    dtip = Z[n2:n2 + 3, :].copy()
    tan = np.array([z[n2 + 5], z[n2 + 8], z[n2 + 11]])
    dtan = np.empty((3, m))
    for d in range(3):
        dtan[d, :] = Z[n2 + 5 + 3 * d, :]
    return r, dr, tip, dtip, tan, dtan


def grid_owners(pb: Problem) -> np.ndarray:
    """(M+1,) the tube whose base position each grid point moves with (−1: s = 0, fixed).

    Grid points are tube tips and section ends, β_i + Σ section lengths (kernels.build_grid)."""
    bounds = pb.grid[0]
    a = pb.arrays
    beta = pb.q[a.k.shape[0]:]
    owner = np.full(bounds.shape[0], -1, dtype=np.int64)
    for b, s in enumerate(bounds):
        if b == 0:
            continue
        for i in range(beta.shape[0]):
            ends = beta[i] + np.cumsum(a.sec_len[i, :a.n_sec[i]])
            if np.any(np.abs(ends - s) <= S_TOL):
                owner[b] = i
                break
    return owner


def tip_jacobian(pb: Problem, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Tip position (3,) mm, its Jacobian (3, 5N) w.r.t. the mechanical basis (module docstring),
    unit tangent (3,) and its Jacobian (3, 5N), at the converged shooting solution x (N,) rad/mm of
    problem pb (mechanics.pointwise.prepare)."""
    a = pb.arrays
    n = a.k.shape[0]
    beta = pb.q[n:]
    _, dr, tip, dtip, tan, dtan = tangent_shoot(
        np.asarray(x, float), pb.alpha, beta, a.extra, pb.tips, a.rigid, a.k, a.k / a.gj,
        pb.grid[0], grid_owners(pb), pb.grid[1], pb.grid[3], pb.grid[4])
    dx = -np.linalg.solve(dr[:, :n], dr[:, n:])          # implicit function theorem on r = 0
    jp = dtip[:, n:] + dtip[:, :n] @ dx
    jt = dtan[:, n:] + dtan[:, :n] @ dx
    norm = float(np.linalg.norm(tan))
    unit = tan / norm
    jt = (jt - np.outer(unit, unit @ jt)) / norm          # d(t/|t|) = (I − t̂ t̂ᵀ) dt / |t|
    return tip, jp, unit, jt
