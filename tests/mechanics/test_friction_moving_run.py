"""follow's compiled run of translating steps with contact effects (mechanics.warm.friction_moving_run,
compiled_runs._friction_moving_run): bit for bit the general path (continuation._advance) that takes
these steps when the runs are off."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ctrkin import Robot, follow, paper_robot
from ctrkin.acquisition.protocols import arbitrary
from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.mechanics import compiled_runs, continuation, warm
from ctrkin.mechanics.continuation import Trajectory
from ctrkin.mechanics.friction import FRESH, SLIP, STICK
from ctrkin.virtual import VirtualRobot
from tests.mechanics.test_continuation import _assert_same_deep


def _rough() -> Robot:
    """The default virtual robot's true tubes, seed 0: friction and clearance, five sections a tube
    (an arc profile of precurvature), so a translation moves tips across section ends."""
    robot = VirtualRobot(paper_robot(), seed=0).true_robot
    assert robot.friction > 0 and robot.clearance > 0
    return robot


def _sweep_sliding(d_end: float) -> np.ndarray:
    """Paper robot's inner tube turned 0 → 360° in 1° steps while it slides from d = 20 mm to d_end:
    every step translates, and the sweep crosses the fold near 200°."""
    Q = rotation_sweep(2, 20.0)[:361]
    Q[:, 2] = np.linspace(-20.0, -d_end, 361)
    return Q


_ARBITRARY = arbitrary(paper_robot()).runs[0].segments[0].q[:111]

# (robot, path, start step): the arbitrary path turns and translates both tubes every step, on the
# rough robot the station count changes along it (8 to 10); the sliding sweeps snap once, the
# creeping one (0.04 mm in all) with elements that stick on some steps (det J compared there), and
# with clearance alone (μ = 0: no element slips, det J compared on almost every step)
CASES = {
    "arbitrary": (_rough(), _ARBITRARY, 0),
    "arbitrary-from-start": (_rough(), _ARBITRARY, 50),
    "sliding-snap": (dataclasses.replace(paper_robot(), friction=0.2), _sweep_sliding(19.0), 0),
    "creeping-snap": (dataclasses.replace(paper_robot(), friction=0.2), _sweep_sliding(19.96), 0),
    "clearance-snap": (dataclasses.replace(paper_robot(), clearance=1.0), _sweep_sliding(19.0), 0),
}


def _moving_steps(tr: Trajectory) -> list[int]:
    """The steps of tr solved by a translating friction run."""
    return [t for t, r in enumerate(tr._steps.runs) if isinstance(r, compiled_runs._MovingRun)]


@pytest.fixture(scope="module", params=list(CASES))
def both(request) -> tuple[str, Trajectory, Trajectory]:
    """(case, follow with its compiled runs, follow by the general path alone)."""
    robot, Q, first = CASES[request.param]
    start = follow(robot, Q[:first + 1]).equilibria[-1] if first else None
    fast = follow(robot, Q[first:], start=start)
    with pytest.MonkeyPatch.context() as m:
        m.setattr(continuation, "run_for", lambda *args: None)
        slow = follow(robot, Q[first:], start=start)
    return request.param, fast, slow


def test_translating_friction_runs_are_the_general_path(both) -> None:
    """Every step, bit for bit: tip poses, snaps and flags; each Equilibrium's fields (x, the body,
    α, the statistics), its problem's (the grid, the stations of its own grid, the cvar solved for
    and the friction state it was gathered from) and its contact report's (the stations' outputs,
    the friction state after the step)."""
    _, fast, slow = both
    for f in ("q", "tip_poses", "snaps", "azimuth", "stable", "converged"):
        np.testing.assert_array_equal(getattr(fast, f), getattr(slow, f), err_msg=f)
    for t, (u, v) in enumerate(zip(fast.equilibria, slow.equilibria, strict=True)):
        _assert_same_deep(u, v, f"step {t}")
    assert not _moving_steps(slow)


def test_the_runs_take_the_steps_their_first_try_takes(both) -> None:
    """The run solves the translating steps (all but those it does not accept: here the snaps, which
    the general path takes from the start), across grids with different station counts on the
    rough robot; so the bit-for-bit test above tests the run."""
    case, fast, _ = both
    moving = _moving_steps(fast)
    snaps = np.flatnonzero(fast.snaps).tolist()
    assert set(moving).isdisjoint(snaps)
    assert len(moving) >= len(fast.q) - 1 - 2 * len(snaps)
    if case.endswith("snap"):
        assert len(snaps) == 1
    if case.startswith("arbitrary"):  # a step of a run on a grid with another station count
        runs, eqs = fast._steps.runs, fast.equilibria
        assert any(runs[t - 1] is runs[t] and eqs[t].contact.out.shape != eqs[t - 1].contact.out.shape
                   for t in moving)


def test_det_j_is_compared_as_the_general_path_does(rng) -> None:
    """warm._held_translating is continuation._det_comparable on a translating step: patterns of
    different lengths (another grid) are not comparable, equal ones only where no element slips."""
    modes = np.array([FRESH, STICK, SLIP], dtype=float)
    for _ in range(300):
        a = modes[rng.integers(0, 3, size=rng.integers(0, 4))]
        b = a.copy() if rng.random() < 0.5 else modes[rng.integers(0, 3, size=rng.integers(0, 4))]
        want = continuation._det_comparable(a.tobytes(), b.tobytes(), translating=True)
        assert warm._held_translating(a, b) == want, (a, b)
