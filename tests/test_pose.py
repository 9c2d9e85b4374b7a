"""Tip pose conventions: 5-DOF quaternion, orientation errors, T(L)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ctrkin.pose import (
    quat_from_tangent,
    quaternion_angle,
    tangent_angle_error,
    tangent_from_quat,
    tip_azimuth,
    tip_pose,
)

unit = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda v: 0.1 < np.linalg.norm(v) and (v[2] / np.linalg.norm(v)) > -0.99)


@settings(max_examples=50, deadline=None)
@given(unit)
def test_tangent_quaternion_round_trip(v) -> None:
    t = np.array(v) / np.linalg.norm(v)
    q = quat_from_tangent(t)
    assert np.linalg.norm(q) == np.float64(1.0) or abs(np.linalg.norm(q) - 1) < 1e-12
    np.testing.assert_allclose(tangent_from_quat(q), t, atol=1e-12)


def test_identity_and_known_rotation() -> None:
    np.testing.assert_allclose(quat_from_tangent(np.array([0, 0, 1.0])), [1, 0, 0])
    # tangent along +x: rotation of 90° about +y -> (cos45, 0, sin45)
    np.testing.assert_allclose(quat_from_tangent(np.array([1.0, 0, 0])), [np.sqrt(0.5), 0, np.sqrt(0.5)])


def test_orientation_errors() -> None:
    a = tip_pose(np.zeros(3), np.array([0, 0, 1.0]))
    b = tip_pose(np.zeros(3), np.array([np.sin(0.1), 0, np.cos(0.1)]))
    assert tangent_angle_error(a, b) == np.float64(np.degrees(0.1)) or \
        abs(tangent_angle_error(a, b) - np.degrees(0.1)) < 1e-9
    q = np.array([0.3, -0.5, 0.1, 0.8])
    assert quaternion_angle(q, -q) < 1e-6  # antipodal: the same rotation
    assert abs(quaternion_angle(np.array([1.0, 0, 0, 0]), np.array([0.0, 0, 0, 1])) - 180) < 1e-9


def test_tip_azimuth_unwraps_and_is_relative_to_outer_tube() -> None:
    th = np.radians(np.arange(0, 721, 10.0))
    p = np.c_[np.cos(th), np.sin(th), np.ones_like(th)]
    az = tip_azimuth(p, 30.0)
    np.testing.assert_allclose(az, np.degrees(th) - 30.0, atol=1e-9)
