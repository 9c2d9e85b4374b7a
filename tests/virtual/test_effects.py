"""The virtual robot's physical effects of issue 20: friction between the tubes, clearance,
precurvature along the arc and out of plane, EM field distortion; each switched and scaled by its
VirtualConfig field."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ctrkin.acquisition.protocols import inner_turn
from ctrkin.geometry import RigidTransform
from ctrkin.mechanics import follow
from ctrkin.virtual import VirtualConfig, VirtualRobot
from ctrkin.virtual.hardware import CURVED_PIECES
from ctrkin.virtual.robot import workspace

IDEAL = VirtualConfig().ideal()


def only(**kw: float) -> VirtualConfig:
    return dataclasses.replace(IDEAL, **kw)


def test_ideal_has_none_of_them(robot):
    v = VirtualRobot(robot, IDEAL, seed=0)
    t = v.true_robot
    assert t.friction == 0 and t.clearance == 0 and v.tracker.warp is None
    assert [len(x.sections) for x in t.tubes] == [len(x.sections) for x in robot.tubes]
    assert all(s.curvature_y == 0 for x in t.tubes for s in x.sections)


def test_friction_and_clearance_go_to_the_true_robot(robot):
    v = VirtualRobot(robot, only(tube_friction=0.3, clearance=0.5), seed=0)
    assert v.true_robot.friction == 0.3 and v.true_robot.clearance == 0.5
    assert VirtualRobot(robot, VirtualConfig(), seed=0).true_robot.friction == VirtualConfig().tube_friction


def test_friction_between_the_tubes_widens_the_loop_and_delays_the_snap(robot):
    """Turning the inner tube through a full overlap and back: with friction the loop of the tip's
    azimuth opens where the TCM has none, and the snaps come later, each by more with more μ."""
    Q = inner_turn(2, 0.0, 0.0, 20.0, step_deg=2.0)
    half = (len(Q) - 1) // 2
    first_snap, loop12 = [], []
    Q12 = inner_turn(2, 0.0, 0.0, 12.0, step_deg=2.0)
    for mu in (0.0, 0.1, 0.3):
        v = VirtualRobot(robot, only(tube_friction=mu), seed=0)
        m, _ = v.move(v.rest(Q[0]), Q)
        first_snap.append(int(np.nonzero(m.snaps)[0][0]))
        m12, _ = v.move(v.rest(Q12[0]), Q12)
        tip = m12.true_poses[:, :3]
        loop12.append(float(np.linalg.norm(tip[: half + 1] - tip[::-1][: half + 1], axis=1).max()))
    assert first_snap[0] < first_snap[1] < first_snap[2] <= half
    assert loop12[0] < 1e-6 < loop12[1] < loop12[2]


def test_precurvature_varies_along_the_arc_and_leaves_its_plane(robot):
    """Each curved section is cut into pieces; the variation has zero mean over the section and
    scales with its field; the plane turns only with precurvature_plane_deg."""
    flat = VirtualRobot(robot, only(precurvature_variation=0.1), seed=3)
    both = VirtualRobot(robot, only(precurvature_variation=0.2, precurvature_plane_deg=5.0), seed=3)
    for t_nom, t_flat, t_both in zip(robot.tubes, flat.true_robot.tubes, both.true_robot.tubes, strict=True):
        curved = [s for s in t_nom.sections if s.curved]
        pieces = [s for s in t_flat.sections if s.curved]
        assert len(pieces) == CURVED_PIECES * len(curved)
        assert all(p.curvature_y == 0 for p in pieces)
        kap = np.array([p.curvature for p in pieces])
        assert kap.mean() == pytest.approx(curved[0].curvature, rel=0.02)     # zero-mean profile
        dev1 = kap - curved[0].curvature
        assert np.abs(dev1).max() > 0.01 * curved[0].curvature
        turned = [s for s in t_both.sections if s.curved]
        mag = np.hypot([p.curvature for p in turned], [p.curvature_y for p in turned])
        np.testing.assert_allclose(mag - curved[0].curvature, 2 * dev1, rtol=1e-9, atol=1e-12)
        angle = np.degrees(np.arctan2([p.curvature_y for p in turned], [p.curvature for p in turned]))
        assert np.abs(angle).max() > 0.1 and abs(angle.mean()) < 1e-9                # zero-mean turn
    assert flat.true_robot.tubes[0].length == pytest.approx(robot.tubes[0].length)


def test_em_warp_is_the_configured_non_rigid_error(robot):
    """The tracker's warp leaves em_distortion_mm after the best rigid fit over the workspace (a
    fresh sample of it: within 20 %), scales with the field, and moves positions only."""
    rng = np.random.default_rng(7)
    pts = workspace(robot, rng)
    for mm in (0.5, 2.0):
        v = VirtualRobot(robot, only(em_distortion_mm=mm), seed=1)
        warp = v.tracker.warp
        assert warp is not None
        assert warp.non_rigid_rms(pts) == pytest.approx(mm, rel=0.2)
    poses = np.c_[pts, np.tile([1.0, 0.0, 0.0], (len(pts), 1))]
    seen = v.tracker.registered(poses)
    np.testing.assert_allclose(seen[:, 3:], poses[:, 3:], atol=1e-12)   # the axis is not warped
    fit = RigidTransform.fit(pts, seen[:, :3])
    assert fit.rms_mm == pytest.approx(2.0, rel=0.2)                   # no registration removes it


def test_clearance_tilts_the_tip_where_the_inner_tube_sticks_out(robot):
    """Clearance alone: more than 0.5 mm at d = 4 mm (16.5 mm of inner tube beyond the outer tip),
    in proportion to the gap share up to its square root (C7: tilt ∝ √δ)."""
    q = np.array([[30.0, 0.0, -4.0, 0.0]])
    moves = []
    for c in (0.25, 1.0):
        v = VirtualRobot(robot, only(clearance=c), seed=0)
        m, _ = v.move(v.rest(q[0]), q)
        moves.append(float(np.linalg.norm(m.true_poses[0, :3] - follow(robot, q).tip_positions[0])))
    assert moves[1] > 0.5
    assert moves[1] / moves[0] == pytest.approx(2.0, rel=0.15)
