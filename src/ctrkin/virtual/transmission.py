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

from ctrkin.robots.overlap import curved_overlap
from ctrkin.robots.robot import Robot
from ctrkin.virtual.config import VirtualConfig

__all__ = ["clip_to_valid", "curved_overlap", "dead_band", "play"]


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
