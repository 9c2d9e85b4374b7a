"""The snap-safe planner: a joint trajectory through tip targets that never snaps unless asked.

For each target in turn, from the equilibrium the robot is in (its joints and its branch):

1. IK on the current branch (planning.ik): damped least squares on the mechanics, Newton warm-started
   along the branch, candidates below the stability margin rejected; seeds: the current joints, and
   the current joints turned as a whole so that the tip's azimuth about z faces the target (turning
   every tube together turns the robot rigidly, on the same branch). If neither leads to a safe
   route, the joints of the history-free IK (planning.naive's, on least-energy equilibria) are
   tried as a goal too: the routes to them are checked on the robot's branch like any other.
2. Routes to the IK's joints (planning.paths): direct, the other way round, detours through low curved
   overlap; each followed on the mechanics from the current equilibrium. A route is safe when it
   crosses no fold, keeps the margin ≥ PlanConfig.min_margin at every step (≥ the margin of the
   robot's state before the move, where that is lower: a plan may lead out of a low margin, never
   further in) and ends within
   PlanConfig.tol_mm of the target; the safe route of least joint motion is taken.
3. If none is safe: the target is reported unreachable on the current branch, the robot stays, and a
   deliberate snap is offered (SnapOffer: turning the inner tube at the current translations until
   its branch ends, where, the predicted tip jump, and whether the target is reachable from the branch
   it lands on). With PlanConfig.allow_snaps the planner takes that snap (flagged as planned).

Guarantees, on the robot it is given (nominal or calibrated mechanics): every step of the plan was
followed by continuation (≤ 5°, ≤ 1 mm steps, sub-stepped at folds), so no unflagged snap lies on it
for that robot; joints stay within the limits and the robot's valid set; every reached target is
within tol_mm on it. Not guaranteed: the same on a robot that differs from the model (friction,
backlash, tube errors: the margin is the cushion against those), global optimality of joint motion,
finding a reachable target whose only solutions lie on another branch not reached by the offered
snap.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ctrkin.errors import CtrkinError
from ctrkin.mechanics.continuation import follow
from ctrkin.mechanics.pointwise import Equilibrium, solve
from ctrkin.planning.ik import BranchSolution, Limits, branch_ik
from ctrkin.planning.learned import LearnedRoute, LearnedSnapModel
from ctrkin.planning.margin import stability_margin
from ctrkin.planning.paths import Checked, check, densify, routes
from ctrkin.robots.robot import Robot


@dataclass(frozen=True)
class PlanConfig:
    """Settings of the planner.

    tol_mm: a target counts as reached within this tip distance (mm); min_margin: the least
    stability margin (planning.margin: 1 at aligned tubes, 0 at a fold) allowed at any step;
    alpha_limits_deg: (lo, hi) of every α (deg); beta_limits_mm: (lo, hi) of every β (mm), within the
    robot's own valid set; allow_snaps: take the offered deliberate snap when a target is not
    reachable on the current branch; ik_iterations: the IK's iteration budget per seed;
    learned_min_deg: with a learned snap model (planning.learned), the least inner-tube rotation (deg)
    left before the model predicts a snap, at any step (one route step, 5°, by default).
    """

    tol_mm: float = 1.0
    min_margin: float = 0.25
    alpha_limits_deg: tuple[float, float] = (-720.0, 720.0)
    beta_limits_mm: tuple[float, float] = (-math.inf, 0.0)
    allow_snaps: bool = False
    ik_iterations: int = 60
    learned_min_deg: float = 5.0

    def __post_init__(self) -> None:
        if not self.tol_mm > 0:
            raise CtrkinError(f"PlanConfig.tol_mm must be > 0 mm, got {self.tol_mm}")
        if not 0.0 <= self.min_margin < 1.0:
            raise CtrkinError(f"PlanConfig.min_margin must be in [0, 1), got {self.min_margin}")
        for name in ("alpha_limits_deg", "beta_limits_mm"):
            lo, hi = getattr(self, name)
            if not lo < hi:
                raise CtrkinError(f"PlanConfig.{name} must be (lo, hi) with lo < hi, got {(lo, hi)}")
        if not 0.0 <= self.learned_min_deg < 180.0:
            raise CtrkinError(f"PlanConfig.learned_min_deg must be in [0, 180) deg, got "
                              f"{self.learned_min_deg}")
        if self.ik_iterations < 1:
            raise CtrkinError(f"PlanConfig.ik_iterations must be >= 1, got {self.ik_iterations}")

    def limits(self, robot: Robot) -> Limits:
        n = robot.n_tubes
        a, b = self.alpha_limits_deg, self.beta_limits_mm
        return Limits(np.r_[np.full(n, a[0]), np.full(n, b[0])], np.r_[np.full(n, a[1]), np.full(n, b[1])])


@dataclass(frozen=True)
class SnapOffer:
    """A deliberate snap: turning α1 from the current joints towards `direction` (+1 or −1) the
    branch ends at joints q (2N,); the tip jumps jump_mm; reachable: the target is within tol_mm of
    the IK on the branch it lands on (landing_q (2N,) those joints, NaN if not)."""

    direction: int
    q: np.ndarray
    jump_mm: float
    reachable: bool
    landing_q: np.ndarray

    def describe(self) -> str:
        where = ", ".join(f"{v:.2f}" for v in self.q)
        out = (f"snap turning alpha_1 {'+' if self.direction > 0 else '-'} at q = ({where}): "
               f"the tip jumps {self.jump_mm:.2f} mm")
        return out + ("; the target is reachable after it" if self.reachable else
                      "; the target is not reachable after it either")


@dataclass(frozen=True)
class TargetReport:
    """One target: reached (within tol on the planned robot), error_mm, route (its name, "" if not
    reached), steps (index of its last step in the plan, −1 if not reached), min_margin along its
    route, planning time (s), offer (a SnapOffer if it is not reachable on the branch), snapped (the
    plan took the offered snap)."""

    index: int
    reached: bool
    error_mm: float
    route: str
    step: int
    min_margin: float
    seconds: float
    offer: SnapOffer | None = None
    snapped: bool = False


@dataclass
class Plan:
    """The plan: q (T, 2N) joints of every step (row 0 the start), tips (T, 3) mm predicted,
    margin (T,), snap (T,) bool (only where allowed: planned), target (T,) int (the target reached at
    this step, −1 between), route (T,) str; targets: one TargetReport each; learned: the learned snap
    model along the plan (planning.learned: state, predicted snaps, jumps, margin in deg per step),
    None without one."""

    q: np.ndarray
    tips: np.ndarray
    margin: np.ndarray
    snap: np.ndarray
    target: np.ndarray
    route: list[str]
    targets: list[TargetReport] = field(default_factory=list)
    learned: LearnedRoute | None = None

    @property
    def n_reached(self) -> int:
        return sum(t.reached for t in self.targets)


def _seeds(robot: Robot, cur: Equilibrium, target: np.ndarray, limits: Limits) -> list[Equilibrium]:
    """The current equilibrium, and the robot turned as a whole to face the target's azimuth."""
    n = robot.n_tubes
    out = [cur]
    if np.hypot(*target[:2]) > 1e-6 and np.hypot(*cur.tip_position[:2]) > 1e-6:
        turn = float(np.degrees(np.arctan2(target[1], target[0])
                                - np.arctan2(cur.tip_position[1], cur.tip_position[0])))
        turn = (turn + 180.0) % 360.0 - 180.0
        q = cur.q.copy()
        q[:n] += turn
        if abs(turn) > 1.0 and limits.holds(q):
            eq = solve(robot, q, guess=cur.x)   # a rigid turn: the same state on the same branch
            if eq.stable:
                out.append(eq)
    return out


def _safe(c: Checked, target: np.ndarray, cfg: PlanConfig, floor: float) -> bool:
    return bool(not c.snaps.any() and c.margin.min() >= floor
                and np.linalg.norm(c.tips[-1] - target) <= cfg.tol_mm)


def _best_route(robot: Robot, cur: Equilibrium, sol: BranchSolution, target: np.ndarray,
                cfg: PlanConfig, limits: Limits, floor: float,
                learned: tuple[LearnedSnapModel, float] | None = None
                ) -> tuple[Checked, LearnedRoute | None] | None:
    """The safe route of least joint motion to sol.q, None if none is safe; with a learned snap model
    (and its floor, deg) also safe on it: no predicted snap (unless allowed), its margin ≥ the floor,
    and within what it knows (a route it refuses to step along, e.g. beyond its trained α range, is
    rejected: it cannot vouch for it)."""
    cands = routes(robot, cur.q, sol.q, limits)
    cands.sort(key=lambda r: _motion([cur.q, *r[1]], robot.n_tubes))
    for name, waypoints in cands:       # sorted by motion: the first safe one is the best
        c = check(robot, cur, name, waypoints)
        if not _safe(c, target, cfg, floor):
            continue
        if learned is None:
            return c, None
        model, lfloor = learned
        lr = model.stream(c.q)
        if not lr.refused and (cfg.allow_snaps or not lr.snap.any()) and lr.margin_deg.min() >= lfloor:
            return c, lr
    return None


def _motion(waypoints: list[np.ndarray], n: int) -> float:
    q = np.array(waypoints)
    d = np.abs(np.diff(q, axis=0))
    return float(d[:, :n].sum() / 30.0 + d[:, n:].sum())


def snap_offer(robot: Robot, cur: Equilibrium, target: np.ndarray, cfg: PlanConfig,
               limits: Limits, tangent: np.ndarray | None = None) -> SnapOffer | None:
    """The deliberate snap nearest in rotation: α1 turned up to a whole turn each way at the current
    translations; None if the branch does not end there (the pair is not bistable at these β)."""
    offers = []
    for direction in (1, -1):
        end = cur.q.copy()
        end[0] += direction * 360.0
        end = np.clip(end, limits.lo, limits.hi)
        if end[0] == cur.q[0]:
            continue
        q = densify([cur.q, end])
        traj = follow(robot, q, start=cur)
        if not traj.snaps.any():
            continue
        i = int(np.argmax(traj.snaps))
        before = traj.tip_positions[i - 1] if i > 0 else cur.tip_position
        landed = traj.equilibrium(i)
        sol = branch_ik(robot, landed, target, limits, tangent, cfg.min_margin,
                        max_iter=cfg.ik_iterations)
        ok = sol.error_mm <= cfg.tol_mm
        offers.append(SnapOffer(direction, q[i], float(np.linalg.norm(traj.tip_positions[i] - before)),
                                ok, sol.q if ok else np.full(robot.n_joints, np.nan)))
    if not offers:
        return None
    return min(offers, key=lambda o: (not o.reachable, abs(o.q[0] - cur.q[0])))


def plan_path(robot: Robot, start: np.ndarray | Equilibrium, targets: np.ndarray,
              tangents: np.ndarray | None = None, config: PlanConfig | None = None,
              learned: LearnedSnapModel | None = None) -> Plan:
    """Plan a joint trajectory through tip targets on robot's mechanics.

    start: the current joints (2N,) (deg, mm), solved point-wise, or the Equilibrium the robot is in
    (its branch); targets (K, 3) mm in the robot base frame; tangents (K, 3) unit tip tangents
    or None (positions only); config: PlanConfig; learned: a learned snap model (planning.learned)
    streamed along every route from the robot's state (started at the start joints unless its
    `start` was called with the robot's history): a route on which it predicts a snap is rejected
    (unless snaps are allowed), and so is one where its margin falls below learned_min_deg (or the
    start's, where lower). Returns a Plan (module docstring).
    """
    cfg = config or PlanConfig()
    limits = cfg.limits(robot)
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    if targets.shape[1:] != (3,) or not np.isfinite(targets).all():
        raise CtrkinError(f"targets must be finite (K, 3) tip positions (mm), got shape {targets.shape}")
    if tangents is not None:
        tangents = np.atleast_2d(np.asarray(tangents, dtype=float))
        if tangents.shape != targets.shape or not np.allclose(np.linalg.norm(tangents, axis=1), 1, atol=1e-3):
            raise CtrkinError("tangents must be unit vectors (K, 3), one per target")
    if isinstance(start, Equilibrium):
        cur = start
    else:
        q0 = robot.check_joints(np.asarray(start, dtype=float))
        if not limits.holds(q0):
            raise CtrkinError(f"start joints {q0.tolist()} lie outside the planner's limits "
                              f"(alpha {cfg.alpha_limits_deg} deg, beta {cfg.beta_limits_mm} mm)")
        cur = solve(robot, q0)
    if not cur.stable:
        raise CtrkinError("the start is not a stable equilibrium: there is no branch to plan from")
    lroutes: list[LearnedRoute] = []
    if learned is not None:
        if not learned.history:
            learned.start(cur.q)
        elif not np.allclose(learned.history[-1], cur.q):
            raise CtrkinError("the learned snap model's history does not end at the start joints: call "
                              "its start(q0, history) with the robot's joints and the way it came")
        lroutes.append(learned.here)
    rows_q, rows_tip = [cur.q], [cur.tip_position]
    rows_m, rows_snap, rows_t, rows_r = [stability_margin(robot, cur)], [False], [-1], ["start"]
    reports = []
    for k, target in enumerate(targets):
        t0 = time.perf_counter()
        tan = None if tangents is None else tangents[k]
        best: tuple[Checked, LearnedRoute | None] | None = None
        closest = math.inf
        # a start below the threshold may not get worse, so that the plan can lead out of it
        floor = min(cfg.min_margin, rows_m[-1])
        lfloor = None if learned is None else (learned, min(cfg.learned_min_deg,
                                                            float(lroutes[-1].margin_deg[-1])))
        for seed in _seeds(robot, cur, target, limits):
            sol = branch_ik(robot, seed, target, limits, tan, floor, max_iter=cfg.ik_iterations)
            closest = min(closest, sol.error_mm)
            if sol.error_mm <= cfg.tol_mm:
                best = _best_route(robot, cur, sol, target, cfg, limits, floor, lfloor)
                if best is not None:
                    break
        if best is None:    # the history-free IK's joints, reached by a route checked on the branch
            sol = branch_ik(robot, solve(robot, cur.q), target, limits, tan, 0.0,
                            max_iter=cfg.ik_iterations, history=False)
            if sol.error_mm <= cfg.tol_mm:
                best = _best_route(robot, cur, sol, target, cfg, limits, floor, lfloor)
        offer = None
        snapped = False
        if best is None:
            offer = snap_offer(robot, cur, target, cfg, limits, tan)
            if cfg.allow_snaps and offer is not None and offer.reachable:
                snap_route = check(robot, cur, "planned snap", [offer.q, offer.landing_q])
                if np.linalg.norm(snap_route.tips[-1] - target) <= cfg.tol_mm:
                    best = snap_route, None if learned is None else learned.stream(snap_route.q)
                    snapped = True
        if best is None:
            reports.append(TargetReport(k, False, closest, "", -1, math.nan,
                                        time.perf_counter() - t0, offer))
            continue
        chosen, lr = best
        if learned is not None and lr is not None:
            learned.accept(chosen.q, lr)
            lroutes.append(lr)
        rows_q += list(chosen.q)
        rows_tip += list(chosen.tips)
        rows_m += list(chosen.margin)
        rows_snap += list(chosen.snaps)
        rows_t += [-1] * (len(chosen.q) - 1) + [k]
        rows_r += [chosen.name] * len(chosen.q)
        cur = chosen.equilibria[-1]
        reports.append(TargetReport(k, True, float(np.linalg.norm(chosen.tips[-1] - target)), chosen.name,
                                    len(rows_q) - 1, float(chosen.margin.min()),
                                    time.perf_counter() - t0, offer, snapped))
    joined = None
    if lroutes:
        state, snap, jump, margin = (np.concatenate([getattr(r, f) for r in lroutes])
                                     for f in ("state", "snap", "jump_mm", "margin_deg"))
        joined = LearnedRoute(state, snap, jump, margin)
    return Plan(np.array(rows_q), np.array(rows_tip), np.array(rows_m), np.array(rows_snap),
                np.array(rows_t), rows_r, reports, joined)

