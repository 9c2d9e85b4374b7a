"""Continuation along a joint trajectory: history-dependent equilibria and snaps.

Each step is warm-started from the previous equilibrium (natural-parameter continuation), moved along
the parabola through the last three states when the joint increment repeats (`Predictor`). A step is
accepted when Newton converges to a stable equilibrium close to the previous one, with a stability
measure that changed continuously; otherwise the joint increment is halved. When even the smallest
sub-step has no stable continuation, the branch has ended at a fold: the robot snaps to another
stable equilibrium, found by a multi-start search around the last state and taken as the nearest
stable one (the basin the released twist falls into).

With friction (Robot.friction > 0) each (sub)step is one step of the rate-independent friction law
from the state of the last accepted one (mechanics.friction): the stuck offsets move only where an
element slips, so the path's history is carried in the state as well as in the branch. An element
switching between stick and slip changes the stiffness of the problem, so det J may jump there
without the branch having ended: its continuity is checked only while the stick/slip pattern holds.
Nor is it checked on a translating (sub)step while an element slips: the element's torsional
tangent in combined slip, T_max r_c² Δd² / (ε (r_c² Δφ² + Δd²)^{3/2}) (contact C4), depends on the
sub-step's own axial slip Δd, so det J changes with the sub-step's length (on the default virtual
robot's arbitrary path by 3× between a sub-step and one twice as long, every element slipping)
and halving the step can never make two of them agree. Such a (sub)step is judged by its
stability (det J > 0, det H > 0) and the twist jump alone.

Newton itself can stall with friction: the residual is piecewise smooth, and a stuck element is a
ramp of slope T_max / ε_t over ε_t ≈ 1e-3 rad of relative twist. Where a path reverses, the
elements that slipped one way sit on the edge of that ramp and unload into it while others slip
the other way; the line search then finds no descent beside a kink, at any sub-step (on three
tubes, 23 elements, the middle and outer tubes turned together: of 25 starts near the last state,
none converge on the whole step or a quarter of it, 2 at 1/16). Newton from the twisted starts of
`recover` reaches the equilibrium from farther away. So when every sub-step down to the smallest
has failed and that search finds the same branch at the smallest one (no fold: no snap), the rest
of the step is taken from the search as well, where it finds a stable equilibrium within a step's
twist (JUMP_RAD); sub-stepping on would need a search per 1/256 of the step and spend the budget.

The common step, a rotation (β kept, so the grid is the previous step's) of a robot without contact
effects whose first try is accepted, runs as one compiled call (`_warm`, mechanics.warm.warm_step:
α, the Newton solve, the acceptance test); any other step, or a first try that is not accepted,
takes the general path below from the start, so the decisions and the snaps are its own. `follow`
goes further: consecutive steps of one kind (rotations or translations, with or without contact
effects) run in one compiled call each (mechanics.compiled_runs), each step what the general
path's first try gives, up to the first that is not accepted, which the general path then takes.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

# sibling modules by full name: `from ctrkin.mechanics import ...` names the package, whose
# lazy table imports this module (an import circle: tests/test_layering.py)
import ctrkin.mechanics.warm as warm
from ctrkin.errors import ConvergenceError, JointError, RobotDescriptionError
from ctrkin.geometry import tip_azimuth, tip_pose
from ctrkin.mechanics.arrays import RobotArrays, robot_arrays
from ctrkin.mechanics.compiled_runs import Steps, run_for
from ctrkin.mechanics.friction import SLIP, FrictionState
from ctrkin.mechanics.pointwise import (
    Equilibrium,
    NewtonResult,
    Problem,
    equilibrium,
    friction_after,
    made,
    newton,
    prepare,
    recover,
    solve,
    twist_distance,
    with_alpha,
    with_state,
)
from ctrkin.mechanics.settings import DEFAULT_SETTINGS, SolverSettings
from ctrkin.robots.robot import Robot

JUMP_RAD = 0.35  # largest accepted twist change per (sub)step, max_i |Δuz_i(0)| · L_i (rad)
SAME_BRANCH_RAD = 0.02  # a state this close (rad of twist) after a failed step is the same branch
# the stability measure det J is continuous along a branch and → 0 at a fold: a (sub)step whose det J
# changes by more than this has left the branch (near-critical folds have a small twist gap)
DET_SLACK, DET_RATE = 0.05, 0.5
MIN_FRACTION = 1.0 / 256  # smallest sub-step, as a fraction of one trajectory step
# largest turn of any α in one sub-step (deg): the end of a longer step can look like its start (a
# whole turn brings the branch back), so a step of 340° or 720° crossed folds unseen (issue 27)
MAX_TURN_DEG = 30.0
PATH_STATES = 3  # states of the previous steps the predictor extrapolates through (a parabola)


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Result of `follow`. tip_poses (T, 6); snaps (T,) bool: a fold was crossed on the way into
    step t; azimuth (T,) deg: T(L), the tip azimuth about z from the outer tube's base rotation
    (unwrapped); stable, converged (T,) bool; equilibria: the T Equilibrium objects (made on first
    access where a compiled run of steps solved them, `Steps`); equilibrium(t): step t's alone (a
    caller that needs a few of them, such as the last, makes only those)."""

    q: np.ndarray
    tip_poses: np.ndarray
    snaps: np.ndarray
    azimuth: np.ndarray
    stable: np.ndarray
    converged: np.ndarray
    _steps: Steps = field(repr=False)

    @functools.cached_property
    def equilibria(self) -> list[Equilibrium]:
        return self._steps.equilibria()

    def equilibrium(self, t: int) -> Equilibrium:
        """Step t's equilibrium (t < 0 counts from the end), the object `equilibria[t]` holds."""
        n = len(self.q)
        if not -n <= t < n:
            raise IndexError(f"step {t} of a trajectory of {n} steps")
        return self._steps.at(t % n)

    @property
    def tip_positions(self) -> np.ndarray:
        return self.tip_poses[:, :3]

    @property
    def tip_tangents(self) -> np.ndarray:
        """(T, 3) unit tip tangents, each step's equilibrium's tip_tangent (without making it)."""
        return self._steps.body[:, 3:6].copy()

    @property
    def n_snaps(self) -> int:
        return int(self.snaps.sum())


@functools.lru_cache(maxsize=256)
def _lagrange(tau: float, k: int) -> np.ndarray:
    """(k,): weights at τ of the polynomial through values at τ = −(k − 1), …, −1, 0 (Lagrange
    basis; cached: the sub-step fractions repeat)."""
    nodes = np.arange(1 - k, 1, dtype=float)
    w = np.array([np.prod([(tau - nodes[m]) / (nodes[j] - nodes[m]) for m in range(k) if m != j])
                  for j in range(k)])
    w.setflags(write=False)
    return w


class Predictor(NamedTuple):
    """The predictor of a continuation step: x(τ) (rad/mm) along the polynomial through the states
    of the last k steps taken with the same joint increment, at τ = −(k − 1), …, −1, 0 (τ in steps).
    Its error one step ahead is O(Δq^k) on a smooth branch: on the paper robot's 1° sweeps the secant
    (k = 2) leaves Newton a median residual of 7e-7 rad/mm at the start, the parabola (k = 3) 1e-8,
    and a start within √(tol / C0) ≈ 3e-7 rad/mm lets the first Newton step be the final pass
    (kernels.newton). xs: (k, N), the latest state last."""

    xs: np.ndarray

    def at(self, tau: float) -> np.ndarray:
        """x(τ) (N,) rad/mm, τ in steps from the latest state (warm.extrapolate: the compiled run
        of steps computes it the same way)."""
        out = np.empty(self.xs.shape[1])
        warm.extrapolate(_lagrange(tau, self.xs.shape[0]), self.xs, out)
        return out


def _repeats(dq: np.ndarray) -> np.ndarray:
    """(T − 2,) bool: joint increment dq[t] (T − 1, 2N) equals dq[t − 1] to 1e-6 of the larger
    component, so that a path built with linspace or a float step, whose increments differ in the
    last bits, is extrapolated too (the predictor's error from such a spacing is ~1e-6 of a step's
    change of x, far below the parabola's own)."""
    scale = np.maximum(np.abs(dq[1:]), np.abs(dq[:-1])).max(axis=1, keepdims=True)
    return (np.abs(dq[1:] - dq[:-1]) <= 1e-6 * scale).all(axis=1)


def _advance(robot: Robot, prev: Equilibrium, q_to: np.ndarray, settings: SolverSettings,
             path: Predictor | None = None, same_grid: bool = False, compiled: bool = True
             ) -> tuple[Equilibrium, bool]:
    """Continue from equilibrium `prev` to joints q_to. Returns (equilibrium, snapped).

    path: the states of the previous steps taken with the same joint increment (`Predictor`);
    Newton then starts from the current state moved along the extrapolated branch instead of from x.
    same_grid: q_to has the translations β of prev.q and prev was solved with these settings, so
    every sub-step keeps prev's grid (`with_alpha`). compiled: try the common step's compiled call
    first (False where follow's compiled run of steps has just tried it: the same try, the same
    outcome).
    """
    if compiled and same_grid and prev.problem.stations is None:  # the common step, one call
        done = _warm(prev, q_to, prev.x if path is None else path.at(1.0), settings)
        if done is not None:
            return done, False
    q_from = prev.q
    arr = prev.problem.arrays
    x = prev.x
    det = prev.stability
    state = prev.friction_state      # friction state of the last accepted (sub)step
    modes = b"" if prev.contact is None else prev.contact.modes
    n = arr.lengths.shape[0]
    # on Python floats: numpy's calls on two or three angles cost 10 µs a step (issue 26)
    turn = max(abs(a - b) for a, b in zip(q_to[:n].tolist(), q_from[:n].tolist(), strict=True))
    translating = not same_grid and q_to[n:].tolist() != q_from[n:].tolist()
    most = 1.0 if turn <= MAX_TURN_DEG else MAX_TURN_DEG / turn    # largest sub-step fraction
    t = 0.0
    dt = most
    snapped = False
    last = None
    work = [0]      # RK4 steps spent on this step, bounded by settings.max_search_steps
    while t < 1.0:
        t_try = min(1.0, t + dt)
        q_try = q_to if t_try == 1.0 else q_from + (q_to - q_from) * t_try
        pb = _problem_at(robot, prev, q_try, settings, same_grid, state)
        if path is None:
            guess = x
        else:  # x moved along the predicted branch (at the start of the step x = path.at(0))
            guess = path.at(t_try) if t == 0.0 else x + path.at(t_try) - path.at(t)
        sol = newton(pb, guess, settings, work)
        if (sol.stable and twist_distance(sol.x, x, pb.arrays.lengths) <= JUMP_RAD
                and (abs(sol.det_j - det) <= DET_SLACK + DET_RATE * det
                     or not _det_comparable(modes, sol.modes, translating))):
            x, det, t, last = sol.x, sol.det_j, t_try, (pb, sol)
            state, modes = _after(pb, sol, state)
            dt = min(2.0 * dt, most)
            continue
        if work[0] > settings.max_search_steps:
            # continuation too costly (an extreme robot): give up this step, reported not converged
            pb = with_state(prepare(robot, q_to, settings, checked=True, arr=arr), state)
            last = (pb, NewtonResult.failed(x, det))
            break
        if path is not None:  # retry from the plain warm start before sub-stepping
            path = None
            continue
        if dt > MIN_FRACTION * most:
            dt *= 0.5
            continue
        # fold: no stable equilibrium near the current one, however small the step
        sol = recover(pb, x, settings, work)
        # a fold was crossed: that is a snap unless the search only re-found the same branch
        same = twist_distance(sol.x, x, pb.arrays.lengths) <= SAME_BRANCH_RAD
        snapped = snapped or not same
        x, det, t, last = sol.x, sol.det_j, t_try, (pb, sol)
        state, modes = _after(pb, sol, state)
        dt = min(1.0 - t, most)
        if same and sol.stable and state is not None and t < 1.0:
            # no fold: Newton stalled beside a stick/slip kink (module docstring), and would at
            # every sub-step: the rest of the step from the search too, where it stays on the branch
            rest = _rest_of_step(robot, prev, q_to, settings, same_grid, x, state, work)
            if rest is not None:
                x, t, last = rest[1].x, 1.0, rest
                state, modes = _after(*rest, state)
    assert last is not None
    return equilibrium(*last, state), snapped


def _warm(prev: Equilibrium, q_to: np.ndarray, guess: np.ndarray, settings: SolverSettings
          ) -> Equilibrium | None:
    """The step from `prev` to q_to (same β, no contact effects) as one compiled call
    (mechanics.warm): the equilibrium if _advance's first try, the whole step from `guess`, is
    accepted, else None (the caller then takes the general path, which repeats that try)."""
    pb0 = prev.problem
    a = pb0.arrays
    n = a.lengths.shape[0]
    alpha, x, body = np.empty(n), np.empty(n), np.empty(7)
    try:
        acc, it, rn, det_j, det_h, _ = warm.warm_step(
            q_to, prev.q, guess, prev.x, prev.stability, a.lengths, pb0.beta, pb0.tips, a.rigid,
            a.k, a.gj, *pb0.grid, settings.tol, settings.max_iter, settings.max_step, MAX_TURN_DEG,
            JUMP_RAD, DET_SLACK, DET_RATE, alpha, x, body)
    except (ZeroDivisionError, OverflowError, FloatingPointError):
        return None  # the general path meets the same and says so
    if not acc:
        return None
    # what with_alpha and pointwise.equilibrium make of it (a converged NewtonResult, no contact)
    pb = made(Problem, arrays=a, q=q_to, alpha=alpha, beta=pb0.beta, tips=pb0.tips, grid=pb0.grid,
               n_rk4=pb0.n_rk4, stations=None, cvar=None, state=None)
    return made(Equilibrium, q=q_to, x=x, tip_position=body[:3], tip_tangent=body[3:6],
                 converged=True, stability=det_j, conjugate=det_h, energy=float(body[6]),
                 residual=rn, iterations=it, problem=pb, contact=None)


def _problem_at(robot: Robot, prev: Equilibrium, q: np.ndarray, settings: SolverSettings,
                same_grid: bool, state: FrictionState | None) -> Problem:
    """The problem at joints q (2N,) of a step from `prev`, with the friction state of the last
    accepted (sub)step: on prev's grid where the step keeps it (`same_grid`, see _advance)."""
    if same_grid:
        return with_alpha(prev.problem, q, state)
    pb = prepare(robot, q, settings, checked=True, arr=prev.problem.arrays)
    return pb if state is None else with_state(pb, state)


def _rest_of_step(robot: Robot, prev: Equilibrium, q_to: np.ndarray, settings: SolverSettings,
                  same_grid: bool, x: np.ndarray, state: FrictionState, work: list[int]
                  ) -> tuple[Problem, NewtonResult] | None:
    """The equilibrium at q_to on the branch of x (N,) rad/mm, found by the multi-start search of
    `recover` from the friction state of the last accepted (sub)step, or None where the nearest
    stable one is farther than a step may twist (JUMP_RAD: a fold, left to the snap search)."""
    pb = _problem_at(robot, prev, q_to, settings, same_grid, state)
    sol = recover(pb, x, settings, work)
    if sol.stable and twist_distance(sol.x, x, pb.arrays.lengths) <= JUMP_RAD:
        return pb, sol
    return None


def _det_comparable(before: bytes, after: bytes, translating: bool) -> bool:
    """Whether det J of two successive (sub)steps measures the same branch: the stick/slip pattern
    (contact modes, bytes of float64; empty without friction) held, and, on a translating step, no
    element slipped (its tangent depends on the sub-step's axial slip, module docstring)."""
    if before != after:
        return False
    return not (translating and bool((np.frombuffer(after, dtype=np.float64) == SLIP).any()))


def _after(pb: Problem, sol: NewtonResult, state: FrictionState | None
           ) -> tuple[FrictionState | None, bytes]:
    """The friction state and stick/slip pattern after an accepted (sub)step (unchanged without
    friction, or where the step did not converge)."""
    if pb.stations is None or sol.stations is None or not sol.converged:
        return state, sol.modes
    return friction_after(pb, sol), sol.modes


def _check_start(robot: Robot, start: Equilibrium) -> None:
    """A start equilibrium must come from this robot (same tubes, same transmission): continuing
    another robot's equilibrium would compute the whole trajectory on that robot."""
    if not isinstance(start, Equilibrium):
        raise TypeError(f"start must be an Equilibrium from solve() or follow(), got {type(start)}")
    if start.x.shape != (robot.n_tubes,):
        raise RobotDescriptionError(
            f"start is an equilibrium of a {start.x.shape[0]}-tube robot; this robot has "
            f"{robot.n_tubes} tubes: solve the start on the same robot")
    if start.problem.arrays is not robot_arrays(robot) and not _same_arrays(
            start.problem.arrays, robot_arrays(robot)):
        raise RobotDescriptionError(
            "start was solved on another robot (tubes or transmission differ): solve the start "
            "on the robot you follow")
    if not start.converged:
        raise ConvergenceError("start is not a converged equilibrium (NaN pose): there is no state "
                               "to continue from; follow without a start or solve it again")


def _same_arrays(a: RobotArrays, b: RobotArrays) -> bool:
    return bool(a.rigid == b.rigid and a.friction == b.friction and a.clearance == b.clearance
                and all(np.array_equal(u, v) for u, v in (
                    (a.k, b.k), (a.gj, b.gj), (a.lengths, b.lengths), (a.sec_len, b.sec_len),
                    (a.sec_kap, b.sec_kap), (a.sec_kapy, b.sec_kapy))))


def follow(robot: Robot, Q: np.ndarray, start: Equilibrium | None = None,
           settings: SolverSettings = DEFAULT_SETTINGS,
           progress: Callable[[int], None] | None = None) -> Trajectory:
    """Follow joint trajectory Q (T, 2N) (deg, mm) by continuation.

    start: the equilibrium the robot is in before Q[0] (continued to Q[0]); without it Q[0] is
    solved point-wise. progress: called with the step index after each step, once per step and in
    order; the steps of a compiled run (consecutive rotation or translating steps, with or without
    contact effects, solved in one call: mechanics.compiled_runs.run_for) are reported one after
    the other when the run returns.
    """
    Qa = robot.check_joints(np.atleast_2d(np.array(Q, dtype=float)))  # a copy: equilibria keep rows
    n_steps = Qa.shape[0]
    if n_steps == 0:
        raise JointError(f"follow needs at least one joint row, got Q of shape {Qa.shape}")
    if start is not None:
        _check_start(robot, start)
    n = robot.n_tubes
    steps = Steps(robot, Qa, settings, PATH_STATES, _weights(PATH_STATES),
                   (MAX_TURN_DEG, JUMP_RAD, DET_SLACK, DET_RATE))
    xs = steps.xs  # eqs[t].x, for the predictor
    snaps = np.zeros(n_steps, dtype=bool)
    if start is None:
        cur = solve(robot, Qa[0], settings=settings)
    else:
        cur, snaps[0] = _advance(robot, start, Qa[0], settings)
    steps.put(0, cur)
    if progress:
        progress(0)
    dq = np.diff(Qa, axis=0)
    same_a = np.r_[False, False, _repeats(dq)]  # step t repeats step t − 1
    rotation_a = np.r_[False, (dq[:, n:] == 0.0).all(axis=1)]  # step t keeps β
    # as Python lists: the loop reads them once a step (numpy's scalars cost more there)
    same, rotation = same_a.tolist(), rotation_a.tolist()
    t = 1
    while t < n_steps:
        # a run of steps in one compiled call, up to one not accepted or of another kind
        run = run_for(cur, rotation[t])
        if run is not None:
            m = run(steps, t, cur, rotation_a, same_a, snaps, settings)
            if m:
                if progress:
                    for i in range(t, t + m):
                        progress(i)
                t += m
                cur = steps.at(t - 1)
                if t == n_steps:
                    break
                if rotation[t] != rotation[t - 1] and run_for(cur, rotation[t]) is not None:
                    continue  # a step of the other kind: its run
        k = 1  # states behind step t on one branch, reached by the joint increment of step t
        while k < PATH_STATES and same[t - k + 1] and not snaps[t - k]:
            k += 1
        path = Predictor(xs[t - k:t]) if k > 1 else None
        # the run has tried step t where it is a rotation step: _advance need not try it again
        cur, snaps[t] = _advance(robot, cur, Qa[t], settings, path, rotation[t], compiled=False)
        steps.put(t, cur)
        if progress:
            progress(t)
        t += 1
    body = steps.body
    poses = tip_pose(body[:, :3].copy(), body[:, 3:6].copy())
    converged, stable = np.ones(n_steps, dtype=bool), np.ones(n_steps, dtype=bool)
    for i, e in enumerate(steps.eqs):  # the steps of the compiled runs are stable equilibria
        if e is not None:
            converged[i], stable[i] = e.converged, e.stable
    return Trajectory(q=Qa, tip_poses=poses, snaps=snaps,
                      azimuth=tip_azimuth(poses[:, :3], Qa[:, n - 1]), stable=stable,
                      converged=converged, _steps=steps)


@functools.lru_cache(maxsize=8)
def _weights(k: int) -> np.ndarray:
    """(k + 1, k): row j ≥ 2, the predictor's Lagrange weights at τ = 1 through j states
    (_lagrange(1, j)); rows 0 and 1 unused."""
    w = np.zeros((k + 1, k))
    for j in range(2, k + 1):
        w[j, :j] = _lagrange(1.0, j)
    w.setflags(write=False)
    return w
