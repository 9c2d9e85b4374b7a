"""The flat shooting pass (mechanics.passes) against the general one (kernels._integrate): the same
arithmetic in the same order, so the same bits, with the variation and with the body."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin import SolverSettings, paper_robot, solve
from ctrkin.mechanics import kernels
from ctrkin.mechanics.passes import NB, flat_pass, flat_work
from ctrkin.robots import timclab_robot


def _configs(robot, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = robot.project_joints(np.c_[rng.uniform(-180, 180, (n, robot.n_tubes)),
                                   -rng.uniform(0, 40, (n, robot.n_tubes)).cumsum(axis=1)[:, ::-1]])
    return q


@pytest.mark.parametrize("robot", [paper_robot(), timclab_robot()], ids=["paper", "timclab"])
def test_flat_pass_is_the_general_pass_bit_for_bit(robot) -> None:
    n = robot.n_tubes
    fw = flat_work(n)
    for q in _configs(robot, 6, seed=3):
        eq = solve(robot, q, settings=SolverSettings())
        pb = eq.problem
        a = pb.arrays
        x = eq.x + 1e-3  # off the root: residuals and Jacobian not ~0
        for with_var, with_body in ((True, False), (False, True)):
            r0, j0, r1, j1 = np.empty(n), np.zeros((n, n)), np.empty(n), np.zeros((n, n))
            zb = np.empty(NB)
            d0 = kernels._integrate(x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid,
                                    with_var, with_body, np.empty(2 * n), np.empty((2 * n, n)), zb,
                                    kernels._work(n), r0, j0, False, np.empty(1), np.empty((1, 3)),
                                    np.empty((1, 1)), np.empty((1, 1)), None, None, None, None, None)
            d1 = flat_pass(x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid, with_var,
                           with_body, fw, r1, j1)
            assert np.array_equal(r0, r1)
            assert np.array_equal(j0, j1)
            assert np.array_equal(np.float64(d0), np.float64(d1))
            if with_body:
                assert np.array_equal(zb, fw[2][0])
