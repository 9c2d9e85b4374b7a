"""Inverse kinematics on one equilibrium branch of the mechanics (the TCM).

Damped least squares (Levenberg-Marquardt) on the tip error, with every candidate solved by Newton
warm-started from the state of the last accepted iterate: Newton stays on that branch, so a
candidate whose solution is unstable (past a fold), jumps in twist, or has a stability margin below
the threshold is rejected like one that does not lower the error, and the damping grows. The
Jacobian is by forward differences of the tip (3 rows, plus 3 of the tip tangent in mm per rad
when an orientation is asked). Joints stay within the robot's valid set (`Robot.project_joints`)
and the planner's α and β limits; steps are capped (α ≤ 15°, β ≤ 3 mm per iteration) so the branch
is tracked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctrkin.mechanics.pointwise import Equilibrium, solve, twist_distance
from ctrkin.planning.margin import stability_margin
from ctrkin.robots.robot import Robot

TANGENT_WEIGHT_MM = 10.0   # mm of tip error that weigh as one radian of tangent error
JUMP_RAD = 0.35            # the continuation's largest twist change per step (mechanics)
MAX_DALPHA, MAX_DBETA = 15.0, 3.0


@dataclass(frozen=True)
class Limits:
    """Joint box (2N,) lo and hi (deg, mm), inside which the robot's own validity also holds."""

    lo: np.ndarray
    hi: np.ndarray

    def clip(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        """q (2N,) clipped to the box, then projected onto the robot's valid translations."""
        out = np.clip(q, self.lo, self.hi)
        return robot.project_joints(out[None])[0]

    def holds(self, q: np.ndarray, tol: float = 1e-9) -> bool:
        return bool(np.all(q >= self.lo - tol) and np.all(q <= self.hi + tol))


@dataclass(frozen=True)
class BranchSolution:
    """The IK's answer: q (2N,), its equilibrium, tip error (mm), tangent error (deg, NaN if no
    orientation was asked), margin (stability_margin) and iterations."""

    q: np.ndarray
    equilibrium: Equilibrium
    error_mm: float
    angle_deg: float
    margin: float
    iterations: int


def _residual(eq: Equilibrium, target: np.ndarray, tangent: np.ndarray | None) -> np.ndarray:
    r = eq.tip_position - target
    if tangent is None:
        return r
    return np.r_[r, TANGENT_WEIGHT_MM * (eq.tip_tangent - tangent)]


def _solve(robot: Robot, q: np.ndarray, prev: Equilibrium, history: bool) -> Equilibrium:
    """On prev's branch (a raw Newton start), or point-wise without history (the least-energy
    stable equilibrium: the paper's TCM baseline)."""
    return solve(robot, q, guess=prev.x) if history else solve(robot, q)


def _try(robot: Robot, q: np.ndarray, prev: Equilibrium, min_margin: float, history: bool
         ) -> tuple[Equilibrium, float] | None:
    """The equilibrium at q continued from prev's branch, or None if it left the branch or its
    margin is below min_margin (history=False: point-wise, any branch)."""
    eq = _solve(robot, q, prev, history)
    if not eq.stable or (history and twist_distance(eq.x, prev.x, robot.lengths) > JUMP_RAD):
        return None
    m = stability_margin(robot, eq)
    return (eq, m) if m >= min_margin else None


def branch_ik(robot: Robot, start: Equilibrium, target: np.ndarray, limits: Limits,
              tangent: np.ndarray | None = None, min_margin: float = 0.0,
              tol_mm: float = 0.05, max_iter: int = 60, history: bool = True) -> BranchSolution:
    """Joints reaching target (3,) mm (and unit tangent (3,) if given) on start's branch.

    start: the stable equilibrium the search begins at (its q is the seed). Stops when the tip is
    within tol_mm (and the tangent within tol_mm / TANGENT_WEIGHT_MM rad), or after max_iter
    iterations; returns the best iterate whatever its error (the caller judges it). history=False
    solves every candidate point-wise instead (no branch: the naive IK the planner is compared with).
    """
    n2 = robot.n_joints
    cur = start
    q = start.q.copy()
    r = _residual(cur, target, tangent)
    cost = float(r @ r)
    margin = stability_margin(robot, cur)
    lam = 1e-2
    h = np.r_[np.full(robot.n_tubes, 1e-3), np.full(robot.n_tubes, 1e-4)]   # deg, mm
    it = 0
    for it in range(1, max_iter + 1):   # noqa: B007 (the count is returned)
        if np.sqrt(cost) < tol_mm:
            break
        jac = np.empty((r.shape[0], n2))
        for j in range(n2):
            qj = q.copy()
            qj[j] += h[j] if qj[j] + h[j] <= limits.hi[j] else -h[j]
            qj = robot.project_joints(qj[None])[0]
            dq = qj[j] - q[j]
            if dq == 0.0:
                jac[:, j] = 0.0
                continue
            ej = _solve(robot, qj, cur, history)
            jac[:, j] = (_residual(ej, target, tangent) - r) / dq if ej.converged else 0.0
        scale = np.r_[np.full(robot.n_tubes, 1.0 / 30.0), np.ones(robot.n_tubes)]  # 30° ~ 1 mm
        js = jac / scale
        jtj, g = js.T @ js, js.T @ r
        accepted = False
        while lam < 1e8:
            step = -np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-9), g) / scale
            big = max(np.abs(step[:robot.n_tubes]).max() / MAX_DALPHA,
                      np.abs(step[robot.n_tubes:]).max() / MAX_DBETA, 1.0)
            q_new = limits.clip(robot, q + step / big)
            got = _try(robot, q_new, cur, min_margin, history)
            if got is not None:
                r_new = _residual(got[0], target, tangent)
                c_new = float(r_new @ r_new)
                if c_new < cost:
                    cur, margin = got
                    q, r, cost = q_new, r_new, c_new
                    lam = max(lam / 3.0, 1e-6)
                    accepted = True
                    break
            lam *= 4.0
        if not accepted:
            break
    angle = np.nan
    if tangent is not None:
        angle = float(np.degrees(np.arccos(np.clip(cur.tip_tangent @ tangent, -1.0, 1.0))))
    return BranchSolution(q, cur, float(np.linalg.norm(cur.tip_position - target)), angle, margin,
                          it)
