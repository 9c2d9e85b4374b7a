"""The outer tube's transmission lag, measured from the data by rotation equivariance.

A tube's base follows its motor through a dead band (gear backlash plus friction wind-up), so after the
outer motor last turned in direction m_N ∈ {−1, 0, +1} (0: not since rest) the outer tube sits at

    αN,tube = αN − λ(β) · m_N,        λ(β) = a + b · overlap(β)                         (1)

where overlap(β) is the curved overlap (ctrkin.robots.overlap): the friction torque grows with the
contact force of curved tubes pressing on each other. The outer motor does not move while a recorded
sequence turns the inner tube, so no input window shows m_N; a model that learns in the frame of the
commanded αN learns the lag of its training data (the paper protocol turns the outer tube forward
before each recorded turn: m_N = +1) and misses by λ·r at a start from rest or after a backward turn.
ctrkin.models.frame turns with αN,tube instead, with (a, b) from `fit_outer_lag`.

Fit: the outer frame is a rotation about the insertion axis, so in the frame of the commanded αN two
rows with the same translations, the same relative angle φ = α1 − αN and the same direction of the
inner turn differ only by Rz(−λ·Δm). For each such pair of a row at rest (m_N = 0) and a row after an
outer turn (m_N = ±1), λ = −(∠p₂ − ∠p₁)/m₂ from the angles of the tip positions about the axis. The
tubes' relative angle of the second row is its commanded φ + λ·m₂, so rows are matched at φ₂ = φ₁ − λ·m₂
and λ iterated to its fixed point (matching at equal commanded φ underestimates λ by the fraction the
tip turns with φ). The median per translation set, then (a, b) by least squares with a, b ≥ 0 (1).
"""

from __future__ import annotations

import numpy as np

from ctrkin.metrics import wrap_deg
from ctrkin.robots.overlap import curved_overlap, curved_overlap_one
from ctrkin.robots.robot import Robot

SETTLED_DEG = 15.0    # inner travel since its last reversal before a row counts (dead band ≤ 13°)
MATCH_DEG = 1.01      # farthest a bracketing row may lie from the matched angle (the protocols step 1°)
MIN_RADIUS_MM = 1.0   # tip distance from the axis below which its angle is not believed
ITERATIONS = 6        # fixed-point steps of the matching (converges when the tip turns less than φ)


def lag_deg(robot: Robot, joints: np.ndarray, coef: tuple[float, float]) -> np.ndarray:
    """λ(β) (T,) deg of (1) for joints (T, 2N)."""
    a, b = coef
    if b == 0.0:
        return np.full(len(np.atleast_2d(joints)), a)
    return a + b * curved_overlap(robot, joints)


def lag_one(robot: Robot, q: np.ndarray, coef: tuple[float, float]) -> float:
    """λ(β) deg of (1) for one joint vector q (2N,) in scalar arithmetic (the streaming steps)."""
    a, b = coef
    return a if b == 0.0 else a + b * curved_overlap_one(robot, q[robot.n_tubes:])


def fit_outer_lag(robot: Robot, joints: np.ndarray, local: np.ndarray, motion: np.ndarray,
                  bounds: list[tuple[int, int]], use: np.ndarray) -> tuple[float, float]:
    """(a, b) of (1). joints (T, 2N); local (T, ≥3) measured positions in the frame of the commanded
    αN; motion (T,) m_N; use (T,) bool rows that may be used (training rows). (0, 0) without pairs."""
    n = robot.n_tubes
    J = np.asarray(joints, float)
    phi = np.mod(J[:, 0] - J[:, n - 1], 360.0)
    ang = np.degrees(np.arctan2(local[:, 1], local[:, 0]))
    ok = use & _settled(J[:, 0], bounds) & (np.hypot(local[:, 0], local[:, 1]) > MIN_RADIUS_MM)
    direction = _inner_direction(J[:, 0], bounds)
    keys = np.round(J[:, n:], 3)
    sets: dict[tuple, list[float]] = {}
    for key in {tuple(k) for k in keys[ok & (motion == 0)]}:
        same = ok & np.all(keys == np.asarray(key), axis=1)
        lam = 0.0
        for _ in range(ITERATIONS):        # the pair's relative angles differ by λ·m: a fixed point
            lags: list[float] = []
            for d in (-1, 1):
                rest = np.nonzero(same & (direction == d) & (motion == 0))[0]
                for m in (-1, 1):
                    moved = np.nonzero(same & (direction == d) & (motion == m))[0]
                    if len(rest) and len(moved):
                        lags.extend(_pair_lags(phi, ang, m, lam, rest, moved))
            if len(lags) < 10:
                break
            lam = float(np.median(lags))
            sets[key] = lags
    med = {k: (float(np.median(v)), len(v)) for k, v in sets.items()}
    if not med:
        return 0.0, 0.0
    keys_arr = np.array(list(med))
    q = np.concatenate([np.zeros((len(keys_arr), n)), keys_arr], axis=1)
    overlap = curved_overlap(robot, q)
    per_set = np.array([v[0] for v in med.values()])
    w = np.sqrt([v[1] for v in med.values()])
    return _nonnegative_line(overlap, per_set, w)


def _pair_lags(phi: np.ndarray, ang: np.ndarray, m: int, lam: float, rest: np.ndarray,
               moved: np.ndarray) -> list[float]:
    """λ of each row at rest against the rows after an outer turn in direction m at the same tube
    relative angle, commanded φ − λ·m (λ: the current estimate): their tip angle interpolated
    linearly between the two rows that bracket it within MATCH_DEG."""
    order = moved[np.argsort(phi[moved])]
    ps = phi[order]
    out = []
    for r in rest:
        target = (phi[r] - lam * m) % 360.0
        k = int(np.searchsorted(ps, target))
        if k == 0 or k == len(ps):
            continue
        lo, hi = int(order[k - 1]), int(order[k])
        span = phi[hi] - phi[lo]
        if target - phi[lo] > MATCH_DEG or phi[hi] - target > MATCH_DEG:
            continue
        w = (target - phi[lo]) / span if span > 1e-9 else 0.0
        a_hi = ang[lo] + (ang[hi] - ang[lo] + 180.0) % 360.0 - 180.0
        a_p = (1.0 - w) * ang[lo] + w * a_hi
        diff = float(wrap_deg(a_p - ang[r]))
        out.append(-diff / m)
    return out


def _nonnegative_line(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    """Weighted least squares y ≈ a + b x with a, b ≥ 0 (the active-set cases of two unknowns)."""
    A = np.c_[np.ones_like(x), x] * w[:, None]
    yw = y * w
    if len(x) >= 2 and np.ptp(x) > 1e-9:
        a, b = np.linalg.lstsq(A, yw, rcond=None)[0]
        if a >= 0 and b >= 0:
            return float(a), float(b)
    a_only = max(float(np.sum(w * yw) / np.sum(w * w)), 0.0)
    xs = float(np.sum(A[:, 1] * A[:, 1]))
    b_only = max(float(np.sum(A[:, 1] * yw) / xs), 0.0) if xs > 0 else 0.0
    r_a = float(np.sum((yw - a_only * w) ** 2))
    r_b = float(np.sum((yw - b_only * A[:, 1]) ** 2))
    return (a_only, 0.0) if r_a <= r_b else (0.0, b_only)


def _inner_direction(alpha1: np.ndarray, bounds: list[tuple[int, int]]) -> np.ndarray:
    """(T,) sign of the inner tube's last step within its sequence (0 before its first move)."""
    out = np.zeros(len(alpha1), dtype=np.int8)
    for a, b in bounds:
        cur = 0
        for t in range(a + 1, b):
            d = alpha1[t] - alpha1[t - 1]
            if abs(d) > 1e-9:
                cur = 1 if d > 0 else -1
            out[t] = cur
    return out


def _settled(alpha1: np.ndarray, bounds: list[tuple[int, int]]) -> np.ndarray:
    """(T,) bool: the inner tube has turned ≥ SETTLED_DEG since its last reversal (its own dead band
    taken up), within the sequence."""
    out = np.zeros(len(alpha1), dtype=bool)
    for a, b in bounds:
        cur, travel = 0, 0.0
        for t in range(a + 1, b):
            d = alpha1[t] - alpha1[t - 1]
            if abs(d) > 1e-9:
                s = 1 if d > 0 else -1
                travel = travel + abs(d) if s == cur else abs(d)
                cur = s
            out[t] = travel >= SETTLED_DEG
    return out
