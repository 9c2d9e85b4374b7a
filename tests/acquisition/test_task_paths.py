"""Square and triangle IK target paths (paper Fig. 12)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ctrkin.acquisition.task_paths import load_targets, task_path
from ctrkin.errors import DatasetError
from ctrkin.pose import tangent_from_quat
from ctrkin.virtual import VirtualRobot


@pytest.mark.parametrize(("shape", "corners"), [("square", 4), ("triangle", 3)])
def test_points_lie_on_a_regular_polygon_of_reachable_corners(robot, shape, corners):
    v = VirtualRobot(robot, seed=0)
    p = task_path(v, shape, n_points=10, seed=1)
    assert p.poses.shape == (10, 6) and p.corners.shape == (corners, 6)
    np.testing.assert_allclose(p.poses[0], p.corners[0], atol=1e-12)
    # the corners are one configuration turned about z: equal edges (within the true robot's
    # residual curvature, which breaks the symmetry slightly)
    edges = np.linalg.norm(np.diff(np.r_[p.corners, p.corners[:1]][:, :3], axis=0), axis=1)
    assert edges.std() / edges.mean() < 0.1
    # every point lies on a polygon edge: distance to the nearest edge segment ~ 0
    ends = np.roll(p.corners, -1, axis=0)
    for x in p.poses[:, :3]:
        dmin = np.inf
        for a, b in zip(p.corners[:, :3], ends[:, :3], strict=True):
            t = np.clip(np.dot(x - a, b - a) / np.dot(b - a, b - a), 0, 1)
            dmin = min(dmin, np.linalg.norm(a + t * (b - a) - x))
        assert dmin < 1e-9
    np.testing.assert_allclose(np.linalg.norm(p.poses[:, 3:], axis=1), 1.0)


def test_orientation_follows_the_equivalent_angle_axis(robot):
    v = VirtualRobot(robot, seed=0)
    p = task_path(v, "square", n_points=8, seed=0)  # 2 points per edge: the midpoint of each edge
    ta, tb = tangent_from_quat(p.corners[0, 3:]), tangent_from_quat(p.corners[1, 3:])
    mid = tangent_from_quat(p.poses[1, 3:])
    # halfway along the edge the tangent is half-way (in angle) between the corner tangents
    ang = np.degrees(np.arccos(np.clip([ta @ mid, mid @ tb, ta @ tb], -1, 1)))
    assert ang[0] == pytest.approx(ang[1], abs=0.5) and ang[0] + ang[1] >= ang[2] - 1e-6
    # and it is the equivalent angle-axis midpoint of the corner rotations
    qa, qb = p.corners[0, 3:], p.corners[1, 3:]
    ra = Rotation.from_quat([qa[1], qa[2], 0.0, qa[0]])
    rb = Rotation.from_quat([qb[1], qb[2], 0.0, qb[0]])
    half = ra * Rotation.from_rotvec(0.5 * (ra.inv() * rb).as_rotvec())
    np.testing.assert_allclose(half.apply([0.0, 0.0, 1.0]), mid, atol=1e-12)


def test_targets_file_round_trip(robot, tmp_path):
    p = task_path(VirtualRobot(robot, seed=0), "triangle", seed=2)
    p.save(tmp_path / "tri")
    poses, meta = load_targets(tmp_path / "tri")
    np.testing.assert_allclose(poses, p.poses)
    assert meta["shape"] == "triangle" and len(meta["corner_joints"]) == 3
    with pytest.raises(DatasetError, match=r"targets\.csv"):
        load_targets(tmp_path / "missing")


def test_bad_shape_is_explained(robot):
    with pytest.raises(ValueError, match="square"):
        task_path(VirtualRobot(robot, seed=0), "circle")
