"""The naive plan the planner is measured against: per target, IK by point-wise solves (no
history: the least-energy equilibrium at each candidate, the paper's TCM baseline), then the straight
joint line to its answer, executed on the mechanics by continuation, snaps and all. It is what a
controller does that trusts a history-free model and moves straight to the joints it gives."""

from __future__ import annotations

import numpy as np

from ctrkin.mechanics.pointwise import Equilibrium, solve
from ctrkin.planning.ik import branch_ik
from ctrkin.planning.paths import Checked, check
from ctrkin.planning.planner import PlanConfig
from ctrkin.robots.robot import Robot


def naive_path(robot: Robot, start: np.ndarray, targets: np.ndarray,
               tangents: np.ndarray | None = None, config: PlanConfig | None = None
               ) -> list[Checked]:
    """One executed leg per target (K): joints, tips, margin and snaps of each, as the planner's
    routes. start (2N,) joints; targets (K, 3) mm; tangents (K, 3) or None."""
    cfg = config or PlanConfig()
    limits = cfg.limits(robot)
    cur: Equilibrium = solve(robot, robot.check_joints(np.asarray(start, dtype=float)))
    legs = []
    for k, target in enumerate(np.atleast_2d(targets)):
        tan = None if tangents is None else tangents[k]
        seed = solve(robot, cur.q)
        sol = branch_ik(robot, seed, target, limits, tan, 0.0, max_iter=cfg.ik_iterations,
                        history=False)
        leg = check(robot, cur, "naive", [sol.q])
        legs.append(leg)
        cur = leg.equilibria[-1]
    return legs
