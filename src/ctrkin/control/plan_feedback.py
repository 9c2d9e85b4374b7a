"""Executing a plan with tracker feedback (issue 24; docs/planning.md: Executing a plan with feedback).

A plan (ctrkin.planning) is made on a model of the robot (the nominal or a calibrated TCM), which a
real robot misses by millimetres (friction, backlash, tube errors, the tracker's own registration).
A real system therefore drives the plan and, at each target, reads its tracker and corrects:

1. drive the plan's joints to the target (the correction of the previous target carried along as
   a constant joint offset, where the model says that is safe; else the plan's own joints, after
   going back along the correction);
2. read the tracker; while the measured tip is further than `tol_mm` from the target, take one
   correction step: the model's branch IK (planning.ik: damped least squares on the model's
   Jacobian, Newton on the branch the model is on) towards the model's own tip moved by the
   measured error, e = p* − p_measured,

       goal = p_model(q) + gain · e,     Δq = branch_ik(goal) − q,   |Δα| ≤ 15°, |Δβ| ≤ 3 mm

   and check the step on the model as the planner checks a route (planning.paths.check:
   continuation in ≤ 5°, ≤ 1 mm steps, no fold crossed, stability margin ≥ the planner's floor:
   PlanConfig.min_margin, or the margin the robot is at where that is lower). A step that fails the
   check is halved up to `halvings` times; where none passes, the planner itself is asked for a
   route from here to the model's goal (planning.plan_path: its routes and detours, the same
   checks), then the branch IK seeded at other relative rotations (`_replan`: the tracker's view
   of a target may need one far from the plan's); where none is safe, the target is left as it is
   (reported, never forced).

The loop is an integrator on the tracker: the model only needs the right Jacobian and the right
branch, its offset from the robot is measured away. What it does not remove: the tracker's static
error (registration, field warp, the sensor point): the tip is taken to the target as the tracker
sees it, which is all a tracked system knows; the snaps of a robot whose folds differ from the
model's (the margin is the cushion for those).

    rig = VirtualRig(VirtualRobot(paper_robot(), seed=0), plan.q[0])      # or a real actuator + tracker
    done = execute_plan(robot, plan, targets, rig)
    done.settled, done.steps                                             # per target
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from ctrkin.errors import CtrkinError
from ctrkin.mechanics.pointwise import Equilibrium, solve
from ctrkin.planning.ik import MAX_DALPHA, MAX_DBETA, branch_ik
from ctrkin.planning.margin import stability_margin
from ctrkin.planning.paths import Checked, check, routes
from ctrkin.planning.planner import Plan, PlanConfig, plan_path
from ctrkin.robots.robot import Robot


class Rig(Protocol):
    """What the executor needs of a robot: drive joints, read the tracker."""

    def move(self, q: np.ndarray) -> None:
        """Drive the motors through the joints q (T, 2N) (deg, mm), in order."""

    def measure(self) -> np.ndarray | None:
        """The tip position the tracker reports now, (3,) mm; None without a valid frame."""


@dataclass(frozen=True)
class FeedbackConfig:
    """tol_mm: a target is settled when the measured tip is within this distance (mm; below the
    goal's 1 mm by the tracker noise it must see through); max_steps: correction steps per target;
    gain: fraction of the measured error asked of one step (0 < gain <= 1); ik_iterations: the
    branch IK's iterations per step; halvings: how often an unsafe step is halved before the target
    is left; step_deg, step_mm: the largest change of any alpha (deg) and any beta (mm) in one
    correction step (the branch IK's own caps; a step is checked, and driven, in <= 5 deg, <= 1 mm
    pieces)."""

    tol_mm: float = 0.5
    max_steps: int = 12
    gain: float = 1.0
    ik_iterations: int = 8
    halvings: int = 3
    step_deg: float = MAX_DALPHA
    step_mm: float = MAX_DBETA

    def __post_init__(self) -> None:
        for name in ("tol_mm", "step_deg", "step_mm"):
            if not getattr(self, name) > 0:
                raise CtrkinError(f"FeedbackConfig.{name} must be > 0, got {getattr(self, name)}")
        if not 0.0 < self.gain <= 1.0:
            raise CtrkinError(f"FeedbackConfig.gain must lie in (0, 1], got {self.gain}")
        for name, least in (("max_steps", 0), ("ik_iterations", 1), ("halvings", 0)):
            if getattr(self, name) < least:
                raise CtrkinError(f"FeedbackConfig.{name} must be a count >= {least}, got "
                                  f"{getattr(self, name)}")


@dataclass(frozen=True, eq=False)
class Executed:
    """A plan driven with feedback. q (T, 2N): every joint command in order; at (K,) the index in q
    of each target's last command (−1: not driven, the plan did not reach it or the tracker was lost
    before, or no command was needed: the robot was there at its start); measured (K, 3) mm the last
    tracker reading at each target (NaN if none); steps (K,)
    correction steps taken; refused (K,) steps the margin check turned down (after halving) that
    ended the target's correction; settled (K,) bool: the measured tip within tol_mm;
    margin (T,) the model's stability margin at every command."""

    q: np.ndarray
    at: np.ndarray
    measured: np.ndarray
    steps: np.ndarray
    refused: np.ndarray
    settled: np.ndarray
    margin: np.ndarray


def _safe(c: Checked, floor: float) -> bool:
    return bool(not c.snaps.any() and c.margin.min() >= floor)


def _inside(model: Robot, cfg: PlanConfig, q: np.ndarray) -> bool:
    """Every row of q (T, 2N) within the planner's limits and the robot's valid set."""
    lim = cfg.limits(model)
    return bool(np.all(q >= lim.lo - 1e-9) and np.all(q <= lim.hi + 1e-9) and model.is_valid(q).all())


def _correct(model: Robot, cur: Equilibrium, error: np.ndarray, cfg: PlanConfig, fb: FeedbackConfig,
             floor: float) -> Checked | None:
    """One correction step from cur for a measured error (3,) mm, checked; None if no safe one."""
    limits = cfg.limits(model)
    n = model.n_tubes
    goal = cur.tip_position + fb.gain * error
    sol = branch_ik(model, cur, goal, limits, None, floor, max_iter=fb.ik_iterations)
    dq = sol.q - cur.q
    dq /= max(np.abs(dq[:n]).max() / fb.step_deg, np.abs(dq[n:]).max() / fb.step_mm, 1.0)
    for _ in range(fb.halvings + 1):
        q_new = limits.clip(model, cur.q + dq)
        if np.abs(q_new - cur.q).max() < 1e-9:
            return None
        c = check(model, cur, "correction", [q_new])
        if _safe(c, floor):
            return c
        dq = dq / 2.0
    return None


TURNS_DEG = (90.0, -90.0, 180.0, -180.0, 45.0, -45.0, 135.0, -135.0)
PULLS_MM = (0.0, 6.0)


def _replan(model: Robot, cur: Equilibrium, goal: np.ndarray, cfg: PlanConfig, floor: float
            ) -> Checked | None:
    """A checked route from cur to goal (3,) mm on the model where the local step found none: the
    planner's plan (planning.plan_path: its seeds, routes and detours, its checks), else the branch
    IK seeded with the inner tube turned by each of TURNS_DEG (another relative rotation: the tip
    seen through a tracker may need one far from the plan's), first as it is, then pulled back by
    PULLS_MM (out of the stop of full extension, where the local step ends), the planner's routes
    to its answer checked alike; None if none is safe (snaps are never allowed here)."""
    plan = plan_path(model, cur, goal[None, :], config=replace(cfg, allow_snaps=False))
    if plan.n_reached:
        return check(model, cur, "replanned correction", list(plan.q[1:]))
    limits = cfg.limits(model)
    n = model.n_tubes
    for pull, turn in itertools.product(PULLS_MM, TURNS_DEG):
        q = cur.q.copy()
        q[0] += turn
        q[n] -= pull
        if not limits.holds(q) or not model.is_valid(q[None, :])[0]:
            continue
        seed = solve(model, q, guess=cur.x)
        if not seed.stable:
            continue
        sol = branch_ik(model, seed, goal, limits, None, floor, max_iter=cfg.ik_iterations)
        if sol.error_mm > cfg.tol_mm:
            continue
        for name, waypoints in routes(model, cur.q, sol.q, limits):
            c = check(model, cur, f"correction turned {turn:+.0f} deg, pulled {pull:.0f} mm ({name})",
                      waypoints)
            if _safe(c, floor) and np.linalg.norm(c.tips[-1] - goal) <= cfg.tol_mm:
                return c
    return None


def execute_plan(model: Robot, plan: Plan, targets: np.ndarray, rig: Rig, config: PlanConfig | None = None,
                 feedback: FeedbackConfig | None = None, start: Equilibrium | None = None) -> Executed:
    """Drive plan (made on model, by planning.plan_path with config) through targets (K, 3) mm on rig
    with tracker feedback at every reached target (module docstring). The rig must be at the plan's
    first joints; start: the model's equilibrium there (its branch; default the point-wise solve, as
    plan_path takes start joints)."""
    cfg = config or PlanConfig()
    fb = feedback or FeedbackConfig()
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    k_count = len(targets)
    if len(plan.targets) != k_count:
        raise CtrkinError(f"the plan has {len(plan.targets)} targets, {k_count} were given")
    cur = start if start is not None else solve(model, plan.q[0])
    if not np.allclose(cur.q, plan.q[0]):
        raise CtrkinError("the start equilibrium is not at the plan's first joints")
    rows_q: list[np.ndarray] = []
    rows_m: list[float] = []
    at = np.full(k_count, -1)
    measured = np.full((k_count, 3), np.nan)
    steps = np.zeros(k_count, int)
    refused = np.zeros(k_count, int)
    settled = np.zeros(k_count, bool)
    offset = np.zeros(model.n_joints)       # the last correction, carried to the next target
    i0 = 0
    lost = False

    def drive(c: Checked) -> Equilibrium:
        rig.move(c.q)
        rows_q.extend(c.q)
        rows_m.extend(c.margin)
        return c.equilibria[-1]

    for rep in plan.targets:
        if not rep.reached or lost:
            continue
        k, s = rep.index, rep.step
        floor = min(cfg.min_margin, stability_margin(model, cur))
        seg = list(plan.q[i0 + 1:s + 1])
        leg = None
        shifted = np.array(seg) + offset
        if np.abs(offset).max() > 0 and len(seg) and _inside(model, cfg, shifted):
            leg = check(model, cur, "plan + correction", list(shifted))
            leg = leg if _safe(leg, floor) else None
        if leg is None:     # back along the correction to the plan's joints, then the plan
            back = [plan.q[i0]] if np.abs(offset).max() > 0 else []
            offset = np.zeros(model.n_joints)
            if back + seg:
                leg = check(model, cur, "plan", back + seg)
                if not _safe(leg, floor):
                    break   # the model does not vouch for the way back: stop here (reported)
        if leg is not None:
            cur = drive(leg)
        for _ in range(fb.max_steps + 1):
            m = rig.measure()
            if m is None or not np.isfinite(m).all():
                lost = True
                break
            measured[k] = m
            err = targets[k] - m
            if np.linalg.norm(err) <= fb.tol_mm:
                settled[k] = True
                break
            if steps[k] == fb.max_steps:
                break
            floor = min(cfg.min_margin, stability_margin(model, cur))
            c = _correct(model, cur, err, cfg, fb, floor)
            if c is None:   # no safe local step: the planner's routes to the shifted goal
                c = _replan(model, cur, cur.tip_position + err, cfg, floor)
            if c is None:
                refused[k] += 1
                break
            cur = drive(c)
            steps[k] += 1
        at[k] = len(rows_q) - 1
        offset = cur.q - plan.q[s]
        i0 = s
    q = np.array(rows_q).reshape(-1, model.n_joints)
    return Executed(q, at, measured, steps, refused, settled, np.array(rows_m))
