"""Physical error metrics: position mm, tip-tangent angle deg, joint-space distances."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.pose import tip_pose
from ctrkin.training import joint_errors, pose_errors


def test_pose_errors_known_offsets():
    a = tip_pose(np.array([[0.0, 0.0, 50.0]] * 2), np.array([[0.0, 0.0, 1.0]] * 2))
    t = np.array([[np.sin(np.radians(3.0)), 0.0, np.cos(np.radians(3.0))]] * 2)
    b = tip_pose(np.array([[3.0, 4.0, 50.0], [0.0, 0.0, 50.0]]), t)
    e = pose_errors(a, b)
    assert e["position_mm_rmse"] == pytest.approx(np.sqrt(25 / 2))
    assert e["position_mm_max"] == pytest.approx(5.0)
    assert e["orientation_deg_mae"] == pytest.approx(3.0)


def test_pose_errors_of_position_only_data_have_no_orientation():
    """A position-only dataset's quaternion columns are placeholders: no orientation error is made up."""
    a = tip_pose(np.array([[0.0, 0.0, 50.0]]), np.array([[0.0, 1.0, 1.0]]))
    b = tip_pose(np.array([[3.0, 4.0, 50.0]]), np.array([[0.0, 0.0, 1.0]]))
    e = pose_errors(a, b, orientation=False)
    assert e == {"position_mm_rmse": pytest.approx(5.0), "position_mm_mae": pytest.approx(5.0),
                 "position_mm_max": pytest.approx(5.0), "n": 1}


def test_joint_errors_euclidean_per_sample_and_wrapped():
    ref = np.array([[1.0, 0.0, -10.0, 0.0], [0.0, 0.0, -10.0, 0.0]])
    pred = np.array([[359.0, 0.0, -13.0, -4.0], [3.0, 4.0, -10.0, 0.0]])
    e = joint_errors(pred, ref, 2)
    assert e["beta_mm_max"] == pytest.approx(5.0)
    assert e["alpha_deg_max"] == pytest.approx(358.0)
    assert e["alpha_wrapped_deg_rmse"] == pytest.approx(np.sqrt((4 + 25) / 2))
