"""Continuation: history, hysteresis and snaps on the paper robot."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ctrkin import Robot, SolverSettings, Tube, follow, paper_robot, solve
from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.errors import ConvergenceError, JointError, RobotDescriptionError
from ctrkin.mechanics import continuation, kernels, warm
from ctrkin.mechanics.continuation import Predictor
from ctrkin.mechanics.pointwise import Equilibrium, equilibrium, newton, prepare, with_alpha
from ctrkin.robots import timclab_robot

ROBOT = paper_robot()


def test_low_overlap_sweep_has_no_snap_and_no_hysteresis() -> None:
    Q = rotation_sweep(2, relative_translation=4.0)
    traj = follow(ROBOT, Q)
    assert traj.n_snaps == 0 and traj.stable.all() and traj.converged.all()
    np.testing.assert_allclose(traj.tip_positions[:361], traj.tip_positions[360:][::-1], atol=1e-8)
    assert np.abs(np.diff(traj.azimuth)).max() < 10.0


def test_full_overlap_sweep_snaps_once_each_way() -> None:
    Q = rotation_sweep(2, relative_translation=20.0)
    traj = follow(ROBOT, Q)
    idx = np.nonzero(traj.snaps)[0]
    assert len(idx) == 2 and idx[0] < 361 <= idx[1]
    jumps = np.linalg.norm(np.diff(traj.tip_positions, axis=0), axis=1)
    assert jumps[idx - 1].min() > 2.0  # mm: the released twist throws the tip ...
    assert jumps[idx - 1].min() > 20 * np.median(jumps)  # ... far more than a 1° step moves it
    fwd, bwd = traj.azimuth[:361], traj.azimuth[360:][::-1]
    assert np.abs(fwd - bwd).max() > 30.0  # deg of T(L): a wide hysteresis loop


def test_hysteresis_grows_with_overlap() -> None:
    widths = []
    for d in (12.0, 16.0, 20.0):
        traj = follow(ROBOT, rotation_sweep(2, d))
        widths.append(np.abs(traj.azimuth[:361] - traj.azimuth[360:][::-1]).max())
    assert widths[0] < 1.0 < widths[1] < widths[2]


def test_start_equilibrium_carries_history() -> None:
    """The same joints reached from two directions give two different stable equilibria."""
    fwd = follow(ROBOT, rotation_sweep(2, 20.0)[:191])  # 0° → 190°, before the forward snap
    back_q = np.array([[a, 0.0, -20.0, 0.0] for a in np.arange(360.0, 189.0, -1.0)])
    start = solve(ROBOT, [360.0, 0.0, -20.0, 0.0])
    back = follow(ROBOT, back_q, start=start)
    a, b = fwd.equilibria[-1], back.equilibria[-1]
    np.testing.assert_allclose(a.q, b.q)
    assert a.stable and b.stable
    assert np.linalg.norm(a.tip_position - b.tip_position) > 3.0


def test_follow_matches_pointwise_on_a_unique_branch() -> None:
    Q = rotation_sweep(2, 8.0, step_deg=10.0)
    traj = follow(ROBOT, Q)
    for q, eq in zip(Q[::7], traj.equilibria[::7], strict=True):
        np.testing.assert_allclose(eq.tip_pose, solve(ROBOT, q).tip_pose, atol=1e-9)


def test_coarse_steps_still_find_the_fold() -> None:
    """Sub-stepping resolves the fold even with 10° steps."""
    traj = follow(ROBOT, rotation_sweep(2, 20.0, step_deg=10.0))
    assert traj.n_snaps == 2


def test_progress_callback_sees_every_step() -> None:
    seen: list[int] = []
    Q = rotation_sweep(2, 8.0, step_deg=30.0)
    follow(ROBOT, Q, progress=seen.append)
    assert seen == list(range(len(Q)))


def test_rigid_transmission_paper_robot_snaps_less_easily() -> None:
    """Without transmission compliance only the exposed straight parts (s ∈ [0, 37] mm) twist, so
    b ≈ 37–41 mm instead of ≈ 55 mm: at d = 16 (L = 10.5) λ tan λ = 0.25 < L/b ≈ 0.26, no snap; at
    d = 20 (L = 14.5) λ tan λ = 0.51 > L/b = 0.39, a snap. The compliant robot snaps at both."""
    rigid = paper_robot("rigid")
    n_snaps = [follow(rigid, rotation_sweep(2, d)).n_snaps for d in (16.0, 20.0)]
    assert n_snaps == [0, 2]
    assert follow(ROBOT, rotation_sweep(2, 16.0)).n_snaps == 2


@pytest.mark.parametrize("d", [4.0, 20.0])
def test_trajectory_arrays_are_consistent(d: float) -> None:
    Q = rotation_sweep(2, d, step_deg=5.0)
    traj = follow(ROBOT, Q)
    T = len(Q)
    assert traj.tip_poses.shape == (T, 6) and traj.snaps.shape == (T,) and traj.azimuth.shape == (T,)
    np.testing.assert_allclose(np.linalg.norm(traj.tip_poses[:, 3:], axis=1), 1.0)
    assert len(traj.equilibria) == T


def test_one_equilibrium_and_the_tangents_are_the_equilibria_s() -> None:
    """Trajectory.equilibrium(t) and tip_tangents read a step without making the others (the
    compiled runs' steps are made on access): the same objects and numbers as `equilibria`."""
    Q = rotation_sweep(2, 20.0, step_deg=5.0)
    fresh = follow(dataclasses.replace(ROBOT, friction=0.2), Q)
    last = fresh.equilibrium(-1)
    assert fresh._steps.eqs.count(None) > 0        # the other compiled steps are still not made
    np.testing.assert_array_equal(fresh.tip_tangents, [e.tip_tangent for e in fresh.equilibria])
    assert last is fresh.equilibria[-1] and fresh.equilibrium(3) is fresh.equilibria[3]
    with pytest.raises(IndexError):
        fresh.equilibrium(len(Q))


# --- issue 9 item 3: a start from another robot, an empty Q ----------------------------------

def _other_robot(n_tubes: int = 2) -> Robot:
    tubes = [Tube(0.4, 0.2, 57.0, 15.0, 1 / 20.0), Tube(0.635, 0.48, 37.0, 14.5, 1 / 24.0),
             Tube(1.0, 0.8, 20.0, 10.0, 0.0)]
    return Robot(tuple(tubes[:n_tubes]))


def test_follow_refuses_start_from_another_robot() -> None:
    """Was: the whole trajectory computed on the start's robot, 4.3 mm off, every step stable."""
    q = np.array([0.0, 0.0, -20.0, -5.0])
    with pytest.raises(RobotDescriptionError, match="another robot"):
        follow(ROBOT, q[None], start=solve(_other_robot(), q))
    with pytest.raises(RobotDescriptionError, match="3-tube robot"):
        follow(ROBOT, q[None], start=solve(_other_robot(3), [0, 0, 0, -20.0, -10.0, -5.0]))
    # an equal robot built again (another object, same description) is the same robot
    same = solve(paper_robot(), q)
    np.testing.assert_allclose(follow(ROBOT, q[None], start=same).tip_poses[0], same.tip_pose,
                               atol=1e-9)


def test_follow_refuses_empty_trajectory_and_failed_start() -> None:
    with pytest.raises(JointError, match="at least one joint row"):
        follow(ROBOT, np.zeros((0, 4)))
    failed = solve(ROBOT, [90.0, 0.0, -20.0, -5.0], settings=SolverSettings(max_iter=1, tol=1e-30))
    assert not failed.converged
    with pytest.raises(ConvergenceError, match="not a converged"):
        follow(ROBOT, [[0.0, 0.0, -20.0, -5.0]], start=failed)


def test_follow_step_work_is_bounded_and_reported():
    """Found by benchmarks/fuzz.py: follow on an extreme robot (κ = 10/mm over 100 mm) ran for minutes.
    A step whose continuation needs more than SolverSettings.max_search_steps RK4 steps is given up
    and reported not converged (NaN pose), never a plausible-looking answer."""
    c = 0.04    # the fuzz input's diameters (0.4 / 0.8 mm) scaled so that a tube can hold 10 /mm
    tubes = (Tube(0.4 * c, 0.2 * c, 60.0, 60.0, 10.0), Tube(0.8 * c, 0.5 * c, 40.0, 50.0, 10.0))
    robot = Robot(tubes)
    Q = np.array([[0.0, 0.0, -30.0, -20.0], [90.0, 0.0, -30.0, -20.0]])
    traj = follow(robot, Q, settings=SolverSettings(max_search_steps=1000))
    assert not traj.converged[1] and not traj.stable[1] and np.isnan(traj.tip_poses[1]).all()


# --- issue 11 goal 5: the predictor of a warm step --------------------------------------------

@pytest.mark.parametrize("k", [2, 3, 4])
def test_predictor_is_exact_on_polynomials_of_its_degree(k: int, rng) -> None:
    """Through k states at τ = 0, −1, …, the predictor reproduces any polynomial of degree k − 1,
    at the whole step and at the sub-step fractions _advance tries."""
    coef = rng.normal(size=(k, 3))

    def x(tau: float) -> np.ndarray:
        return sum(tau ** p * coef[p] for p in range(k))

    pred = Predictor(np.array([x(-j) for j in range(k - 1, -1, -1)]))
    for tau in (0.0, 1.0, 0.5, 0.75, 1.0 / 256):
        np.testing.assert_allclose(pred.at(tau), x(tau), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(pred.at(0.0), x(0.0))  # the step starts exactly at the state


def _start_residuals(Q: np.ndarray, k: int) -> np.ndarray:
    """|r|∞ (rad/mm) of the shooting residual at the k-state prediction of each step of Q (T, 4)."""
    xs = np.array([e.x for e in follow(ROBOT, Q).equilibria])
    out = []
    for t in range(k, len(Q)):
        pb = prepare(ROBOT, Q[t], SolverSettings())
        a = pb.arrays
        x0 = Predictor(xs[t - k:t]).at(1.0)
        r, jac = np.empty(2), np.empty((2, 2))
        kernels.shoot(x0, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid, r, jac, False)
        out.append(np.abs(r).max())
    return np.array(out)


def test_parabola_starts_newton_within_reach_of_the_final_pass() -> None:
    """On 1° steps the parabola through the last three states leaves a residual below √(tol / C0)
    = 3.2e-7 rad/mm, where kernels.newton makes its first step the final pass; the secant does not."""
    Q = rotation_sweep(2, 12.0)[:120]
    secant, parabola = _start_residuals(Q, 2), _start_residuals(Q, 3)
    reach = math.sqrt(SolverSettings().tol / kernels.C0)
    assert np.median(parabola) < reach / 10 < reach < np.median(secant)
    assert np.mean(parabola < reach) > 0.8


def _passes_per_step(monkeypatch, Q: np.ndarray, path_states: int) -> tuple[list[float], object]:
    """Integration passes of every Newton solve in follow(Q), with PATH_STATES = path_states: those
of the general path (continuation.newton) and of the compiled warm step (mechanics.warm)."""
    passes: list[float] = []
    inner = continuation.newton
    inner_warm = warm.warm_step
    inner_run = warm.warm_run

    def counting_warm(*args):
        out = inner_warm(*args)
        passes.append(out[5])
        return out

    def counting_run(*args):
        counts = args[-2]  # (T, 2): iterations and passes of each step tried, 0 before
        before = counts[:, 1].copy()
        out = inner_run(*args)
        passes.extend(counts[before != counts[:, 1], 1].tolist())
        return out

    def counting(pb, x0, settings, work=None):
        w = [0]
        sol = inner(pb, x0, settings, w)
        passes.append(w[0] / pb.n_rk4)
        if work is not None:
            work[0] += w[0]
        return sol

    with monkeypatch.context() as m:
        m.setattr(continuation, "newton", counting)
        m.setattr(warm, "warm_step", counting_warm)
        m.setattr(warm, "warm_run", counting_run)
        m.setattr(continuation, "PATH_STATES", path_states)
        traj = follow(ROBOT, Q)
    return passes, traj


def test_warm_step_in_follow_takes_two_passes(monkeypatch) -> None:
    """A 1° step inside follow: one Newton pass with the variation and the final pass (the plain
    warm start and the secant took three), one Newton solve per step (the prediction never failed)."""
    Q = rotation_sweep(2, 12.0)
    passes, traj = _passes_per_step(monkeypatch, Q, continuation.PATH_STATES)
    assert traj.n_snaps == 0 and len(passes) == len(Q) - 1
    assert np.median(passes) == 2 and np.mean(np.array(passes) == 2) > 0.8
    assert np.median(_passes_per_step(monkeypatch, Q, 2)[0]) == 3


@pytest.mark.parametrize("d", [12.0, 16.0, 20.0])
def test_predictor_changes_no_snap_and_no_pose(monkeypatch, d: float) -> None:
    """The predictor only moves Newton's start: the same snaps, stability and poses as the plain
    warm start (the residual tolerance, 1e-10 rad/mm, is far below the tip tolerance)."""
    Q = rotation_sweep(2, d)
    _, plain = _passes_per_step(monkeypatch, Q, 1)
    pred = follow(ROBOT, Q)
    np.testing.assert_array_equal(pred.snaps, plain.snaps)
    np.testing.assert_array_equal(pred.stable, plain.stable)
    np.testing.assert_allclose(pred.tip_poses, plain.tip_poses, rtol=0, atol=1e-6)


def test_rotation_step_keeps_the_grid(rng) -> None:
    """with_alpha (a continuation step that keeps β) gives the problem prepare builds afresh."""
    base = prepare(ROBOT, np.array([10.0, 20.0, -18.0, -4.0]), SolverSettings())
    for _ in range(20):
        q = np.r_[rng.uniform(-720, 720, 2), base.q[2:]]
        fresh, kept = prepare(ROBOT, q, SolverSettings()), with_alpha(base, q)
        for u, v in zip((fresh.alpha, fresh.beta, fresh.tips, *fresh.grid),
                        (kept.alpha, kept.beta, kept.tips, *kept.grid), strict=True):
            np.testing.assert_array_equal(u, v)


def test_follow_does_not_alias_the_callers_joints() -> None:
    Q = rotation_sweep(2, 8.0, step_deg=30.0)
    traj = follow(ROBOT, Q)
    Q[:] = 0.0
    assert traj.q[1, 0] == 30.0 and traj.equilibria[1].q[0] == 30.0


def test_increments_equal_to_round_off_repeat() -> None:
    """A linspace path's increments differ in the last bits; they still repeat (the predictor is
    used), while a change of direction or of step does not."""
    q = np.c_[np.linspace(0.0, 90.0, 91), np.zeros(91), np.linspace(-20.0, -2.0, 91), np.zeros(91)]
    assert not (np.diff(q, axis=0)[1:] == np.diff(q, axis=0)[:-1]).all()  # not bit-equal
    assert continuation._repeats(np.diff(q, axis=0)).all()
    turn = np.r_[q[:10], q[9:0:-1]]
    assert not continuation._repeats(np.diff(turn, axis=0))[8]
    faster = np.r_[q[:10], q[10:30:2]]
    assert not continuation._repeats(np.diff(faster, axis=0))[9]


def test_a_step_of_a_whole_turn_or_more_flags_the_snaps_it_crosses() -> None:
    """Issue 27 item 14: `follow` with large steps (340° or 720° of α1 in one step) crossed snaps
    without flagging them. A step now turns no α by more than continuation.MAX_TURN_DEG at a time."""
    robot = paper_robot()
    q0 = rotation_sweep(2, 20.0, 0.0, 0.0, 1.0)[0]
    fine = follow(robot, rotation_sweep(2, 20.0, 0.0, 0.0, 1.0))
    assert fine.n_snaps == 2                        # the 1° sweep snaps forward and back
    for turn in (340.0, 720.0):
        path = np.array([q0, q0 + np.array([turn, 0.0, 0.0, 0.0])])
        tr = follow(robot, path)
        assert tr.snaps.tolist() == [False, True], turn
        fine_path = np.linspace(path[0], path[1], int(turn) + 1)
        end = follow(robot, fine_path).tip_poses[-1]
        np.testing.assert_allclose(tr.tip_poses[-1], end, atol=1e-6)   # the same branch at the end


def test_solve_from_the_previous_equilibrium_recovers_after_a_snap() -> None:
    """Issue 24: `prev = solve(q, guess=prev)` through a full inner turn at full curved overlap
    snaps where `follow` does and stays converged and stable after it (before: Newton from the
    state past the fold failed, and every later step started from that failure)."""
    Q = rotation_sweep(2, relative_translation=20.0, step_deg=4.0)[:91]   # 0 → 360°, one snap
    traj = follow(ROBOT, Q)
    assert traj.n_snaps == 1
    prev = solve(ROBOT, Q[0])
    tips = []
    for q in Q:
        prev = solve(ROBOT, q, guess=prev)
        assert prev.converged and prev.stable
        tips.append(prev.tip_position)
    np.testing.assert_allclose(np.array(tips), traj.tip_positions, atol=1e-6)


def test_compiled_warm_step_is_the_general_step() -> None:
    """continuation._warm (one compiled call, mechanics.warm) gives the Equilibrium the general
    path gives for the same step, field by field and bit for bit (every dataclass field: one
    added to Equilibrium or Problem and not to _warm fails here)."""
    Q = rotation_sweep(2, 16.0)[:60]
    traj = follow(ROBOT, Q)
    settings = SolverSettings()
    for t in range(1, len(Q)):
        prev = traj.equilibria[t - 1]
        fast = continuation._warm(prev, Q[t], prev.x, settings)
        assert fast is not None
        pb = with_alpha(prev.problem, Q[t])
        slow = equilibrium(pb, newton(pb, prev.x, settings))
        for f in dataclasses.fields(Equilibrium):
            u, v = getattr(fast, f.name), getattr(slow, f.name)
            if f.name == "problem":
                for g in dataclasses.fields(type(u)):
                    _assert_same(getattr(u, g.name), getattr(v, g.name), g.name)
            else:
                _assert_same(u, v, f.name)


def _assert_same(u: object, v: object, name: str) -> None:
    """Equal bit for bit: arrays, tuples of arrays, numbers (NaN equal to NaN), objects."""
    if isinstance(u, tuple):
        assert isinstance(v, tuple) and len(u) == len(v), name
        for a, b in zip(u, v, strict=True):
            _assert_same(a, b, name)
    elif isinstance(u, np.ndarray):
        np.testing.assert_array_equal(u, v, err_msg=name)
    elif isinstance(u, float):
        assert u == v or (math.isnan(u) and math.isnan(v)), name
    else:
        assert u is v or u == v, name


def _mixed_path() -> np.ndarray:
    """Paper robot: a 1° sweep at d = 20 mm (two snaps), then translating steps (a new grid each)
    and a sweep back at the new β: runs of rotation steps that stop at folds and at translations."""
    sweep = rotation_sweep(2, 20.0)
    slide = np.c_[np.full(10, sweep[-1, 0]), np.zeros(10), np.linspace(-20.0, -11.0, 10),
                  np.zeros(10)]
    back = np.c_[np.linspace(0.0, 200.0, 201), np.zeros(201), np.full(201, -11.0), np.zeros(201)]
    return np.r_[sweep, slide, back]


_MIXED = _mixed_path()


@pytest.mark.parametrize("robot, Q", [
    (ROBOT, _MIXED),
    (ROBOT, np.c_[np.linspace(0.0, 360.0, 361), np.zeros(361), np.linspace(-20.0, -2.0, 361),
                  np.zeros(361)]),
    (timclab_robot(), np.c_[rotation_sweep(2, 0.0)[:, 0], np.zeros((721, 2)),
                            np.full(721, -40.0), np.full(721, -20.0), np.zeros(721)]),
], ids=["paper", "paper-translating", "timclab"])
def test_compiled_runs_are_the_general_path(monkeypatch, robot: Robot, Q: np.ndarray) -> None:
    """follow's compiled runs of warm steps (mechanics.warm.warm_run, with the predictor inside)
    give what the general path gives step by step, bit for bit: every Equilibrium field (its
    Problem's too; made when read), the snaps, poses and flags; rotation runs (warm.warm_run) and
    translating ones (warm.moving_run, a grid each step). With the runs off every step takes the
    general path (continuation._advance without its compiled try)."""
    fast = follow(robot, Q)
    with monkeypatch.context() as m:
        m.setattr(continuation, "run_for", lambda *args: None)
        slow = follow(robot, Q)
    for f in ("q", "tip_poses", "snaps", "azimuth", "stable", "converged"):
        np.testing.assert_array_equal(getattr(fast, f), getattr(slow, f), err_msg=f)
    if Q is _MIXED:
        assert fast.n_snaps == 2
    for u, v in zip(fast.equilibria, slow.equilibria, strict=True):
        for f in dataclasses.fields(Equilibrium):
            a, b = getattr(u, f.name), getattr(v, f.name)
            if f.name == "problem":
                for g in dataclasses.fields(type(a)):
                    _assert_same(getattr(a, g.name), getattr(b, g.name), g.name)
            else:
                _assert_same(a, b, f.name)


def test_predictor_extrapolates_as_a_dot_product(rng) -> None:
    """warm.extrapolate (one fused multiply-add a term, in order) is the Lagrange polynomial:
    numpy's w.dot(xs) to round-off (bit for bit on this machine's OpenBLAS for N ≤ 3, which the
    benchmark's digest shows)."""
    for k in (2, 3):
        for tau in (1.0, 0.5, 1.0 / 256):
            w = continuation._lagrange(tau, k)
            xs = 1e-3 * rng.normal(size=(k, 5)).cumsum(axis=0)
            out = np.empty(5)
            warm.extrapolate(w, xs, out)
            np.testing.assert_allclose(out, w.dot(xs), rtol=1e-14, atol=1e-18)


def _assert_same_deep(u: object, v: object, name: str) -> None:
    """_assert_same, into dataclasses (Problem, ContactReport, FrictionState, Stations) field by
    field."""
    if dataclasses.is_dataclass(u) and not isinstance(u, type):
        assert type(u) is type(v), name
        for f in dataclasses.fields(u):
            _assert_same_deep(getattr(u, f.name), getattr(v, f.name), f"{name}.{f.name}")
    else:
        _assert_same(u, v, name)


@pytest.mark.parametrize("d", [12.0, 20.0])
def test_friction_runs_are_the_general_path(monkeypatch, d: float) -> None:
    """With friction (μ = 0.2, the virtual robot's) follow's compiled runs (warm.friction_run) give
    what the general path gives, step by step and bit for bit: the equilibria with their problems
    (stations, gathered state, the state solved for) and contact reports (outputs, the state after),
    the snaps, poses and flags; the path turns back and translates, so runs start from states
    the general path left."""
    rough = dataclasses.replace(ROBOT, friction=0.2)
    sweep = rotation_sweep(2, d)
    slide = np.c_[np.full(6, sweep[-1, 0]), np.zeros(6), np.linspace(-d, -d + 5.0, 6), np.zeros(6)]
    Q = np.r_[sweep, slide, np.c_[np.linspace(0.0, 90.0, 91), np.zeros(91),
                                  np.full(91, -d + 5.0), np.zeros(91)]]
    fast = follow(rough, Q)
    with monkeypatch.context() as m:
        m.setattr(continuation, "run_for", lambda *args: None)
        slow = follow(rough, Q)
    for f in ("q", "tip_poses", "snaps", "azimuth", "stable", "converged"):
        np.testing.assert_array_equal(getattr(fast, f), getattr(slow, f), err_msg=f)
    for t, (u, v) in enumerate(zip(fast.equilibria, slow.equilibria, strict=True)):
        _assert_same_deep(u, v, f"step {t}")
