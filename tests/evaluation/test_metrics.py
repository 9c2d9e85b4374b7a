"""Metrics on hand-computed cases."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.evaluation.metrics import (
    azimuth_series,
    error_stats,
    glitch_window,
    joint_errors,
    pose_errors,
    rotation_direction,
    snap_report,
    snap_score,
    snap_steps,
    snap_window,
)
from ctrkin.pose import quat_from_tangent


def test_error_stats_hand_computed() -> None:
    s = error_stats(np.array([3.0, -4.0]))
    assert s == {"rmse": pytest.approx(np.sqrt(12.5)), "mae": 3.5, "max": 4.0, "median": 3.5,
                 "n": 2}
    assert np.isnan(error_stats(np.array([1.0, np.nan]))["rmse"])  # a failure is not hidden


def test_pose_errors_position_and_tangent_angle() -> None:
    a = np.array([[0, 0, 0, 1.0, 0, 0]])
    t = np.array([0.0, np.sin(np.radians(30)), np.cos(np.radians(30))])
    b = np.r_[3.0, 4.0, 0.0, quat_from_tangent(t)][None]
    e = pose_errors(b, a)
    assert e["position_mm"]["rmse"] == pytest.approx(5.0)
    assert e["orientation_deg"]["rmse"] == pytest.approx(30.0)


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


def test_azimuth_wraps_across_180_and_is_relative_to_outer_alpha() -> None:
    th = np.radians(np.array([170.0, 179.0, -179.0, -170.0]))
    poses = np.c_[np.cos(th), np.sin(th), np.ones(4), np.ones(4), np.zeros((4, 2))]
    joints = np.c_[np.zeros(4), np.full(4, 20.0), np.full((4, 2), -5.0)]
    az = azimuth_series(poses, joints, 2, [(0, 4)])
    np.testing.assert_allclose(az, [150.0, 159.0, 161.0, 170.0])
    assert len(snap_steps(az, [(0, 4)])) == 0  # the wrap is not a snap


def test_snap_score_matches_events_within_tolerance() -> None:
    ref = np.r_[np.zeros(10), np.full(10, 40.0), np.zeros(10), np.full(10, -30.0)]
    pred = np.r_[np.zeros(11), np.full(9, 40.0), np.zeros(10), np.zeros(10)]  # one late, one missed
    pred[35] = 25.0  # a false spike in the last sequence: up and back down is one event
    bounds = [(0, 20), (20, 40)]
    s = snap_score(pred, ref, bounds)
    assert s.n_reference == 2
    assert s.n_matched == 1 and s.timing_error_steps == 1.0 and s.magnitude_error_deg == 0.0
    assert s.recall == 0.5
    assert s.n_predicted == 2 and s.precision == pytest.approx(1 / 2)


def test_snap_steps_never_cross_sequences() -> None:
    az = np.r_[np.zeros(5), np.full(5, 90.0)]
    assert len(snap_steps(az, [(0, 5), (5, 10)])) == 0
    assert list(snap_steps(az, [(0, 10)])) == [5]


def test_snap_window_marks_two_steps_inside_sequence() -> None:
    snap = np.zeros(8, bool)
    snap[[2, 4]] = True
    w = snap_window(snap, [(0, 5), (5, 8)])
    assert list(np.nonzero(w)[0]) == [2, 3, 4]


def test_snap_report_splits_events_by_direction_of_rotation() -> None:
    """A forward-and-back turn: the forward snap matched, the backward one missed."""
    a0 = np.r_[np.arange(0, 361, 1.0), np.arange(359, -1, -1.0)]
    joints = np.c_[a0, np.zeros_like(a0), np.full((len(a0), 2), -10.0)]
    bounds = [(0, len(a0))]
    ref = np.where(a0 < 200, 0.0, 40.0)
    ref[361:] = np.where(a0[361:] > 150, 40.0, 0.0)
    pred = ref.copy()
    pred[361:] = 40.0                                                 # never snaps back
    direction = rotation_direction(joints, 2, bounds)
    assert direction[0] == 0 and direction[10] == 1 and direction[400] == -1
    r = snap_report(pred, ref, bounds, direction)
    assert r["n_reference"] == 2 and r["recall"] == 0.5
    assert r["forward"]["recall"] == 1.0 and r["forward"]["precision"] == 1.0
    assert r["backward"]["recall"] == 0.0 and r["backward"]["n_reference"] == 1


def test_events_just_after_an_encoder_glitch_are_not_counted() -> None:
    """A one-row glitch in the joints makes the prediction spike (two T(L) jumps); the paper removed
    glitch rows, so the spike is neither a predicted nor a missed snap. Elsewhere events still count."""
    n = 100
    ref = np.zeros(n)
    ref[60:] = 40.0                                                   # one true snap at row 60
    pred = ref.copy()
    pred[30] = 25.0                                                   # the spike of a glitch at row 30
    outlier = np.zeros(n, bool)
    outlier[30] = True
    bounds, direction = [(0, n)], np.ones(n)
    assert snap_report(pred, ref, bounds, direction)["precision"] == 0.5      # the spike: one event
    keep = ~glitch_window(outlier, bounds)
    np.testing.assert_array_equal(np.nonzero(~keep)[0], [30, 31, 32, 33])
    r = snap_report(pred, ref, bounds, direction, keep)
    assert r["n_predicted"] == 1 and r["precision"] == 1.0 and r["recall"] == 1.0
