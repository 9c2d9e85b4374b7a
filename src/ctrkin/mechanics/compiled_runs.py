"""follow's steps (mechanics.continuation): those of the general path as made, and the compiled runs
of steps (mechanics.warm's warm_run, friction_run, moving_run and friction_moving_run) with their
outputs kept as arrays, made into Equilibrium objects when they are read (`Steps`).

`run_for` picks the run for a step: consecutive rotation steps without contact effects
(`_warm_run`), with them (`_friction_run`), translating steps without them (`_moving_run`) and with
them (`_friction_moving_run`: a grid and stations each step, the friction state carried per slot
across grids). Each goes on up to the first step that is not accepted or of another kind and
returns the number of steps accepted; follow takes the step after them by the general path
(continuation._advance), whose decisions and snaps are its own: every step a run accepts is, bit
for bit, what _advance's first try (the whole step from the predictor's guess) gives (tested).
The predictor and the acceptance test's bounds are follow's (continuation.PATH_STATES, JUMP_RAD,
...), carried by `Steps`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

# sibling modules by full name: `from ctrkin.mechanics import ...` names the package, whose
# lazy table imports continuation, which imports this module (an import circle: tests/test_layering.py)
import ctrkin.mechanics.warm as warm
from ctrkin.mechanics.arrays import RobotArrays
from ctrkin.mechanics.friction import N_OUT, ContactReport, FrictionState
from ctrkin.mechanics.pointwise import Equilibrium, Problem, made, prepare, rk4_step
from ctrkin.mechanics.settings import SolverSettings
from ctrkin.robots.robot import Robot

__all__ = ["Steps", "run_for"]


class Steps:
    """The equilibria of a `follow`: those of the general path as made (eqs[t]), and those of the
    compiled runs of steps (warm.warm_run and the others) as their output arrays, made into
    Equilibrium objects on first access, field by field what the general path makes of the same
    step (tested): q = Q[t], x = xs[t], α, the body and the statistics; the grid, β and tips of
    base[t], the problem of the step before the run, or, for a translating run's step (moved[t]),
    the problem pointwise.prepare makes at Q[t] (as continuation._problem_at does); with contact
    effects the stations' cvar and outputs and the friction states of the run's rows (runs[t]).
    On the paper robot's sweeps making them took ~2 µs a step, 15 % of the step (issue 26), and
    most callers read only the trajectory's arrays; a translating step's prepare costs ~13 µs more
    (a new grid, and with contact effects its stations)."""

    def __init__(self, robot: Robot, Q: np.ndarray, settings: SolverSettings, path_states: int,
                 weights: np.ndarray, bounds: tuple[float, float, float, float]) -> None:
        T, n = Q.shape[0], robot.n_tubes
        self.robot, self.settings = robot, settings
        # follow's predictor (states, Lagrange weights) and the acceptance test's bounds (max turn
        # deg, twist jump rad, det J slack and rate), as the general path reads them at this call
        self.path_states, self.weights, self.bounds = path_states, weights, bounds
        self.moved = [False] * T  # step t of a translating run: its problem is prepared afresh
        self.Q = Q
        self.eqs: list[Equilibrium | None] = [None] * T
        self.base: list[Problem | None] = [None] * T
        self.xs = np.empty((T, n))
        self.alpha = np.empty((T, n))
        self.body = np.empty((T, 7))
        self.stats = np.empty((T, 3))
        self.counts = np.zeros((T, 2), dtype=np.int64)
        self.done = np.zeros(1, dtype=np.int64)
        # step t's rows of its friction run, if any: its own (_friction_run) or a translating run's
        # in `moving_rows` (_friction_moving_run)
        self.runs: list[_ContactStep | _MovingRun | None] = [None] * T
        self.states: dict[int, FrictionState] = {}   # the friction states made so far
        self.last_run: _ContactRun | None = None
        self.moving_rows: _MovingRows | None = None

    def put(self, t: int, eq: Equilibrium) -> None:
        """Step t solved by the general path."""
        self.eqs[t] = eq
        self.xs[t] = eq.x
        self.body[t, :3] = eq.tip_position
        self.body[t, 3:6] = eq.tip_tangent

    def at(self, t: int) -> Equilibrium:
        eq = self.eqs[t]
        if eq is None:
            pb0 = self.base[t]
            assert pb0 is not None
            q = self.Q[t]
            if self.moved[t]:  # _problem_at's prepare, the grid warm.moving_run built
                pb = prepare(self.robot, q, self.settings, checked=True, arr=pb0.arrays)
            else:
                pb = made(Problem, arrays=pb0.arrays, q=q, alpha=self.alpha[t], beta=pb0.beta,
                          tips=pb0.tips, grid=pb0.grid, n_rk4=pb0.n_rk4, stations=None,
                          cvar=None, state=None)
            contact = None
            run = self._contact(t)
            if run is not None:  # what _problem_at, _after and pointwise.equilibrium make
                # a translating run's step: the stations of its own grid, which prepare built
                stations = pb.stations if self.moved[t] else pb0.stations
                assert stations is not None
                pb.__dict__.update(stations=stations, cvar=run.cvar,
                                   state=run.first if t == run.start else self.state(t - 1))
                contact = ContactReport(stations, run.cout, self.state(t))
            body, st = self.body[t], self.stats[t].tolist()
            eq = made(Equilibrium, q=q, x=self.xs[t], tip_position=body[:3],
                      tip_tangent=body[3:6], converged=True, stability=st[1], conjugate=st[2],
                      energy=float(body[6]), residual=st[0], iterations=int(self.counts[t, 0]),
                      problem=pb, contact=contact)
            self.eqs[t] = eq
        return eq

    def state(self, t: int) -> FrictionState:
        """The friction state after step t of a friction run (one object per step)."""
        out = self.states.get(t)
        if out is None:
            run = self.runs[t]
            assert run is not None
            theta = run.rows.theta[t] if isinstance(run, _MovingRun) else run.theta
            out = self.states[t] = FrictionState(theta, self.Q[t])
        return out

    def _contact(self, t: int) -> _ContactStep | None:
        """Step t's rows of its friction run, if any (a translating run's: its K stations')."""
        run = self.runs[t]
        if isinstance(run, _MovingRun):
            rows, k = run.rows, int(run.rows.n_stations[t])
            return _ContactStep(rows.theta[t], rows.cvar[t, :k + self.robot.n_tubes - 1],
                                rows.cout[t, :k], run.start, run.first)
        return run

    def equilibria(self) -> list[Equilibrium]:
        return [self.at(t) for t in range(len(self.eqs))]



_Run = Callable[["Steps", int, Equilibrium, np.ndarray, np.ndarray, np.ndarray, SolverSettings],
               int]


def run_for(prev: Equilibrium, rotation: bool) -> _Run | None:
    """The compiled run for a step from prev: rotation steps without contact effects (_warm_run)
    or with them (_friction_run), translating steps without them (_moving_run) or with them
    (_friction_moving_run); those with contact effects from a converged equilibrium (its friction
    state). None: the general path."""
    if prev.problem.stations is None:
        return _warm_run if rotation else _moving_run
    if prev.contact is None:
        return None
    return _friction_run if rotation else _friction_moving_run


def _moving_run(steps: Steps, t: int, prev: Equilibrium, rotation: np.ndarray, same: np.ndarray,
                snaps: np.ndarray, settings: SolverSettings) -> int:
    """_warm_run for translating steps (warm.moving_run: a grid of its own every step)."""
    a = prev.problem.arrays
    try:
        m = warm.moving_run(
            steps.Q, t, rotation, same, snaps, steps.xs, prev.stability, steps.weights,
            steps.path_states, a.lengths, a.extra, a.sec_len, a.sec_kap, a.sec_kapy, a.n_sec,
            rk4_step(a, settings), settings.max_rk4_steps, a.rigid, a.k, a.gj, settings.tol,
            settings.max_iter, settings.max_step, *steps.bounds, steps.alpha, steps.body, steps.stats,
            steps.counts, steps.done)
    except (ZeroDivisionError, OverflowError, FloatingPointError):
        m = int(steps.done[0])
    steps.base[t:t + m] = [prev.problem] * m
    steps.moved[t:t + m] = [True] * m
    return m


def _warm_run(steps: Steps, t: int, prev: Equilibrium, rotation: np.ndarray, same: np.ndarray,
              snaps: np.ndarray, settings: SolverSettings) -> int:
    """Steps t, t + 1, … from `prev` (step t − 1, no contact effects) as one compiled call
    (warm.warm_run): each the compiled step of _advance (`_warm`), with follow's predictor, up to
    the first that is not a rotation or not accepted. Returns the number of steps accepted; their
    outputs are in `steps`, their equilibria made when read (Steps.at)."""
    pb0 = prev.problem
    a = pb0.arrays
    try:
        m = warm.warm_run(
            steps.Q, t, rotation, same, snaps, steps.xs, prev.stability, steps.weights,
            steps.path_states, a.lengths, pb0.beta, pb0.tips, a.rigid, a.k, a.gj, *pb0.grid,
            settings.tol, settings.max_iter, settings.max_step, *steps.bounds, steps.alpha, steps.body,
            steps.stats, steps.counts, steps.done)
    except (ZeroDivisionError, OverflowError, FloatingPointError):
        m = int(steps.done[0])  # the general path meets the same at the next step and says so
    steps.base[t:t + m] = [pb0] * m
    return m


class _ContactRun(NamedTuple):
    """The arrays of follow's friction runs on one grid's stations (warm.friction_run), rows by step
    (runs on stations of the same count share them: their steps differ): theta (T, P · slots) the
    state after each step, cvar (T, K + P), cout (T, K, 8); start and first: the run's first step
    and the friction state it started from."""

    theta: np.ndarray
    cvar: np.ndarray
    cout: np.ndarray
    start: int
    first: FrictionState


class _ContactStep(NamedTuple):
    """One accepted step of a friction run: its rows of the run's arrays (theta (P · slots,) the state
    after it, cvar (K + P,), cout (K, 8)), the run's first step and the friction state it started from."""

    theta: np.ndarray
    cvar: np.ndarray
    cout: np.ndarray
    start: int
    first: FrictionState


def _friction_run(steps: Steps, t: int, prev: Equilibrium, rotation: np.ndarray,
                  same: np.ndarray, snaps: np.ndarray, settings: SolverSettings) -> int:
    """_warm_run on a robot with contact effects (warm.friction_run), from prev's friction state."""
    pb0 = prev.problem
    a = pb0.arrays
    st = pb0.stations
    assert st is not None and prev.contact is not None
    first = prev.contact.state
    T = steps.Q.shape[0]
    last = steps.last_run
    if last is not None and last.cout.shape[1] == st.count:
        run = _ContactRun(last.theta, last.cvar, last.cout, t, first)
    else:
        run = _ContactRun(np.empty((T, first.theta.shape[0])), np.empty((T, st.relaxed.shape[0])),
                          np.empty((T, st.count, N_OUT)), t, first)
    run.theta[t - 1] = first.theta
    try:
        m = warm.friction_run(
            steps.Q, t, rotation, same, snaps, steps.xs, prev.stability, steps.weights,
            steps.path_states, a.lengths, pb0.beta, pb0.tips, a.rigid, a.k, a.gj, *pb0.grid,
            settings.tol, settings.max_iter, settings.max_step, *steps.bounds, st.table, st.pairs,
            st.prm, st.slot, first.q, prev.contact.out[:, 3], run.theta, run.cvar, run.cout,
            steps.alpha, steps.body, steps.stats, steps.counts, steps.done)
    except (ZeroDivisionError, OverflowError, FloatingPointError):
        m = int(steps.done[0])
    steps.base[t:t + m] = [pb0] * m
    # each accepted step keeps its own rows: the run's (T, …) arrays are not held by the steps (a
    # path whose grid changes often would otherwise keep one such set per run: O(T²) memory)
    steps.runs[t:t + m] = [_ContactStep(run.theta[i].copy(), run.cvar[i].copy(), run.cout[i].copy(), t, first)
                           for i in range(t, t + m)]
    steps.last_run = run
    return m


class _MovingRows(NamedTuple):
    """The arrays of follow's translating friction runs (warm.friction_moving_run), one set a
    follow, rows by step: theta (T, P · slots) the state after each step, cvar (T, K_max + P),
    cout (T, K_max, 8) and n_stations (T,): step t's K = n_stations[t] stations are
    cvar[t, :K + P] and cout[t, :K]. The station count changes with the grid, so a row holds the
    most stations a grid of this robot can have (K_max, `_max_stations`). Every run writes its own
    steps' rows in place and no step copies its rows out: O(T K_max) memory for the whole follow
    (~1 kB a step on two tubes of five sections), one set however many runs the path breaks into
    (one set a run would be O(T²)), and nothing made per step until a step is read (Steps.at)."""

    theta: np.ndarray
    cvar: np.ndarray
    cout: np.ndarray
    n_stations: np.ndarray


class _MovingRun(NamedTuple):
    """The steps of one translating friction run: the follow's rows, the run's first step and the
    friction state it started from."""

    rows: _MovingRows
    start: int
    first: FrictionState


def _max_stations(a: RobotArrays) -> int:
    """The most friction stations a grid of this robot can have (contact.build_stations: at most
    one a pair at each breakpoint; a grid has at most 2 + Σ n_sec of them: the front plate, the
    section ends, the end)."""
    return (2 + int(a.n_sec.sum())) * max(a.k.shape[0] - 1, 1)


def _friction_moving_run(steps: Steps, t: int, prev: Equilibrium, rotation: np.ndarray,
                         same: np.ndarray, snaps: np.ndarray, settings: SolverSettings) -> int:
    """_moving_run on a robot with contact effects (warm.friction_moving_run), from prev's friction
    state: each step's stations on its own grid, made again when the step is read (Steps.at:
    _problem_at's prepare, with the run's cvar and the state before the step)."""
    pb0 = prev.problem
    a = pb0.arrays
    st = pb0.stations
    assert st is not None and prev.contact is not None
    first = prev.contact.state
    rows = steps.moving_rows
    if rows is None:
        T, k_max = steps.Q.shape[0], _max_stations(a)
        rows = steps.moving_rows = _MovingRows(
            np.empty((T, first.theta.shape[0])), np.empty((T, k_max + st.pairs.shape[0])),
            np.empty((T, k_max, N_OUT)), np.zeros(T, dtype=np.int64))
    rows.theta[t - 1] = first.theta
    try:
        m = warm.friction_moving_run(
            steps.Q, t, rotation, same, snaps, steps.xs, prev.stability, steps.weights,
            steps.path_states, a.lengths, a.extra, a.sec_len, a.sec_kap, a.sec_kapy, a.n_sec,
            rk4_step(a, settings), settings.max_rk4_steps, a.rigid, a.k, a.gj, settings.tol,
            settings.max_iter, settings.max_step, *steps.bounds, a.slots, st.pairs, st.prm, first.q,
            prev.contact.out[:, 3], rows.theta, rows.cvar, rows.cout, rows.n_stations,
            steps.alpha, steps.body, steps.stats, steps.counts, steps.done)
    except (ZeroDivisionError, OverflowError, FloatingPointError):
        m = int(steps.done[0])
    steps.base[t:t + m] = [pb0] * m
    steps.moved[t:t + m] = [True] * m
    steps.runs[t:t + m] = [_MovingRun(rows, t, first)] * m
    return m
