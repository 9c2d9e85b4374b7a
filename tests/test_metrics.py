"""ctrkin.metrics on hand-computed cases: position, tip-tangent angle, α wrapping, joint norms, and
the two output forms (results.json nested, metrics.json flat) agreeing on the same numbers."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.geometry import quat_from_tangent, tip_pose
from ctrkin.metrics import (
    error_stats,
    joint_error_norms,
    joint_errors,
    metrics_json_joint_errors,
    metrics_json_pose_errors,
    pose_errors,
    timing_stats,
    wrap_deg,
)


def test_error_stats_hand_computed() -> None:
    s = error_stats(np.array([3.0, -4.0]))
    assert s == {"rmse": pytest.approx(np.sqrt(12.5)), "mae": 3.5, "max": 4.0, "median": 3.5,
                 "n": 2}
    assert np.isnan(error_stats(np.array([1.0, np.nan]))["rmse"])  # a failure is not hidden
    empty = error_stats(np.zeros(0))
    assert empty["n"] == 0 and np.isnan(empty["rmse"])


def test_wrap_deg_at_and_around_180() -> None:
    a = np.array([-540.0, -360.0, -181.0, -180.0, -179.0, 0.0, 179.0, 180.0, 181.0, 359.0, 360.0, 540.0])
    np.testing.assert_allclose(wrap_deg(a),
                               [-180.0, 0.0, 179.0, -180.0, -179.0, 0.0, 179.0, -180.0, -179.0, -1.0, 0.0,
                                -180.0])
    assert wrap_deg(np.zeros((2, 3, 4))).shape == (2, 3, 4)  # any shape, elementwise


def test_pose_errors_position_and_tangent_angle() -> None:
    a = np.array([[0, 0, 0, 1.0, 0, 0]])
    t = np.array([0.0, np.sin(np.radians(30)), np.cos(np.radians(30))])
    b = np.r_[3.0, 4.0, 0.0, quat_from_tangent(t)][None]
    e = pose_errors(b, a)
    assert e["position_mm"]["rmse"] == pytest.approx(5.0)
    assert e["orientation_deg"]["rmse"] == pytest.approx(30.0)


def test_pose_errors_mask_counts_only_its_rows() -> None:
    a = np.zeros((3, 6))
    a[:, 3] = 1.0
    b = a.copy()
    b[:, 0] = [1.0, 2.0, 10.0]
    e = pose_errors(b, a, mask=np.array([True, True, False]))
    assert e["position_mm"]["n"] == 2 and e["position_mm"]["max"] == pytest.approx(2.0)


def test_antipodal_quaternions_have_zero_orientation_error() -> None:
    q = quat_from_tangent(np.array([0.3, -0.2, 0.9]))
    a = np.r_[0, 0, 0, q][None]
    b = np.r_[0, 0, 0, -q][None]
    assert pose_errors(a, b)["orientation_deg"]["max"] == pytest.approx(0.0, abs=1e-6)


def test_joint_errors_norms() -> None:
    pred = np.array([[3.0, 4.0, -1.0, 0.0]])
    ref = np.zeros((1, 4))
    e = joint_errors(pred, ref, 2)
    assert e["alpha_deg"]["rmse"] == pytest.approx(5.0) and e["beta_mm"]["rmse"] == pytest.approx(1.0)


def test_joint_errors_wrap_full_turns() -> None:
    pred = np.array([[359.0, 10.0, -1.0, 0.0], [-170.0, 720.0, -1.0, 0.0]])
    ref = np.array([[-1.0, 370.0, -1.0, 0.0], [170.0, 0.0, -1.0, 0.0]])
    e = joint_errors(pred, ref, 2)
    assert e["alpha_deg"]["max"] == pytest.approx(20.0)  # (0, 0) and (20, 0)
    assert e["alpha_deg"]["rmse"] == pytest.approx(np.sqrt(200.0))
    assert e["beta_mm"]["max"] == 0.0


def test_joint_error_norms_at_plus_minus_180_and_shapes() -> None:
    """An α error of exactly ±180° is half a turn either way: 180° wrapped, never 0 or 360."""
    ref = np.zeros((3, 6))                                     # three tubes: (T, 2N) = (3, 6)
    pred = np.array([[180.0, 0, 0, 0, 0, 0], [-180.0, 0, 0, 0, 0, 0], [540.0, -180.0, 0, 0, 0, 2.0]])
    alpha, beta = joint_error_norms(pred, ref, 3)
    assert alpha.shape == beta.shape == (3,)
    np.testing.assert_allclose(alpha, [180.0, 180.0, np.hypot(180.0, 180.0)])
    np.testing.assert_allclose(beta, [0.0, 0.0, 2.0])
    raw, _ = joint_error_norms(pred, ref, 3, wrap=False)
    np.testing.assert_allclose(raw, [180.0, 180.0, np.hypot(540.0, 180.0)])


def test_metrics_json_forms_carry_the_same_numbers() -> None:
    """metrics.json (flat, training) and results.json (nested, evaluation) come from one computation."""
    ref = np.array([[1.0, 0.0, -10.0, 0.0], [0.0, 0.0, -10.0, 0.0]])
    pred = np.array([[359.0, 0.0, -13.0, -4.0], [3.0, 4.0, -10.0, 0.0]])
    flat = metrics_json_joint_errors(pred, ref, 2)
    nested = joint_errors(pred, ref, 2)
    assert flat["beta_mm_max"] == pytest.approx(5.0) == nested["beta_mm"]["max"]
    assert flat["alpha_deg_max"] == pytest.approx(358.0)                     # unwrapped: what the loss sees
    assert flat["alpha_wrapped_deg_rmse"] == pytest.approx(np.sqrt((4 + 25) / 2))
    assert flat["alpha_wrapped_deg_rmse"] == nested["alpha_deg"]["rmse"]    # wrapped: the configuration
    assert flat["n"] == 2

    a = tip_pose(np.array([[0.0, 0.0, 50.0]] * 2), np.array([[0.0, 0.0, 1.0]] * 2))
    t = np.array([[np.sin(np.radians(3.0)), 0.0, np.cos(np.radians(3.0))]] * 2)
    b = tip_pose(np.array([[3.0, 4.0, 50.0], [0.0, 0.0, 50.0]]), t)
    fp, np_ = metrics_json_pose_errors(a, b), pose_errors(a, b)
    assert fp["position_mm_rmse"] == pytest.approx(np.sqrt(25 / 2)) == np_["position_mm"]["rmse"]
    assert fp["position_mm_max"] == pytest.approx(5.0)
    assert fp["orientation_deg_mae"] == pytest.approx(3.0) == np_["orientation_deg"]["mae"]
    assert metrics_json_pose_errors(a[:0], b[:0]) == {"n": 0}                # no rows: no statistics


def test_timing_stats_units() -> None:
    t = timing_stats(np.array([1e-3, 3e-3]))
    assert t["ms_mean"] == pytest.approx(2.0) and t["ms_std"] == pytest.approx(1.0)
    assert t["us_median"] == pytest.approx(2000.0) and t["n"] == 2


def test_pose_errors_of_position_only_data_have_no_orientation() -> None:
    """A position-only dataset's quaternion columns are placeholders: no orientation error is made up."""
    a = tip_pose(np.array([[0.0, 0.0, 50.0]]), np.array([[0.0, 1.0, 1.0]]))
    b = tip_pose(np.array([[3.0, 4.0, 50.0]]), np.array([[0.0, 0.0, 1.0]]))
    e = metrics_json_pose_errors(a, b, orientation=False)
    assert e == {"position_mm_rmse": pytest.approx(5.0), "position_mm_mae": pytest.approx(5.0),
                 "position_mm_max": pytest.approx(5.0), "n": 1}
