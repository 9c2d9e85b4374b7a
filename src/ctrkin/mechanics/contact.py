"""Contact between neighbouring tubes: Coulomb friction elements and the clearance tilt (numba),
docs/mechanics.md: Friction and clearance (equations C1–C7).

Tube i and tube i+1 (pair p = i) touch where the bundle of tubes 1..i exchanges bending moment with
the tubes outside it. The bundle's moment (in the backbone frame)

    (C1) M_p = K_in u − Σ_{c≤i} k_c v_c,   v_c = Rz(ψ_c) û_c,   K_in = Σ_{c≤i, present} k_c

jumps at every breakpoint of the grid (a precurvature change, a tube tip, the front plate: the
tubes are held by the actuation unit for s < 0, so M = 0 there). A jump ΔM is carried by a force
couple over a contact length ℓ set by the radial clearance δ of the pair: the bundle crosses the gap
between the two contact points, a relative displacement 2δ = |ΔM| ℓ² / (6 k_eff) for a moment that
ramps linearly over ℓ, with k_eff = K_in K_out / (K_in + K_out):

    (C2) ℓ = clip(√(12 δ k_eff / |ΔM|), od_i, ℓ_max),   N_c = 2 |ΔM| / ℓ   (two contact forces)

(Lock & Dupont, ICRA 2011: the friction of concentric tubes is concentrated at curvature
discontinuities and tube ends; Ha, Fagogenis & Dupont, T-RO 2019: contact forces with clearance).
Between breakpoints the distributed contact force per unit length is |M_p''| (the derivative of the
shear force), lumped half into each end of the stretch:

    (C3) N_d = ½ h_left |M_p''(s⁻)| + ½ h_right |M_p''(s⁺)|

The friction element at the breakpoint is elasto-plastic (a play element): stuck offset θ, trial
vector of the slip at the contact surface (torsion, axial) a = r_c (φ − θ) / ε, b = Δd / ε (φ = ψ_i −
ψ_{i+1}, Δd the relative translation of the pair in this step, ε the element's elastic slip, mm),
returned to the unit disc of Coulomb's law (isotropic friction: the force opposes the slip
velocity at the surface, whatever its direction):

    (C4) T_max = μ r_c (N_c + N_d),   g = a / max(1, √(a² + b²)),   f = T_max g
    (C5) uz_i⁺ = uz_i⁻ + f / GJ_i,    uz_{i+1}⁺ = uz_{i+1}⁻ − f / GJ_{i+1}       (torque −f on tube i)
    (C6) θ ← φ − ε_t g   after an accepted step (stick: unchanged; slip: the element moves), ε_t = ε / r_c

A translation (b ≫ 1) takes the friction axially and releases the torsional element, as Coulomb's
law does for combined sliding. With clearance, the bundle leaving an outer tube's tip tilts in the
gap towards its own precurvature (the deficit of the ramped moment):

    (C7) ω = min(|ΔM| ℓ / (2 k_eff), 6 δ / ℓ) · ΔM / |ΔM|     (body-frame rotation of the backbone)

with ℓ from (C2) at the scaled gap (Robot.clearance · δ). All angles in radians, lengths mm, forces N.
(numba's cache tracks only a kernel's own file: after editing this file, clear the __pycache__
folders of mechanics, whose kernels.py inlines these functions.)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# modes of a friction element after a pass
FRESH, STICK, SLIP = -2, 0, 1


@njit(cache=True)
def build_stations(bounds, present, code, tips, width):
    """Friction stations of one grid: every breakpoint b where tube p+1 is present on the side of
    the pair (left of b; for s = 0 the right), for each pair p.

    bounds (M+1,) mm, present (M, N), code (M+1,) breakpoint identities (grid.build_grid), tips (N,)
    mm, width = N (S + 1) + 1 slots per pair. Returns st_b (K,) breakpoint index, st_p (K,) pair,
    st_slot (K,) state slot p·width + code, lmax (K,) the pair's exposed overlap (mm, the longest
    couple), hl, hr (K,) the lengths of the stretches either side where the pair is present (mm),
    tip (K,) bool: tube p+1 ends at the breakpoint."""
    n = tips.shape[0]
    nb = bounds.shape[0]
    cap = max(1, nb * max(n - 1, 1))
    st_b = np.empty(cap, dtype=np.int64)
    st_p = np.empty(cap, dtype=np.int64)
    st_slot = np.empty(cap, dtype=np.int64)
    lmax = np.empty(cap)
    hl = np.empty(cap)
    hr = np.empty(cap)
    tip = np.zeros(cap, dtype=np.bool_)
    cnt = 0
    for b in range(nb):
        for p in range(n - 1):
            o = p + 1
            on_left = b > 0 and present[b - 1, o] > 0.0
            on_right = b < nb - 1 and present[b, o] > 0.0
            if not (on_left or (b == 0 and on_right)):
                continue
            st_b[cnt] = b
            st_p[cnt] = p
            st_slot[cnt] = p * width + code[b]
            lmax[cnt] = max(tips[o], 0.0)
            hl[cnt] = bounds[b] - bounds[b - 1] if on_left else 0.0
            hr[cnt] = bounds[b + 1] - bounds[b] if on_right else 0.0
            tip[cnt] = abs(tips[o] - bounds[b]) <= 1e-9
            cnt += 1
    return (st_b[:cnt].copy(), st_p[:cnt].copy(), st_slot[:cnt].copy(), lmax[:cnt].copy(),
            hl[:cnt].copy(), hr[:cnt].copy(), tip[:cnt].copy())


@njit(cache=True, inline="always")
def _side(y, kx, ky, pres, k, gj, inner, sign, dist, h, dm, ddm, gm, vx, vy, aa):
    """One side of a breakpoint: adds sign · M_p (C1) to dm (2,) and sign · ∂M_p/∂ψ to gm (N, 2);
    if dist and h > 0, returns ½ h |M_p''| (C3) and adds its gradient over y (2N,) to ddm. Returns
    (½ h |M''|, K_in, K_out) of the side. vx, vy, aa: (N,) scratch."""
    n = k.shape[0]
    ksum = 0.0
    kin = 0.0
    for c in range(n):
        if pres[c] > 0.0:
            ksum += k[c]
            if c <= inner:
                kin += k[c]
    if ksum == 0.0:
        return 0.0, 0.0, 0.0
    ux = 0.0
    uy = 0.0
    curved = False
    for c in range(n):
        vx[c] = 0.0
        vy[c] = 0.0
        aa[c] = 0.0
        if pres[c] > 0.0 and (kx[c] != 0.0 or ky[c] != 0.0):
            curved = True
            cs = math.cos(y[c])
            sn = math.sin(y[c])
            vx[c] = kx[c] * cs - ky[c] * sn
            vy[c] = kx[c] * sn + ky[c] * cs
            ux += k[c] * vx[c]
            uy += k[c] * vy[c]
            aa[c] = k[c] * (kin / ksum - (1.0 if c <= inner else 0.0))
    ux /= ksum
    uy /= ksum
    for c in range(n):
        if aa[c] != 0.0:
            dm[0] += sign * aa[c] * vx[c]
            dm[1] += sign * aa[c] * vy[c]
            gm[c, 0] -= sign * aa[c] * vy[c]
            gm[c, 1] += sign * aa[c] * vx[c]
    nd = 0.0
    if dist and h > 0.0 and curved:
        # M'' = Σ a_c (v⊥_c w_c − v_c z_c²), w_c = uz_c' = (k_c/GJ_c)(ux v_cy − uy v_cx) (M2)
        mx = 0.0
        my = 0.0
        for c in range(n):
            if aa[c] != 0.0:
                w = k[c] / gj[c] * (ux * vy[c] - uy * vx[c])
                z2 = y[n + c] * y[n + c]
                mx += aa[c] * (-vy[c] * w - vx[c] * z2)
                my += aa[c] * (vx[c] * w - vy[c] * z2)
        mag = math.sqrt(mx * mx + my * my)
        nd = 0.5 * h * mag
        if mag > 0.0:
            ex = 0.5 * h * mx / mag
            ey = 0.5 * h * my / mag
            for j in range(n):
                if aa[j] != 0.0:   # ∂/∂z_j and the explicit ∂/∂ψ_j of tube j's own term
                    wj = k[j] / gj[j] * (ux * vy[j] - uy * vx[j])
                    z = y[n + j]
                    ddm[n + j] += aa[j] * (-2.0 * z) * (ex * vx[j] + ey * vy[j])
                    ddm[j] += aa[j] * (ex * (-vx[j] * wj + vy[j] * z * z)
                                       + ey * (-vy[j] * wj - vx[j] * z * z))
                if pres[j] > 0.0 and (kx[j] != 0.0 or ky[j] != 0.0):
                    for c in range(n):   # through w_c: ∂w_c/∂ψ_j = g_c (δ_cj u·v_c − k_j v_j·v_c / K)
                        if aa[c] != 0.0:
                            dw = -k[j] / ksum * (vx[j] * vx[c] + vy[j] * vy[c])
                            if c == j:
                                dw += ux * vx[c] + uy * vy[c]
                            dw *= k[c] / gj[c]
                            ddm[j] += aa[c] * dw * (-ex * vy[c] + ey * vx[c])
    return nd, kin, ksum - kin


@njit(cache=True, inline="always")
def turn_wrapped(x):
    """x (rad) less its whole turns, in [−π, π]: the relative angle φ of a pair and its stuck
    offset θ are angles, and the solver reduces each α to (−180°, 180°] (pointwise.whole_turns_removed),
    so φ − θ jumps by 2π where a tube's α crosses 180° between two steps; the slip is the rest."""
    return x - 2.0 * math.pi * math.floor(x / (2.0 * math.pi) + 0.5)


@njit(cache=True)
def station(y, b, p, lmax, hl, hr, theta, dd, bounds_n, kap, kapy, present, k, gj,
            gap, rc, lmin, mu, eps, dist, clearance, dfdy, scr, gm, out):
    """Friction element at breakpoint b of pair p (C1–C4) at state y = (ψ, uz) (2N,).

    kap, kapy, present: the grid's (M, N) rows (stretch b − 1 on the left, b on the right; bounds_n =
    M + 1); theta: stuck offset (rad; NaN: a fresh contact, no force); dd: relative translation of
    the pair in this step (mm); gap, rc, lmin (P,): radial clearance, contact radius and shortest
    couple (mm) per pair; mu: friction coefficient; eps (mm): the elastic slip of an element at the
    contact surface (torsional range ε / r_c rad); dist: include (C3); clearance: scale of the gap
    for the tilt (C7).
    Writes dfdy (2N,) = ∂f/∂y and out (8,) = (φ rad, g, N (N), mode, tilt angle (rad), tilt axis
    x, y, T_max (N·mm)); scr (4, N), gm (N, 2): scratch. Returns f (N·mm): the torque −f acts on
    tube p, +f on tube p + 1 (C5)."""
    n = k.shape[0]
    o = p + 1
    for j in range(2 * n):
        dfdy[j] = 0.0
    for c in range(n):
        gm[c, 0] = 0.0
        gm[c, 1] = 0.0
    dm = scr[3]
    dm[0] = 0.0
    dm[1] = 0.0
    kin = 0.0
    kout = 0.0
    nd = 0.0
    if b > 0:
        d1, kin, kout = _side(y, kap[b - 1], kapy[b - 1], present[b - 1], k, gj, p, -1.0, dist,
                              hl, dm, dfdy, gm, scr[0], scr[1], scr[2])
        nd += d1
    if b < bounds_n - 1:
        d2, ki2, ko2 = _side(y, kap[b], kapy[b], present[b], k, gj, p, 1.0, dist, hr, dm, dfdy,
                             gm, scr[0], scr[1], scr[2])
        nd += d2
        if b == 0:
            kin, kout = ki2, ko2
    big = math.sqrt(dm[0] * dm[0] + dm[1] * dm[1])
    keff = kin * kout / (kin + kout) if kin > 0.0 and kout > 0.0 else 0.0
    top = max(lmax, lmin[p])
    nc = 0.0
    dnc = 0.0      # ∂N_c/∂|ΔM|
    if big > 0.0 and keff > 0.0:
        ell = math.sqrt(12.0 * gap[p] * keff / big)
        dnc = 3.0
        if ell < lmin[p] or ell > top:
            ell = min(max(ell, lmin[p]), top)
            dnc = 2.0
        nc = 2.0 * big / ell                          # (C2)
        dnc /= ell
    tmax = mu * rc[p] * (nc + nd)                     # (C4)
    phi = y[p] - y[o]
    out[0] = phi
    out[2] = nc + nd
    out[4] = 0.0
    out[5] = 0.0
    out[6] = 0.0
    out[7] = tmax
    if clearance > 0.0 and big > 0.0 and keff > 0.0:   # (C7), at the scaled gap
        dl = clearance * gap[p]
        lc = min(max(math.sqrt(12.0 * dl * keff / big), lmin[p]), top)
        out[4] = min(big * lc / (2.0 * keff), 6.0 * dl / lc)
        out[5] = dm[0] / big
        out[6] = dm[1] / big
    if not math.isfinite(theta) or tmax <= 0.0:
        out[1] = 0.0
        out[3] = FRESH if not math.isfinite(theta) else STICK
        for j in range(2 * n):
            dfdy[j] = 0.0
        return 0.0
    eps_t = eps / rc[p]
    a = turn_wrapped(phi - theta) / eps_t
    bb = dd / eps
    nrm = math.sqrt(a * a + bb * bb)
    if nrm <= 1.0:
        g = a
        dg = 1.0 / eps_t
        out[3] = STICK
    else:
        g = a / nrm
        dg = bb * bb / (nrm * nrm * nrm) / eps_t
        out[3] = SLIP
    out[1] = g
    # ∂f/∂y = g ∂T_max/∂y + T_max ∂g/∂φ ∂φ/∂y, ∂T_max = μ r (∂N_c + ∂N_d)
    s = mu * rc[p] * g
    for j in range(2 * n):
        dfdy[j] *= s                               # ∂N_d/∂y, accumulated by _side
    if dnc > 0.0:
        for c in range(n):
            dfdy[c] += s * dnc * (dm[0] * gm[c, 0] + dm[1] * gm[c, 1]) / big
    dfdy[p] += tmax * dg
    dfdy[o] -= tmax * dg
    return tmax * g


@njit(cache=True, inline="always")
def huber(g_raw):
    """Potential of a unit play element at normalised displacement a: ½ a² (stick), |a| − ½ (slip)."""
    aa = abs(g_raw)
    return 0.5 * aa * aa if aa <= 1.0 else aa - 0.5


@njit(cache=True, inline="always")
def tilt(zb, ax, ay, ang):
    """Rotate the backbone frame R (zb[3:12], row-major) by angle ang (rad) about the body-frame
    axis (ax, ay, 0) (unit): R ← R exp(ang [e]^) (Rodrigues)."""
    c = math.cos(ang)
    s = math.sin(ang)
    t = 1.0 - c
    # E = exp(ang [e]^) for e = (ax, ay, 0)
    e00 = c + t * ax * ax
    e01 = t * ax * ay
    e02 = s * ay
    e10 = t * ax * ay
    e11 = c + t * ay * ay
    e12 = -s * ax
    e20 = -s * ay
    e21 = s * ax
    e22 = c
    for row in range(3):
        r0 = zb[3 + 3 * row]
        r1 = zb[4 + 3 * row]
        r2 = zb[5 + 3 * row]
        zb[3 + 3 * row] = r0 * e00 + r1 * e10 + r2 * e20
        zb[4 + 3 * row] = r0 * e01 + r1 * e11 + r2 * e21
        zb[5 + 3 * row] = r0 * e02 + r1 * e12 + r2 * e22


# columns of the per-station array cst (K, ST_COLS) and the per-pair array cpr (P, PR_COLS)
ST_B, ST_PAIR, ST_LMAX, ST_HL, ST_HR, ST_TIP = range(6)
ST_COLS = 6
PR_GAP, PR_RC, PR_LMIN = range(3)
PR_COLS = 3


@njit(cache=True)
def station_table(bounds, present, code, tips, width):
    """build_stations as the kernels take them: table (K, 6) the per-station array cst (columns
    ST_B … ST_TIP: breakpoint, pair, ℓ_max mm, h_left mm, h_right mm, tip 0/1, as float64), slot
    (K,) and the breakpoint index b (K,). One definition for friction.Stations.build and the
    compiled runs of translating steps (mechanics.warm.friction_moving_run)."""
    b, pair, slot, lmax, hl, hr, tip = build_stations(bounds, present, code, tips, width)
    table = np.empty((b.shape[0], ST_COLS))
    for j in range(b.shape[0]):
        table[j, ST_B] = b[j]
        table[j, ST_PAIR] = pair[j]
        table[j, ST_LMAX] = lmax[j]
        table[j, ST_HL] = hl[j]
        table[j, ST_HR] = hr[j]
        table[j, ST_TIP] = 1.0 if tip[j] else 0.0
    return table, slot, b


@njit(cache=True)
def apply_stations(cst, cpr, cvar, cprm, cout, b, js, y, phi, zb, with_var, with_body, k, gj, kap,
                   kapy, present, nb, work):
    """Apply the friction elements of breakpoint b (stations js, js + 1, … of cst) to the state: the
    torque jumps (C5) on y (2N,) and, if with_var, on the variation Φ (2N, N) through ∂f/∂y; if
    with_body, the elements' potential (the play element's, with T_max frozen) into the energy
    zb[12] and the clearance tilt (C7) of the backbone frame at an outer tube's tip.

    cst (K, 6): per station (breakpoint, pair, ℓ_max mm, h_left mm, h_right mm, tip 0/1);
    cpr (P, 3): per pair (gap mm, contact radius mm, shortest couple mm); cvar (K + P,): the
    step's state, θ (rad, NaN: fresh) per station then Δd (mm) per pair; cprm (4,) = (μ, ε mm,
    clearance, distributed 0/1); cout (K, 8): the stations' outputs (contact.station), written;
    work: scratch of contact_work. Returns the index of the first station past b."""
    mu, eps, clr = cprm[0], cprm[1], cprm[2]
    dist = cprm[3] > 0.0
    dfdy, scr, gm, row = work
    n = k.shape[0]
    nst = cst.shape[0]
    gap, rc, lmin = cpr[:, PR_GAP], cpr[:, PR_RC], cpr[:, PR_LMIN]
    while js < nst and int(cst[js, ST_B]) == b:
        p = int(cst[js, ST_PAIR])
        o = p + 1
        theta = cvar[js]
        ot = cout[js]
        f = station(y, b, p, cst[js, ST_LMAX], cst[js, ST_HL], cst[js, ST_HR], theta,
                    cvar[nst + p], nb, kap, kapy, present, k, gj, gap, rc, lmin, mu, eps, dist, clr,
                    dfdy, scr, gm, ot)
        if with_var:
            nc = phi.shape[1]
            for c in range(nc):
                acc = 0.0
                for j in range(2 * n):
                    acc += dfdy[j] * phi[j, c]
                row[c] = acc
            for c in range(nc):
                phi[n + p, c] += row[c] / gj[p]
                phi[n + o, c] -= row[c] / gj[o]
        y[n + p] += f / gj[p]
        y[n + o] -= f / gj[o]
        if with_body:
            if math.isfinite(theta) and ot[7] > 0.0:
                eps_t = eps / rc[p]
                zb[12] += ot[7] * eps_t * huber(turn_wrapped(ot[0] - theta) / eps_t)
            if cst[js, ST_TIP] > 0.0 and ot[4] > 0.0:
                tilt(zb, ot[5], ot[6], ot[4])
        js += 1
    return js


@njit(cache=True)
def gather_state(theta_all, slot, q_now, q_then):
    """The kernels' cvar (K + P,) of a friction state: θ (K,) of the stations' slots, then each
    pair's relative translation Δ(β_p − β_{p+1}) (mm) from the state's joints q_then (2N,) to
    q_now (2N,)."""
    nst = slot.shape[0]
    n = q_now.shape[0] // 2
    out = np.empty(nst + n - 1)
    for j in range(nst):
        out[j] = theta_all[slot[j]]
    for p in range(n - 1):
        out[nst + p] = (q_now[n + p] - q_then[n + p]) - (q_now[n + p + 1] - q_then[n + p + 1])
    return out


@njit(cache=True)
def state_after(slot, cout, cst, cpr, eps, size):
    """Stuck offsets (size,) after a converged solve whose stations gave cout (K, 8): each element's
    offset moved by its slip (C6), a fresh one set where it is, every other slot NaN (a contact
    that is not a station any more loses its state)."""
    theta = np.full(size, np.nan)
    for j in range(slot.shape[0]):
        phi, g = cout[j, 0], cout[j, 1]
        if cout[j, 3] == FRESH:
            theta[slot[j]] = phi
        else:
            theta[slot[j]] = phi - eps / cpr[int(cst[j, ST_PAIR]), PR_RC] * g
    return theta


@njit(cache=True)
def contact_work(n):
    """Scratch of apply_stations for N tubes: ∂f/∂y (2N,), (4, N), (N, 2) and a row (N,)."""
    return np.empty(2 * n), np.empty((4, n)), np.empty((n, 2)), np.empty(n)
