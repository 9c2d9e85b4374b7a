"""Joint paths between two configurations and their check on the mechanics.

A leg is a straight line in joint space, cut into steps of at most 5° of any α and 1 mm of any β;
a route is a list of legs. A route is checked by continuation (`mechanics.follow`) from the robot's
current equilibrium, which flags every fold crossed (a snap), and every step's stability margin
(planning.margin). Routes offered for one move, in order of joint motion:

1. direct: the straight line to the goal;
2. the other way round: the goal with the relative rotation α1 − αN taken by the other side of a
   whole turn (α1 ± 360°: the same configuration reached turning the other way);
3. detours through low curved overlap: translate to the translations of least curved overlap
   near the straight path (`robots.overlap`), rotate there (where the pair is not bistable, or
   least so), translate to the goal: the way an operator pulls the inner tube back into the outer
   one, or pushes it out, before turning it through the bistable band.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ctrkin.mechanics.continuation import follow
from ctrkin.mechanics.pointwise import Equilibrium
from ctrkin.planning.ik import Limits
from ctrkin.planning.margin import stability_margin
from ctrkin.robots.overlap import curved_overlap_one
from ctrkin.robots.robot import Robot

STEP_DEG, STEP_MM = 5.0, 1.0


@dataclass(frozen=True)
class Checked:
    """A route checked on the mechanics: q (T, 2N) joints of every step (the start excluded),
    tips (T, 3) mm, margin (T,), snaps (T,) bool, equilibria (T,), name of the route."""

    name: str
    q: np.ndarray
    tips: np.ndarray
    margin: np.ndarray
    snaps: np.ndarray
    equilibria: list[Equilibrium]

    @property
    def motion(self) -> float:
        """Joint motion: Σ |Δα| / 30° + Σ |Δβ| / 1 mm along the route (30° ~ 1 mm)."""
        n = self.q.shape[1] // 2
        d = np.abs(np.diff(self.q, axis=0))
        return float(d[:, :n].sum() / 30.0 + d[:, n:].sum())


def densify(waypoints: list[np.ndarray]) -> np.ndarray:
    """(T, 2N) steps along straight legs between waypoints (the first excluded)."""
    rows = []
    n = waypoints[0].shape[0] // 2
    for a, b in itertools.pairwise(waypoints):
        d = np.abs(b - a)
        k = max(1, int(np.ceil(max(d[:n].max() / STEP_DEG, d[n:].max() / STEP_MM))))
        rows.append(a + (b - a) * (np.arange(1, k + 1)[:, None] / k))
    return np.concatenate(rows) if rows else np.empty((0, waypoints[0].shape[0]))


def check(robot: Robot, start: Equilibrium, name: str, waypoints: list[np.ndarray]) -> Checked:
    """Follow the route start.q → waypoints on the mechanics from the equilibrium start."""
    q = densify([start.q, *waypoints])
    traj = follow(robot, q, start=start)
    margin = np.array([stability_margin(robot, e) for e in traj.equilibria])
    return Checked(name, q, traj.tip_positions, margin, traj.snaps.copy(), traj.equilibria)


def _low_overlap_betas(robot: Robot, q0: np.ndarray, q1: np.ndarray, limits: Limits,
                       grid: int = 7) -> list[np.ndarray]:
    """Translations (N,) of least curved overlap on a grid of the box spanned by the limits and the
    robot's valid set, nearest first among equals (at most two: the least overlap, and the least
    overlap that moves the outer tubes least)."""
    n = robot.n_tubes
    axes = [np.linspace(max(limits.lo[n + i], -robot.lengths[i]), min(limits.hi[n + i], 0.0), grid)
            for i in range(n)]
    cands = np.array(list(itertools.product(*axes)))
    cands = cands[robot.is_valid(np.c_[np.zeros((len(cands), n)), cands])]
    if len(cands) == 0:
        return []
    over = np.array([curved_overlap_one(robot, b) for b in cands])
    dist = (np.abs(cands - q0[n:]).sum(axis=1) + np.abs(cands - q1[n:]).sum(axis=1))
    order = np.lexsort((dist, np.round(over, 3)))
    best = cands[order[0]]
    outer_still = np.abs(cands[:, 1:] - q0[n + 1:]).sum(axis=1) if n > 1 else np.zeros(len(cands))
    alt = cands[np.lexsort((dist, outer_still, np.round(over, 3)))[0]]
    return [best] if np.allclose(alt, best) else [best, alt]


def routes(robot: Robot, q0: np.ndarray, goal: np.ndarray, limits: Limits
           ) -> list[tuple[str, list[np.ndarray]]]:
    """Candidate routes q0 → goal (module docstring), each as (name, waypoints)."""
    n = robot.n_tubes
    goals = [("direct", goal)]
    for turn in (360.0, -360.0):
        other = goal.copy()
        other[0] += turn
        if limits.holds(other):
            goals.append(("other way", other))
    out = [(name, [g]) for name, g in goals]
    for beta in _low_overlap_betas(robot, q0, goal, limits):
        for name, g in goals:
            a = q0.copy()
            a[n:] = beta
            b = g.copy()
            b[n:] = beta
            out.append((f"detour ({name})", [a, b, g]))
    return out
