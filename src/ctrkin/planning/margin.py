"""The stability margin of an equilibrium: how far the robot is from the nearest fold.

The continuation's stability measure is det J = det ∂uz(tips)/∂uz(0) (docs/mechanics.md: Stability):
1 for a straight robot, → 0 at a fold, where the branch ends and the robot snaps. Its scale grows
with the curved overlap (on the paper robot 1.0 at no overlap, 2.9 at full overlap with the tubes
aligned), so the margin divides it by its value at the same translations with every tube at the
same rotation (α0 = 0: the tubes' curvatures aligned, the most stable configuration, unique branch):

    m(q) = det J(q) / det J(α = 0, β)            (1 at aligned tubes, 0 at a fold)

An unstable or unconverged equilibrium has margin 0. Only the translations set the reference, so it
is cached per β.
"""

from __future__ import annotations

import functools

import numpy as np

from ctrkin.mechanics.pointwise import Equilibrium, solve
from ctrkin.robots.robot import Robot


@functools.lru_cache(maxsize=4096)
def _reference(robot: Robot, beta: tuple[float, ...]) -> float:
    """det J at translations beta (N,) mm with every α = 0 (the aligned, unique equilibrium)."""
    eq = solve(robot, np.r_[np.zeros(len(beta)), beta])
    return float(eq.stability) if eq.stable else 1.0


def stability_margin(robot: Robot, eq: Equilibrium) -> float:
    """Margin m (dimensionless, ≥ 0) of equilibrium eq of robot: module docstring."""
    if not eq.stable:
        return 0.0
    n = robot.n_tubes
    beta = tuple(np.round(eq.q[n:], 6).tolist())
    return max(0.0, float(eq.stability) / _reference(robot, beta))
