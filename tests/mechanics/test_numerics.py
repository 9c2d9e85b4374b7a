"""Integration step from a stated tolerance, exact straight stretches, the combined final pass."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ctrkin import SolverSettings, paper_robot, solve
from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.mechanics import kernels
from ctrkin.mechanics.pointwise import _integrate, prepare
from ctrkin.robots import timclab_robot

from .reference_tcm import reference_tip

PAPER = paper_robot()
TIMCLAB = timclab_robot()


def paper_q(rng: np.random.Generator) -> np.ndarray:
    b2 = rng.uniform(-15, 0)
    return np.array([rng.uniform(0, 360), rng.uniform(0, 360), b2 - rng.uniform(0, 20.5), b2])


def timclab_q(rng: np.random.Generator) -> np.ndarray:
    """Curved parts overlapping: each inner tube's tip 0-40 mm beyond the next one's."""
    b3 = -rng.uniform(0, 100)
    b2 = b3 + 199.0 - 330.5 + rng.uniform(0, 40)
    b1 = b2 + 330.5 - 463.0 + rng.uniform(0, 40)
    return np.r_[rng.uniform(0, 360, 3), b1, b2, b3]


@pytest.mark.parametrize(("robot", "make_q", "tip_tol"), [
    (PAPER, paper_q, 1e-3), (PAPER, paper_q, 1e-6), (TIMCLAB, timclab_q, 1e-3),
    (TIMCLAB, timclab_q, 1e-5)])
def test_step_from_tolerance_meets_it(robot, make_q, tip_tol: float, rng) -> None:
    """With the step taken from tip_tol alone (no 3 mm cap), the tip is within tip_tol of the
    tight reference (scipy DOP853, rtol 1e-12); the estimate is 2-8× above the measured error."""
    settings = SolverSettings(step=math.inf, tip_tol=tip_tol)
    worst = 0.0
    for _ in range(4):
        q = make_q(rng)
        eq = solve(robot, q, settings=settings)
        assert eq.converged
        tip, _, _ = reference_tip(robot, q, eq.x)
        worst = max(worst, float(np.linalg.norm(eq.tip_position - tip)))
    assert worst <= tip_tol


def test_error_falls_as_step_to_the_fourth(rng) -> None:
    """RK4's global error ∝ h⁴: from 8 to 2 mm the tip error falls with slope 3.5-4.5 in log-log
    (stretches shorter than h are stepped whole, so single halvings are not exactly 16×)."""
    q = timclab_q(rng)
    ref = reference_tip(TIMCLAB, q, solve(TIMCLAB, q).x)[0]
    errs = [np.linalg.norm(solve(TIMCLAB, q, settings=SolverSettings(step=h, angle_step=10.0))
                           .tip_position - ref) for h in (8.0, 2.0)]
    assert 3.5 < math.log(errs[0] / errs[1]) / math.log(4.0) < 4.5


def test_straight_stretch_in_one_step_is_exact(rng) -> None:
    """A stretch where every present tube is straight is one RK4 step; subdividing it as a
    curved stretch would be changes nothing (residual, Jacobian, det H, tip) beyond round-off."""
    for robot, q in ((PAPER, paper_q(rng)), (TIMCLAB, timclab_q(rng))):
        pb = prepare(robot, q, SolverSettings())
        bounds, kap, kapy, present, nsteps, nsample = pb.grid
        straight = ~((kap != 0.0) | (kapy != 0.0)).any(axis=1)
        assert straight.any() and (nsteps[straight] == 1).all()
        assert (nsteps[~straight] == nsample[~straight]).all()
        x = solve(robot, q).x + 1e-3 / robot.lengths.max()
        a = pb.arrays
        n = robot.n_tubes
        out = []
        for steps in (nsteps, nsample):
            r, jac = np.empty(n), np.empty((n, n))
            det_h = kernels.shoot(x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, bounds, kap,
                                  kapy, present, steps, nsample, r, jac, True)
            body = np.empty(7)
            rec = (np.empty(1), np.empty((1, 3)), np.empty((1, n)), np.empty((1, n)))
            kernels.integrate_full(x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, bounds,
                                   kap, kapy, present, steps, nsample, False, *rec, body)
            out.append((r, jac, det_h, body))
        for u, v in zip(*out, strict=True):
            np.testing.assert_allclose(u, v, rtol=1e-10, atol=1e-12)


def test_final_pass_equals_a_separate_backbone_pass(rng) -> None:
    """The tip, tangent and energy of the final Newton pass are those of integrating (M3) afresh."""
    for robot, q in ((PAPER, paper_q(rng)), (TIMCLAB, timclab_q(rng))):
        eq = solve(robot, q)
        tip, tan, energy, _ = _integrate(eq.problem, eq.x, record=False)
        np.testing.assert_allclose(eq.tip_position, tip, atol=1e-12)
        np.testing.assert_allclose(eq.tip_tangent, tan, atol=1e-12)
        assert eq.energy == pytest.approx(energy, rel=1e-12)


def test_warm_step_takes_three_passes() -> None:
    """A 1° warm step on the paper robot: two Newton passes with the variation and the final one
    with the backbone (was three and a separate backbone pass)."""
    Q = rotation_sweep(2, 12.0)[:40]
    prev = solve(PAPER, Q[0])
    passes = []
    for q in Q[1:]:
        pb = prepare(PAPER, q, SolverSettings())
        a = pb.arrays
        x, body = np.empty(2), np.empty(7)
        out = kernels.newton(prev.x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid,
                             1e-10, 40, 0.05, x, body)
        assert out[0]
        passes.append(out[5])
        prev = solve(PAPER, q, guess=prev)
    assert np.median(passes) <= 3
