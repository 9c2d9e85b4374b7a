"""Snap scoring (T(L) rule, event matching, windows) on hand-computed cases."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.evaluation.snapping import (
    azimuth_series,
    glitch_window,
    rotation_direction,
    snap_event_rows,
    snap_report,
    snap_score,
    snap_steps,
    snap_window,
)


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


def test_snap_magnitude_error_is_an_angle_difference() -> None:
    """A jump across the axis read as +170° by the prediction and −175° by the reference lands 15° apart
    (not 345°); a plain size error stays as it is."""
    ref = np.r_[np.zeros(10), np.full(10, -175.0), np.zeros(10), np.full(10, 40.0)]
    pred = np.r_[np.zeros(10), np.full(10, 170.0), np.zeros(10), np.full(10, 30.0)]
    s = snap_score(pred, ref, [(0, 20), (20, 40)])
    assert s.n_matched == 2
    assert s.magnitude_error_deg == pytest.approx((15.0 + 10.0) / 2)


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


def test_a_snap_over_two_steps_is_one_event() -> None:
    # jumps of 12° and 15° at rows 10 and 11 (one snap over two steps; threshold 10°), −27° at row 21
    az = np.r_[np.zeros(10), np.full(1, 12.0), np.full(10, 27.0), np.zeros(5)]
    events = snap_event_rows(az, [(0, len(az))])
    assert events.tolist() == [10, 21]
