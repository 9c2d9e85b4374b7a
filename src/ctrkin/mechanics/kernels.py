"""Numba kernels of the torsionally compliant model (TCM), docs/mechanics.md: Model.

State along the arc length s ≥ 0, in a non-twisting (Bishop) backbone frame:
    y = (ψ1..ψN, u1z..uNz)     material angle and torsional curvature of each tube
    Φ = ∂y/∂x                  variational matrix (2N, N), x = uz(0) the shooting unknowns
Equations (eq. M1–M4 below are cited in the code):
    (M1) u_xy = Σ_{i∈P} ki vi / Σ_{i∈P} ki,  vi = Rz(ψi) ûi           backbone bending
    (M2) ψi' = uiz,   uiz' = (ki / GJi)(ux viy − uy vix)               torsion (= ki/GJi (uix ûiy − uiy ûix))
    (M3) p' = R e3,   R' = R [ux, uy, 0]^                              backbone
    (M4) ψi(0) = αi − βi uiz(0) (compliant) or αi (rigid);  uiz(βi + Li) = 0
The RK4 map is differentiated stage by stage, so the Jacobian is exact for the discrete residual
(no finite differences). All angles here are radians. ûi = (κx, κy) is the precurvature of tube i
in its material frame on the stretch (planar tubes: κy = 0, vi = κi (cos ψi, sin ψi)). The contact
stations (friction and clearance, mechanics.contact) act at the grid's breakpoints.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import overload

from ctrkin.mechanics.contact import apply_stations, contact_work
from ctrkin.mechanics.grid import S_TOL, build_grid, prepare
from ctrkin.mechanics.passes import NB, det, flat_pass, flat_work, straight_min_det
from ctrkin.mechanics.passes import relative_det as _relative_det
from ctrkin.mechanics.rk4 import rk4_stepper, rk4_work

__all__ = ["S_TOL", "build_grid", "integrate_full", "newton", "prepare", "sane", "shoot"]


@njit(cache=True)
def _solve_linear(a, v, out, m):
    """Solve a out = v by Gaussian elimination with partial pivoting, on m (N, N), a copy of a, and
    on v in place; False if (near-)singular."""
    n = v.shape[0]
    m[:, :] = a
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
def _init_state(x, alpha, beta, rigid, k, gj, y, phi, zb):
    """(M4) base conditions: ψi(0) = αi − βi xi (compliant) or αi (rigid), uiz(0) = xi; body at the
    front plate: p = 0, R = I, energy ½ GJi xi² (−βi) stored in the compliant transmission."""
    n = x.shape[0]
    phi[:, :] = 0.0
    zb[:] = 0.0
    for d in range(3):
        zb[3 + 4 * d] = 1.0
    for i in range(n):
        y[n + i] = x[i]
        y[i] = alpha[i] if rigid else alpha[i] - beta[i] * x[i]
        phi[n + i, i] = 1.0
        if not rigid:
            phi[i, i] = -beta[i]
            zb[12] += 0.5 * gj[i] * x[i] * x[i] * (-beta[i])


@njit(cache=True, inline="always")
def _body_deriv(zb, ux, uy, y, pres, k, gj, vx, vy, dzb):
    """(M3) and the elastic energy density Σ ½ ki |u − Rz(ψi) ûi|² + ½ GJi uiz², at backbone
    curvature (ux, uy) and vx, vy = Rz(ψ) û (from _rhs at the same state y).
    zb: p (3), R row-major (9), energy; R' = R [u]^ with u = (ux, uy, 0): columns c0' = −uy c2,
    c1' = ux c2, c2' = uy c0 − ux c1; p' = c2."""
    n = k.shape[0]
    for row in range(3):
        c0 = zb[3 + 3 * row]
        c1 = zb[4 + 3 * row]
        c2 = zb[5 + 3 * row]
        dzb[row] = c2
        dzb[3 + 3 * row] = -uy * c2
        dzb[4 + 3 * row] = ux * c2
        dzb[5 + 3 * row] = uy * c0 - ux * c1
    e = 0.0
    for i in range(n):
        if pres[i] > 0.0:
            bx = ux - vx[i]
            by = uy - vy[i]
            e += 0.5 * k[i] * (bx * bx + by * by) + 0.5 * gj[i] * y[n + i] * y[n + i]
    dzb[12] = e


@njit(cache=True, inline="always")
def _rhs(y, phi, zb, p, with_var, with_body, dy, dphi, dzb):
    """The TCM as an RK4 system (mechanics.rk4): (M1), (M2) and its variation dΦ = A(y) Φ always,
    (M3) and the energy if with_body. p = (κx (N,), κy (N,), present (N,), k, gj, vx, vy): the
    stretch's precurvature and tubes, the stiffnesses and two (N,) scratch arrays for vi = Rz(ψi) ûi
    (ûi = (κx, κy): (κ cos ψ, κ sin ψ) for planar precurvature). Writes dy (2N,), dphi (2N, N).

    uiz' = (ki/GJi)(ux viy − uy vix);  ∂uiz'/∂ψj = (ki/GJi) [δij (u · vi) − kj (vi · vj) / Σk].
    One flat function: every array an inlined helper takes costs reference counting per call,
    four calls per RK4 step (it made the pass 2-4× its bare arithmetic, issue 26)."""
    kap, kapy, pres, k, gj, vx, vy = p
    n = k.shape[0]
    ksum = 0.0
    ux = 0.0
    uy = 0.0
    for i in range(n):  # (M1)
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
    for i in range(n):  # (M2)
        if pres[i] > 0.0:
            dy[i] = y[n + i]
            dy[n + i] = k[i] / gj[i] * (ux * vy[i] - uy * vx[i])
        else:
            dy[i] = 0.0
            dy[n + i] = 0.0
    if with_var:
        nc = phi.shape[1]
        for i in range(n):
            if pres[i] > 0.0:
                for c in range(nc):
                    dphi[i, c] = phi[n + i, c]
                for c in range(nc):
                    dphi[n + i, c] = 0.0
                if kap[i] == 0.0 and kapy[i] == 0.0:
                    continue
                a = k[i] / gj[i]
                for j in range(n):  # row i of ∂uz'/∂ψ, one entry at a time, times row j of Φ
                    if pres[j] > 0.0 and (kap[j] != 0.0 or kapy[j] != 0.0):
                        m = -a * k[j] * (vx[i] * vx[j] + vy[i] * vy[j]) / ksum
                        if i == j:
                            m += a * (ux * vx[i] + uy * vy[i])
                        for c in range(nc):
                            dphi[n + i, c] += m * phi[j, c]
            else:
                for c in range(nc):
                    dphi[i, c] = 0.0
                    dphi[n + i, c] = 0.0
    if with_body:
        _body_deriv(zb, ux, uy, y, pres, k, gj, vx, vy, dzb)


_rk4_step = rk4_stepper(_rhs)


@njit(cache=True)
def _work(n):
    """Work arrays of _integrate: those of the RK4 step (rk4_work), vx, vy (N,) and a (2N, N)
    copy of Φ at the start of a stretch."""
    return rk4_work(2 * n, n, NB), np.empty(n), np.empty(n), np.empty((2 * n, n))


@njit(cache=True)
def _integrate(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
               with_var, with_body, y, phi, zb, w, r, jac,
               record, s_rec, p_rec, psi_rec, uz_rec, cst, cpr, cvar, cprm, cout):
    """One integration pass from s = 0 with uz(0) = x: (M2) always, writing the residuals
    r_i = uiz(tip_i) (M4); the variation and jac = ∂r/∂x (N, N) if with_var; (M3) and the energy
    into zb if with_body; the grid records (see integrate_full) if record; the contact stations
    (mechanics.contact.apply_stations: friction jumps of uz, clearance tilt) at the breakpoints if
    cst is not None (cst, cpr, cvar, cprm, cout: the contact arrays, None without contact
    effects).

    Returns min over s ∈ (0, min tip] of det H (_relative_det; +inf for one tube or without the
    variation). On a straight stretch taken in one exact step, Φ is affine in s, so det H is
    sampled at the nsample points of spacing ≤ h_max as if the stretch had been stepped.
    """
    n = k.shape[0]
    nb = bounds.shape[0]
    _init_state(x, alpha, beta, rigid, k, gj, y, phi, zb)
    rk, vx, vy, phi_a = w
    p_int = rk[4]  # a stage state of Φ, free between stretches
    done = np.zeros(n, dtype=np.bool_)
    min_tip = tips.min()
    min_det = np.inf
    check = with_var and n > 1
    js = 0
    if cst is not None:
        cw = contact_work(n)
        js = apply_stations(cst, cpr, cvar, cprm, cout, 0, js, y, phi, zb, with_var, with_body, k,
                            gj, kap, kapy, present, nb, cw)
    if record:
        s_rec[0] = 0.0
        p_rec[0, :] = 0.0
        for i in range(n):
            on = tips[i] > S_TOL
            psi_rec[0, i] = y[i] if on else np.nan
            uz_rec[0, i] = y[n + i] if on else np.nan
    rec = 0
    for i in range(n):  # a tube flush with the front plate ends at s = 0
        if tips[i] <= S_TOL:
            done[i] = True
            r[i] = y[n + i]
            if with_var:
                for c in range(n):
                    jac[i, c] = phi[n + i, c]
    for seg in range(nb - 1):
        a, b = bounds[seg], bounds[seg + 1]
        ns = nsteps[seg]
        h = (b - a) / ns
        sampled = check and ns < nsample[seg]
        if sampled:
            phi_a[:, :] = phi
        p = (kap[seg], kapy[seg], present[seg], k, gj, vx, vy)  # the stretch's system (_rhs)
        for st in range(ns):
            _rk4_step(y, phi, zb, h, p, with_var, with_body, rk)
            if check and a + (st + 1) * h <= min_tip + S_TOL:
                d = _relative_det(phi, gj)
                if d < min_det:
                    min_det = d
            if record:
                rec += 1
                s_rec[rec] = a + (st + 1) * h
                for d3 in range(3):
                    p_rec[rec, d3] = zb[d3]
                for i in range(n):
                    on = present[seg, i] > 0.0
                    psi_rec[rec, i] = y[i] if on else np.nan
                    uz_rec[rec, i] = y[n + i] if on else np.nan
        if sampled and b <= min_tip + S_TOL:
            d = straight_min_det(phi_a, phi, gj, nsample[seg], p_int)
            if d < min_det:
                min_det = d
        if cst is not None:   # friction torques at the breakpoint, before the tips' residuals
            js = apply_stations(cst, cpr, cvar, cprm, cout, seg + 1, js, y, phi, zb, with_var,
                                with_body, k, gj, kap, kapy, present, nb, cw)
        for i in range(n):
            if not done[i] and tips[i] <= b + S_TOL:
                done[i] = True
                r[i] = y[n + i]
                if with_var:
                    for c in range(n):
                        jac[i, c] = phi[n + i, c]
    return min_det


@njit(cache=True)
def shoot(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample, r, jac,
          with_var, cst=None, cpr=None, cvar=None, cprm=None, cout=None):
    """Integrate (M2) from s = 0 with uz(0) = x; write residuals r_i = uiz(tip_i) (M4) and, if
    with_var, their exact Jacobian jac = ∂r/∂x (N, N); cst, cpr, cvar, cprm, cout: the contact
    arrays (mechanics.contact.apply_stations), None without contact effects.

    x, alpha (rad), beta (mm), tips (mm): (N,). Returns min over s ∈ (0, min tip] of det H
    (see _relative_det; +inf for one tube or without the variation).
    """
    n = k.shape[0]
    return _integrate(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                      nsample, with_var, False, np.empty(2 * n), np.empty((2 * n, n)),
                      np.empty(NB), _work(n), r, jac, False, np.empty(1), np.empty((1, 3)),
                      np.empty((1, 1)), np.empty((1, 1)), cst, cpr, cvar, cprm, cout)


@njit(cache=True)
def _tip(zb, out):
    """out (7,) = tip position (3,) mm, unit tip tangent (3,) (third column of R), energy."""
    for d in range(3):
        out[d] = zb[d]
        out[3 + d] = zb[5 + 3 * d]
    nrm = math.sqrt(out[3] * out[3] + out[4] * out[4] + out[5] * out[5])
    for d in range(3):
        out[3 + d] /= nrm
    out[6] = zb[12]


def _pass(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
          with_var, with_body, work, r, jac, zb, cst, cpr, cvar, cprm, cout):
    """One pass of a Newton solve into r, jac and (with_body) zb (NB,), chosen when numba compiles
    the solve (overload below): passes.flat_pass without contact effects (cst None, work =
    passes.flat_work), _integrate with them (work = _newton_work's)."""
    raise NotImplementedError("compiled only (numba overload)")


def _newton_work(n, cst):
    """The work of a Newton solve's passes (overload below): passes.flat_work(n) without contact
    effects (cst None), else _integrate's y (2N,), Φ (2N, N), _work(n) and its unused records."""
    raise NotImplementedError("compiled only (numba overload)")


def _no_contact(cst):
    return isinstance(cst, (types.NoneType, types.Omitted))


@overload(_pass)
def _pass_impl(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
               with_var, with_body, work, r, jac, zb, cst, cpr, cvar, cprm, cout):
    if _no_contact(cst):
        def flat(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
                 with_var, with_body, work, r, jac, zb, cst, cpr, cvar, cprm, cout):
            md = flat_pass(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                           nsample, with_var, with_body, work, r, jac)
            if with_body:
                zs = work[2]
                for j in range(NB):
                    zb[j] = zs[0, j]
            return md
        return flat

    def general(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
                with_var, with_body, work, r, jac, zb, cst, cpr, cvar, cprm, cout):
        y, phi, w, rs, ps, qs, us = work
        return _integrate(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                          nsample, with_var, with_body, y, phi, zb, w, r, jac, False, rs, ps, qs,
                          us, cst, cpr, cvar, cprm, cout)
    return general


@overload(_newton_work)
def _newton_work_impl(n, cst):
    if _no_contact(cst):
        return lambda n, cst: flat_work(n)

    def general(n, cst):
        rec = np.empty(6)
        return (np.empty(2 * n), np.empty((2 * n, n)), _work(n), rec[0:1], rec[1:4].reshape((1, 3)),
                rec[4:5].reshape((1, 1)), rec[5:6].reshape((1, 1)))
    return general


@njit(cache=True, inline="always")
def _inf_norm(v):
    """max |vi| of a vector (NaN if any is), np.abs(v).max() without its temporary."""
    out = 0.0
    for e in v:
        a = abs(e)
        if a > out:
            out = a
        elif a != a:
            return math.nan
    return out


# A full Newton step from residual |r| lands near C |r|² (quadratic convergence); C is measured on
# the iteration's own steps (|r₊| / |r|²), and taken as C0 (mm/rad) before the first. A step
# predicted to land below tol is run as the final pass: without the variation, with the backbone
# and energy (a wrong guess costs that pass; tol/10 instead made more passes on both robots).
C0 = 1e3


@njit(cache=True)
def newton(x0, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
           tol, max_iter, max_step, x_out, body_out, cst=None, cpr=None, cvar=None, cprm=None,
           cout=None):
    """Damped Newton on the shooting residual from x0 (rad/mm).

    Writes the root to x_out and, if converged, body_out (7,) = tip position (3,) mm, unit tip
    tangent (3,), elastic energy (N·mm) (_tip); converged means |r|∞ < tol and the checks of
    `sane`. A start that is not finite returns at once, not converged (x_out = x0, |r| = inf).
    Returns (converged, iterations, |r|∞, det J, min det H, passes) where J = ∂r/∂x at the root
    (Gilbert et al. 2016 stability measure), det H the conjugate-point test (see shoot) and passes
    the number of integrations (the work, backtracking included).

    The pass predicted to be the last (C |r|² < tol) integrates the backbone and
    energy instead of the variation; J and det H are then those of the previous iterate, |Δx| ≤
    |r| / |J| away (≤ 1e-7 relative for tol 1e-10), which no stability decision can resolve. A
    wrong prediction costs that pass and Newton carries on. max_step bounds |Δx|∞ per iteration
    (rad/mm). cst, cpr, cvar, cprm, cout: the contact arrays (mechanics.contact.apply_stations)
    or None; the outputs cout are those of the last pass, at the root when converged. The friction
    elements make the residual piecewise smooth (stick and slip): Newton on it is semismooth, its
    Jacobian that of the active branch of each element. Without them every pass is
    passes.flat_pass, and the solve allocates two arrays (its vectors, the passes' work).
    """
    work = _newton_work(x0.shape[0], cst)
    return _newton(x0, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                   nsample, tol, max_iter, max_step, x_out, body_out, work, cst, cpr, cvar, cprm,
                   cout)


@njit(cache=True)
def _newton(x0, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
            tol, max_iter, max_step, x_out, body_out, work, cst, cpr, cvar, cprm, cout):
    """newton with the passes' work arrays given (its docstring)."""
    n = x0.shape[0]
    x_out[:] = x0
    for v in x0:
        if not math.isfinite(v):  # nothing to integrate from
            return False, 0, math.inf, math.nan, math.nan, 0
    nn = n * n
    buf = np.empty(6 * n + 3 * nn + NB)  # the solve's vectors, one allocation
    x, r, dx, xt, rt, mr = buf[:n], buf[n:2 * n], buf[2 * n:3 * n], buf[3 * n:4 * n], \
        buf[4 * n:5 * n], buf[5 * n:6 * n]
    jac = buf[6 * n:6 * n + nn].reshape((n, n))
    jt = buf[6 * n + nn:6 * n + 2 * nn].reshape((n, n))
    mj = buf[6 * n + 2 * nn:6 * n + 3 * nn].reshape((n, n))
    zb = buf[6 * n + 3 * nn:]
    x[:] = x0
    mdet = _pass(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
                 True, False, work, r, jac, zb, cst, cpr, cvar, cprm, cout)
    rn = _inf_norm(r)
    it = 0
    shoots = 1
    have_body = False
    c_quad = C0
    converged = rn < tol
    while not converged and it < max_iter:
        it += 1
        for i in range(n):
            mr[i] = -r[i]
        if not _solve_linear(jac, mr, dx, mj):
            break
        big = _inf_norm(dx)
        full = big <= max_step
        if not full:
            dx *= max_step / big
        final = full and c_quad * rn * rn < tol
        t = 1.0
        accepted = False
        for _ in range(12):  # backtracking line search on |r|∞
            for i in range(n):
                xt[i] = x[i] + t * dx[i]
            if final:
                _pass(xt, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                      nsample, False, True, work, rt, jt, zb, cst, cpr, cvar, cprm, cout)
                shoots += 1
                final = False
                rnt = _inf_norm(rt)
                if rnt < tol:
                    have_body = True
                    accepted = True
                    break
            md = _pass(xt, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                       nsample, True, False, work, rt, jt, zb, cst, cpr, cvar, cprm, cout)
            shoots += 1
            rnt = _inf_norm(rt)
            if rnt < (1.0 - 1e-4 * t) * rn or rnt < tol:
                accepted = True
                break
            t *= 0.5
        if not accepted:
            break
        if have_body:
            x[:] = xt
            rn = rnt
            converged = True
            break
        if t == 1.0 and full and rn > 0.0:
            c_quad = rnt / (rn * rn)
        x[:] = xt
        r[:] = rt
        jac[:, :] = jt
        rn = rnt
        mdet = md
        converged = rn < tol
    if converged and not have_body:
        _pass(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
              False, True, work, rt, jt, zb, cst, cpr, cvar, cprm, cout)
        shoots += 1
    if converged:
        _tip(zb, body_out)
        converged = sane(x, body_out, tips)
    x_out[:] = x
    return converged, it, rn, det(jac), mdet, shoots


@njit(cache=True)
def sane(x, body, tips):
    """Checks a converged equilibrium must pass (x: the root, body: _tip): a finite root, a finite
    tip no farther from the base than the longest tube reaches (a backbone is never longer than
    itself; 1e-6 relative slack for round-off), a finite unit tip tangent (so a unit quaternion)
    and a finite energy."""
    for v in x:
        if not math.isfinite(v):
            return False
    for v in body:
        if not math.isfinite(v):
            return False
    s_end = max(tips.max(), 0.0)
    tip = math.sqrt(body[0] * body[0] + body[1] * body[1] + body[2] * body[2])
    # the tangent was normalised by _tip: |t| − 1 measures only NaN/overflow (finite check above)
    return tip <= s_end * (1.0 + 1e-6) + 1e-9


@njit(cache=True)
def integrate_full(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
                   record, s_rec, p_rec, psi_rec, uz_rec, body_out, cst=None, cpr=None, cvar=None,
                   cprm=None, cout=None):
    """Integrate (M2), (M3) and the elastic energy at the solution x into body_out (7,) (_tip).

    If record, every grid point is written to s_rec (K,), p_rec (K, 3) mm, psi_rec (K, N) rad and
    uz_rec (K, N) rad/mm, K = 1 + Σ nsteps; tubes not present there are NaN. Energy = Σ ∫ ½ ki
    |u − Rz(ψi) ûi|² + ½ GJi uiz² ds, plus ½ GJi xi² (−βi) stored in the compliant transmission
    and the friction elements' potential (the contact arrays, mechanics.contact.apply_stations).
    """
    n = k.shape[0]
    zb = np.empty(NB)
    _integrate(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
               False, True, np.empty(2 * n), np.empty((2 * n, n)), zb, _work(n), np.empty(n),
               np.empty((n, n)), record, s_rec, p_rec, psi_rec, uz_rec, cst, cpr, cvar, cprm,
               cout)
    _tip(zb, body_out)
