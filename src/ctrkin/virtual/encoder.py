"""Rare encoder glitches: a recorded joint reading is corrupted (the robot itself did not move).

The paper removed "outliers caused by encoder errors" (Sec. III.A); here they are kept and flagged
(`outlier = True`) so cleaning can be tested. A glitch adds ±U(¼, 1)·glitch_deg to one rotation
reading or ±U(¼, 1)·glitch_mm to one translation reading, the joint drawn uniformly; a translation
reading stays within the stage's travel (clipped to the valid joint set, as the controller reports).
"""

from __future__ import annotations

import numpy as np

from ctrkin.robots.robot import Robot
from ctrkin.virtual.transmission import clip_to_valid


def glitch(robot: Robot, Q: np.ndarray, rate: float, max_deg: float, max_mm: float,
           rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Readings of joints Q (T, 2N) with glitches -> (readings (T, 2N), outlier (T,) bool)."""
    Qa = np.atleast_2d(np.asarray(Q, dtype=float))
    t_count, n_j = int(Qa.shape[0]), int(Qa.shape[1])
    n = robot.n_tubes
    hit = np.asarray(rng.random(size=t_count) < rate)
    joint = np.asarray(rng.integers(0, n_j, size=t_count))
    mag: np.ndarray = rng.uniform(0.25, 1.0, size=t_count) * rng.choice([-1.0, 1.0], size=t_count)
    out = Qa.copy()
    rows = np.nonzero(hit)[0]
    if rows.size == 0:
        return out, hit
    scale = np.where(joint[rows] < n, max_deg, max_mm)
    out[rows, joint[rows]] += mag[rows] * scale
    out[rows] = clip_to_valid(robot, out[rows])
    # a glitch clipped back onto the true reading is no glitch
    changed = np.abs(out[rows] - Qa[rows]).max(axis=1) > 0
    outlier = np.zeros(t_count, dtype=bool)
    outlier[rows[changed]] = True
    return out, outlier
