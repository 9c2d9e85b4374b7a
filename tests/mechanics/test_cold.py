"""The cold solve's compiled common case (mechanics.cold, pointwise._cold) against the Python path."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ctrkin import Robot, SolverSettings, Tube, paper_robot, solve
from ctrkin.errors import ConvergenceError, JointError
from ctrkin.mechanics import pointwise
from ctrkin.mechanics.pointwise import Equilibrium, prepare, solve_prepared
from ctrkin.robots import timclab_robot

ONE_TUBE = Robot((Tube(1.0, 0.8, 60.0, 40.0, 1 / 30.0),))


def _same(u: object, v: object, name: str) -> None:
    if isinstance(u, tuple):
        assert isinstance(v, tuple) and len(u) == len(v), name
        for a, b in zip(u, v, strict=True):
            _same(a, b, name)
    elif isinstance(u, np.ndarray):
        assert isinstance(v, np.ndarray) and u.dtype == v.dtype, name
        np.testing.assert_array_equal(u, v, err_msg=name)
    elif isinstance(u, float):
        assert type(v) is float and (u == v or (math.isnan(u) and math.isnan(v))), name
    else:
        assert type(u) is type(v) and (u is v or u == v), name


def _configs(robot: Robot, rng: np.random.Generator, n: int) -> np.ndarray:
    """Random valid joints: α anywhere (whole turns too), each tube retracted within its limits."""
    lengths = robot.lengths
    out = []
    while len(out) < n:
        q = np.r_[rng.uniform(-720, 720, robot.n_tubes), np.zeros(robot.n_tubes)]
        b = -rng.uniform(0, lengths[-1])
        q[2 * robot.n_tubes - 1] = b
        for i in range(robot.n_tubes - 2, -1, -1):
            b = b - rng.uniform(0, lengths[i] - lengths[i + 1])
            q[robot.n_tubes + i] = b
        if robot.is_valid(q)[0]:
            out.append(q)
    return np.array(out)


@pytest.mark.parametrize("robot", [paper_robot(), timclab_robot(), ONE_TUBE],
                         ids=["paper", "timclab", "one-tube"])
def test_compiled_cold_solve_is_the_python_path(robot: Robot, rng) -> None:
    """solve(robot, q) by the compiled call gives what prepare + solve_prepared give, every field
    of the Equilibrium and its Problem bit for bit (the unstable first solves, which go on to the
    multi-start search, included where the sample has them)."""
    settings = SolverSettings()
    for q in _configs(robot, rng, 40):
        fast = solve(robot, q)
        slow = solve_prepared(prepare(robot, q, settings), None, settings)
        for f in dataclasses.fields(Equilibrium):
            a, b = getattr(fast, f.name), getattr(slow, f.name)
            if f.name == "problem":
                for g in dataclasses.fields(type(a)):
                    _same(getattr(a, g.name), getattr(b, g.name), g.name)
            else:
                _same(a, b, f.name)


def test_compiled_cold_solve_is_taken(monkeypatch) -> None:
    """The common case takes the compiled call (a float (2N,) array, no guess or state)."""
    calls: list[int] = []
    inner = pointwise.cold.cold_start

    def counting(*args):
        calls.append(1)
        return inner(*args)

    monkeypatch.setattr(pointwise.cold, "cold_start", counting)
    solve(paper_robot(), np.array([10.0, 20.0, -12.0, -4.0]))
    solve(paper_robot(), [10.0, 20.0, -12.0, -4.0])  # a list: the Python path
    assert len(calls) == 1


@pytest.mark.parametrize("q", [
    [0, 0, 5.0, -5.0],          # β1 > 0
    [0, 0, -5.0, -10.0],        # β1 > β2
    [0, 0, -30.0, 0.0],         # inner tip behind outer tip
    [0, 0, np.inf, -5.0],
], ids=["beta1", "order", "tips", "inf"])
def test_invalid_joints_raise_the_python_message(q) -> None:
    """The compiled call checks the joints and leaves the message to Robot.check_joints."""
    robot = paper_robot()
    with pytest.raises(JointError) as fast:
        solve(robot, np.array(q, dtype=float))
    with pytest.raises(JointError) as slow:
        robot.check_joints(q)
    assert str(fast.value) == str(slow.value)


def test_too_fine_a_grid_raises_the_python_message() -> None:
    robot = Robot((Tube(1.0, 0.8, 5000.0, 5000.0, 0.01),))
    with pytest.raises(ConvergenceError, match="max_rk4_steps"):
        solve(robot, np.array([0.0, 0.0]), settings=SolverSettings(step=1e-3))
