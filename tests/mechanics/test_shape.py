"""Dense backbones (mechanics/shape.py): on the exact arc, on the solved curve, evenly spaced."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ctrkin import Robot, SolverSettings, Tube, follow, paper_robot, solve
from ctrkin.mechanics.shape import dense_backbone

TIP_TOL_MM = 1e-3    # the solve's default tip tolerance (SolverSettings.tip_tol)


@pytest.mark.parametrize("alpha", [0.0, 200.0])
@pytest.mark.parametrize("spacing", [0.25, 2.0])
def test_single_tube_points_lie_on_the_exact_arc(alpha: float, spacing: float) -> None:
    """Straight 30 mm then a 20 mm arc of radius 25 mm (towards −y at α = 0, turned by α): every
    dense point on the straight line or on the circle, points at most `spacing` apart."""
    kappa, straight = 1 / 25.0, 30.0
    robot = Robot((Tube(1.0, 0.8, straight_length=straight, curved_length=20.0, curvature=kappa),))
    eq = solve(robot, [alpha, 0.0])
    bb = dense_backbone(eq, spacing)
    assert np.diff(bb.s).max() <= spacing + 1e-9 and bb.s[0] == 0.0 and bb.s[-1] == pytest.approx(50.0)
    assert len(bb.s) >= 50.0 / spacing
    a = math.radians(alpha)
    local = np.c_[np.cos(a) * bb.points[:, 0] + np.sin(a) * bb.points[:, 1],       # turned back by −α
                  -np.sin(a) * bb.points[:, 0] + np.cos(a) * bb.points[:, 1], bb.points[:, 2]]
    on_line = bb.s <= straight
    np.testing.assert_allclose(local[on_line], np.c_[0 * bb.s, 0 * bb.s, bb.s][on_line], atol=1e-9)
    centre = np.array([0.0, -1 / kappa, straight])
    radius = np.linalg.norm(local[~on_line] - centre, axis=1)
    np.testing.assert_allclose(radius, 1 / kappa, atol=1e-4)
    np.testing.assert_allclose(local[~on_line, 0], 0.0, atol=1e-9)
    # arc length along the circle equals s
    th = np.arctan2(local[~on_line, 2] - straight, local[~on_line, 1] + 1 / kappa)
    np.testing.assert_allclose(th / kappa, bb.s[~on_line] - straight, atol=1e-3)


def test_paper_robot_dense_backbone_passes_through_the_solved_one() -> None:
    robot = paper_robot()
    for q in ([0, 0, -15, -5], [180, 0, -20, 0], [90, 45, -10, -2]):
        eq = solve(robot, np.array(q, float))
        bb = dense_backbone(eq, 0.5)
        assert len(eq.s) <= 10 < 100 <= len(bb.s)                  # 6–9 points before, 100+ after
        assert np.diff(bb.s).max() <= 0.5 + 1e-9
        np.testing.assert_allclose(bb.points[-1], eq.tip_position, atol=TIP_TOL_MM)
        for s0, p0 in zip(eq.s, eq.backbone, strict=True):            # the coarse points, within tol
            k = np.flatnonzero(np.isclose(bb.s, s0))
            if len(k):
                np.testing.assert_allclose(bb.points[k[0]], p0, atol=TIP_TOL_MM)
        np.testing.assert_allclose(bb.tips, eq.q[2:] + robot.lengths)
        assert bb.extent(1) == (0.0, bb.tips[1]) and bb.extent(0) == (bb.tips[1], bb.tips[0])
        assert np.isnan(bb.twist[bb.s > bb.tips[1] + 1e-9, 1]).all()
        assert not np.isnan(bb.twist[:, 0]).any()


def test_a_tighter_tolerance_moves_the_dense_points_by_less_than_the_default_tolerance() -> None:
    robot = paper_robot()
    q = np.array([200.0, 0.0, -20.0, 0.0])
    coarse = dense_backbone(solve(robot, q), 0.5)
    fine = dense_backbone(solve(robot, q, settings=SolverSettings(tip_tol=1e-7)), 0.5)
    np.testing.assert_allclose(coarse.s, fine.s)
    np.testing.assert_allclose(coarse.points, fine.points, atol=TIP_TOL_MM)


def test_follow_rows_and_bad_spacing() -> None:
    robot = paper_robot()
    a = np.arange(0, 40, 10.0)
    traj = follow(robot, np.c_[a, 0 * a, np.full(4, -20.0), 0 * a])
    bb = dense_backbone(traj.equilibria[-1], 1.0)
    np.testing.assert_allclose(bb.points[-1], traj.tip_poses[-1, :3], atol=TIP_TOL_MM)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="spacing"):
            dense_backbone(traj.equilibria[0], bad)
    section = bb.section(*bb.extent(0))
    assert section.shape[1] == 3 and len(section) >= 2


def test_friction_and_clearance_rows_keep_their_torques_and_tilt() -> None:
    """A row of a friction sweep (stuck twist, clearance tilt): the dense backbone applies the
    same friction torques and tilt as the solve, so it ends at the row's tip; the frictionless
    equilibrium at the same joints ends elsewhere (the check can fail)."""
    rough = dataclasses.replace(paper_robot(), friction=0.2, clearance=1.0)
    a = np.arange(0, 100, 10.0)
    traj = follow(rough, np.c_[a, 0 * a, np.full(len(a), -8.0), 0 * a])
    eq = traj.equilibria[-1]
    bb = dense_backbone(eq, 0.5)
    np.testing.assert_allclose(bb.points[-1], eq.tip_position, atol=TIP_TOL_MM)
    free = solve(paper_robot(), eq.q)
    assert np.linalg.norm(free.tip_position - eq.tip_position) > 10 * TIP_TOL_MM
