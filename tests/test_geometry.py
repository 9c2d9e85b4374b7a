"""ctrkin.geometry: the tip pose convention (5-DOF quaternion, orientation errors, T(L)), conversions
against closed forms and scipy, the rigid transform, names defined once, the old ctrkin.pose path.

Tolerance: 1e-12 wherever two formulas of the same quantity meet (double rounding over a handful of
operations on unit-scale numbers stays below 1e-15; 1e-12 leaves room for SVD round-off)."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import ctrkin
from ctrkin import geometry
from ctrkin.data import schema
from ctrkin.models.features import POSE_NAMES, FeatureLayout
from ctrkin.models.frame import local_tips_to_world, world_poses_to_local
from ctrkin.robots.robot import joint_names

TOL = 1e-12
SRC = Path(ctrkin.__file__).parent

unit = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda v: 0.1 < np.linalg.norm(v) and (v[2] / np.linalg.norm(v)) > -0.99)


@settings(max_examples=50, deadline=None)
@given(unit)
def test_tangent_quaternion_round_trip(v) -> None:
    t = np.array(v) / np.linalg.norm(v)
    q = geometry.quat_from_tangent(t)
    assert np.linalg.norm(q) == np.float64(1.0) or abs(np.linalg.norm(q) - 1) < 1e-12
    np.testing.assert_allclose(geometry.tangent_from_quat(q), t, atol=1e-12)


def test_identity_and_known_rotation() -> None:
    np.testing.assert_allclose(geometry.quat_from_tangent(np.array([0, 0, 1.0])), [1, 0, 0])
    # tangent along +x: rotation of 90° about +y -> (cos45, 0, sin45)
    np.testing.assert_allclose(geometry.quat_from_tangent(np.array([1.0, 0, 0])),
                               [np.sqrt(0.5), 0, np.sqrt(0.5)])


def test_orientation_errors() -> None:
    a = geometry.tip_pose(np.zeros(3), np.array([0, 0, 1.0]))
    b = geometry.tip_pose(np.zeros(3), np.array([np.sin(0.1), 0, np.cos(0.1)]))
    assert geometry.tangent_angle_error(a, b) == np.float64(np.degrees(0.1)) or \
        abs(geometry.tangent_angle_error(a, b) - np.degrees(0.1)) < 1e-9
    q = np.array([0.3, -0.5, 0.1, 0.8])
    assert geometry.quaternion_angle(q, -q) < 1e-6  # antipodal: the same rotation
    assert abs(geometry.quaternion_angle(np.array([1.0, 0, 0, 0]), np.array([0.0, 0, 0, 1])) - 180) < 1e-9


def test_tip_azimuth_unwraps_and_is_relative_to_outer_tube() -> None:
    th = np.radians(np.arange(0, 721, 10.0))
    p = np.c_[np.cos(th), np.sin(th), np.ones_like(th)]
    az = geometry.tip_azimuth(p, 30.0)
    np.testing.assert_allclose(az, np.degrees(th) - 30.0, atol=1e-9)


quaternions = st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: np.linalg.norm(q) > 0.1)


@settings(max_examples=50, deadline=None)
@given(quaternions)
def test_tangent_of_a_full_quaternion_is_the_third_matrix_column(q) -> None:
    q = np.array(q)
    np.testing.assert_allclose(geometry.tangent_from_quaternion(q), geometry.quaternion_to_matrix(q)[:, 2],
                               atol=TOL)
    xyzw = np.r_[q[1:], q[0]]
    np.testing.assert_allclose(geometry.quaternion_to_matrix(q), Rotation.from_quat(xyzw).as_matrix(),
                               atol=TOL)


@settings(max_examples=50, deadline=None)
@given(quaternions)
def test_five_dof_quaternion_is_a_full_one_with_qz_zero(q) -> None:
    q3 = np.array(q[:3])
    if np.linalg.norm(q3) < 0.1:
        return
    full = np.r_[q3, 0.0]
    t = geometry.tangent_from_quat(q3)
    np.testing.assert_allclose(t, geometry.tangent_from_quaternion(full), atol=TOL)
    np.testing.assert_allclose(geometry.pose_rotation(q3).apply([0.0, 0.0, 1.0]), t, atol=TOL)


def test_matrix_to_quaternion_keeps_the_scalar_part_non_negative() -> None:
    rng = np.random.default_rng(3)
    R = Rotation.random(200, random_state=rng).as_matrix()
    q = geometry.matrix_to_quaternion(R)
    assert np.all(q[:, 0] >= 0)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=TOL)
    np.testing.assert_allclose(geometry.quaternion_to_matrix(q), R, atol=TOL)


def test_rotate_z_turns_the_x_axis_onto_the_azimuth() -> None:
    deg = np.array([0.0, 90.0, 30.0, -120.0])
    v = geometry.rotate_z(np.tile([1.0, 0.0, 2.0], (4, 1)), deg)
    np.testing.assert_allclose(v, np.c_[np.cos(np.radians(deg)), np.sin(np.radians(deg)), np.full(4, 2.0)],
                               atol=TOL)


def test_kabsch_fit_recovers_a_transform_and_agrees_with_scipy_align_vectors() -> None:
    rng = np.random.default_rng(7)
    true = geometry.RigidTransform.from_rotvec(rng.normal(size=3), rng.normal(scale=10.0, size=3))
    a = rng.normal(scale=20.0, size=(50, 3))
    b = true.apply_points(a) + rng.normal(scale=0.1, size=(50, 3))
    fit = geometry.RigidTransform.fit(a, b)
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    rot, _ = Rotation.align_vectors(b - cb, a - ca)           # b − cb ≈ R (a − ca)
    np.testing.assert_allclose(fit.rotation, rot.as_matrix(), atol=TOL)
    np.testing.assert_allclose(fit.translation, cb - rot.as_matrix() @ ca, atol=1e-10)   # mm, |cb| ~ 10
    np.testing.assert_allclose(fit.rotation, true.rotation, atol=0.01)
    exact = geometry.RigidTransform.fit(a, true.apply_points(a))
    np.testing.assert_allclose(exact.rotation, true.rotation, atol=TOL)
    assert exact.rms_mm < 1e-9


def test_transform_dict_round_trip_and_rotvec() -> None:
    t = geometry.RigidTransform.from_rotvec(np.array([0.1, -0.2, 0.3]), np.array([1.0, 2.0, 3.0]))
    back = geometry.RigidTransform.from_dict(t.to_dict())
    np.testing.assert_array_equal(back.rotation, t.rotation)
    np.testing.assert_array_equal(back.translation, t.translation)
    np.testing.assert_allclose(t.rotvec, [0.1, -0.2, 0.3], atol=TOL)
    assert geometry.Registration is geometry.RigidTransform


def test_sensor_view_is_the_pose_transformed_at_the_offset_point() -> None:
    rng = np.random.default_rng(11)
    poses = geometry.tip_pose(rng.normal(size=(20, 3)), rng.normal(size=(20, 3)) + np.array([0, 0, 3.0]))
    t = geometry.RigidTransform.from_rotvec(rng.normal(scale=0.1, size=3), rng.normal(size=3))
    view = geometry.sensor_view(poses, t, 4.0)
    tangent = geometry.tangent_from_quat(poses[:, 3:6])
    np.testing.assert_allclose(view[:, :3], (poses[:, :3] + 4.0 * tangent) @ t.rotation.T + t.translation,
                               atol=TOL)
    np.testing.assert_allclose(view, t.apply(np.c_[poses[:, :3] + 4.0 * tangent, poses[:, 3:6]]), atol=TOL)


def test_scalar_kernels_restate_the_pose_convention() -> None:
    """The numba kernels of ctrkin.models.frame inline quat_from_tangent / tangent_from_quat."""
    rng = np.random.default_rng(5)
    poses = geometry.tip_pose(rng.normal(size=(30, 3)), rng.normal(size=(30, 3)) + np.array([0, 0, 1.5]))
    zero, R, t = np.zeros(30), np.eye(3), np.zeros(3)
    pos, tan = local_tips_to_world(poses, zero, R, t)
    np.testing.assert_allclose(tan, geometry.tangent_from_quat(poses[:, 3:6]), atol=TOL)
    np.testing.assert_allclose(pos, poses[:, :3], atol=TOL)
    np.testing.assert_allclose(world_poses_to_local(poses, zero, R, t), poses, atol=TOL)


def test_pose_and_joint_names_are_defined_once() -> None:
    assert schema.POSE_COLUMNS == list(geometry.POSE_COLUMNS)
    assert POSE_NAMES is geometry.POSE_COLUMNS
    assert schema.joint_columns(3) == joint_names(3) == ["alpha_1", "alpha_2", "alpha_3", "beta_1", "beta_2",
                                                         "beta_3"]
    assert list(FeatureLayout(task="fk", n_tubes=2).input_names[:4]) == joint_names(2)
    assert list(FeatureLayout(task="fk", n_tubes=2).output_names) == list(geometry.POSE_COLUMNS)
    literal = "\"x\", \"y\", \"z\", \"q0\""
    copies = [p.relative_to(SRC) for p in SRC.rglob("*.py") if literal in p.read_text()]
    assert copies == [], f"pose column names spelt out again in {copies}"


def _imports(path: Path) -> set[str]:
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


def test_only_acquisition_and_evaluation_know_the_virtual_robot() -> None:
    """The learned side (models, the families, training, inference) and data never import
    ctrkin.virtual; models (the bundle) imports neither training nor inference; the training engine
    produces a bundle without the inference package."""
    for package in ("models", "families", "training", "inference", "data"):
        for path in (SRC / package).rglob("*.py"):
            assert not any(m.startswith("ctrkin.virtual") for m in _imports(path)), path
    for path in (SRC / "models").glob("*.py"):
        assert not any(m.startswith(("ctrkin.training", "ctrkin.inference", "ctrkin.evaluation"))
                       for m in _imports(path)), path
    assert not any(m.startswith("ctrkin.inference") for m in _imports(SRC / "training" / "engine.py"))


def test_the_old_pose_module_is_the_geometry_module() -> None:
    from ctrkin import pose

    assert pose.__all__
    for name in pose.__all__:
        assert getattr(pose, name) is getattr(geometry, name), name
