"""Motor-to-tube transmission: backlash and torsional friction as a direction-dependent dead band.

A play (backlash) operator per joint: the tube base follows the motor only once the motor has taken up
the play, so after a reversal the base lags by up to half the band width w (Krasnosel'skii–Pokrovskii
play operator, the standard model of gear backlash and of Coulomb friction with a compliant drive):

    b(t) = clip(b(t−1), m(t) − w(t)/2, m(t) + w(t)/2)

For rotation joints w = gear backlash + friction wind-up; the wind-up grows with the curved overlap of
the tubes (inter-tube contact force, hence friction torque, exists where curved tubes press on each
other), so hysteresis loops widen with overlap even where the TCM itself has none. For translation
joints w is the lead-screw backlash.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ctrkin.robots.robot import Robot
from ctrkin.virtual.config import VirtualConfig


def curved_overlap(robot: Robot, Q: np.ndarray) -> np.ndarray:
    """Length (mm) of s ≥ 0 where at least two tubes with non-zero precurvature overlap.

    Q: (T, 2N) joints (deg, mm) -> (T,) mm. On the paper robot: 0 for d ≤ 5.5 mm, 14.5 at d = 20 mm.
    """
    Qa = np.atleast_2d(np.asarray(Q, dtype=float))
    n = robot.n_tubes
    beta = Qa[:, n:]
    starts, ends = [], []
    for i, t in enumerate(robot.tubes):
        cum = 0.0
        for s in t.sections:
            if s.curvature != 0.0 and s.length > 0:
                starts.append(np.maximum(beta[:, i] + cum, 0.0))
                ends.append(np.maximum(beta[:, i] + cum + s.length, 0.0))
            cum += s.length
    if len(starts) < 2:
        return np.zeros(Qa.shape[0])
    a = np.stack(starts, axis=1)  # (T, K)
    b = np.stack(ends, axis=1)
    pts = np.sort(np.concatenate([a, b], axis=1), axis=1)  # (T, 2K)
    mid = 0.5 * (pts[:, 1:] + pts[:, :-1])  # (T, 2K-1)
    cover = ((a[:, None, :] <= mid[:, :, None]) & (mid[:, :, None] < b[:, None, :])).sum(axis=2)
    return ((cover >= 2) * np.diff(pts, axis=1)).sum(axis=1)


def dead_band(robot: Robot, config: VirtualConfig, Q: np.ndarray) -> np.ndarray:
    """Full dead-band width per joint, (T, 2N): deg for rotations, mm for translations."""
    Qa = np.atleast_2d(np.asarray(Q, dtype=float))
    n = robot.n_tubes
    w = np.empty_like(Qa)
    rot = (config.gear_backlash_deg + config.friction_deg
           + config.friction_deg_per_mm * curved_overlap(robot, Qa))
    w[:, :n] = rot[:, None]
    w[:, n:] = config.leadscrew_backlash_mm
    return w


@njit(cache=True)
def play(motor: np.ndarray, width: np.ndarray, start: np.ndarray, out: np.ndarray) -> None:
    """Play operator. motor, width: (T, J); start: (J,) the base position before motor[0];
    out: (T, J) base positions, written in place."""
    prev = start.copy()
    for t in range(motor.shape[0]):
        for j in range(motor.shape[1]):
            lo = motor[t, j] - 0.5 * width[t, j]
            hi = motor[t, j] + 0.5 * width[t, j]
            v = prev[j]
            if v < lo:
                v = lo
            elif v > hi:
                v = hi
            out[t, j] = v
            prev[j] = v


def clip_to_valid(robot: Robot, Q: np.ndarray) -> np.ndarray:
    """Project joints (T, 2N) onto the valid set as the mechanical stops would (Robot.project_joints)."""
    return robot.project_joints(Q)
