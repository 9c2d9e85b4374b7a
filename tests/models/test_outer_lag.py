"""The outer tube's lag from the data: recovered from synthetic turns with a known lag, and zero
where the data has no rows at rest to compare with."""

from __future__ import annotations

import numpy as np
import pytest

import ctrkin
from ctrkin.geometry import Registration
from ctrkin.models.frame import OuterFrame
from ctrkin.models.outer_lag import fit_outer_lag, lag_deg
from ctrkin.robots.overlap import curved_overlap

A, B = 0.75, 0.40          # λ = A + B·overlap, deg and deg/mm (the virtual robot's half dead band)


def _turns(robot, motions=(0, 1, 1, -1), noise_deg=0.0, seed=0):
    """Inner turns 0 -> 360 -> 0 at four translation sets, one per outer state in `motions`; tip
    positions in the frame of the commanded αN: the outer tube's bend (3 mm along x) plus the inner
    tube's (2 mm at the tubes' relative angle φ + λ·m), turned by −λ·m."""
    rng = np.random.default_rng(seed)
    inner = np.r_[np.arange(361.0), np.arange(359.0, -1.0, -1.0)]
    rows, motion, bounds = [], [], []
    for d in (4.0, 10.0, 15.0, 20.0):
        for k, m in enumerate(motions):
            q = np.zeros((len(inner), 4))
            q[:, 0], q[:, 1], q[:, 2], q[:, 3] = inner, 60.0 * k, -d, 0.0
            bounds.append((len(motion), len(motion) + len(q)))
            rows.append(q)
            motion.extend([m] * len(q))
    J, motion = np.concatenate(rows), np.array(motion, np.int8)
    lam = A + B * curved_overlap(robot, J)
    phi_tube = np.radians(J[:, 0] - J[:, 1] + lam * motion)
    x, y = 3.0 + 2.0 * np.cos(phi_tube), 2.0 * np.sin(phi_tube)
    turn = np.radians(-lam * motion + rng.normal(0.0, noise_deg, len(J)))
    c, s = np.cos(turn), np.sin(turn)
    local = np.c_[c * x - s * y, s * x + c * y, np.full(len(J), 100.0)]
    return J, local, motion, bounds


def test_lag_of_synthetic_turns_is_recovered():
    robot = ctrkin.paper_robot()
    J, local, motion, bounds = _turns(robot, noise_deg=1.0)
    a, b = fit_outer_lag(robot, J, local, motion, bounds, np.ones(len(J), bool))
    assert a == pytest.approx(A, abs=0.05) and b == pytest.approx(B, abs=0.01)


def test_matching_at_equal_commanded_angles_would_underestimate():
    """The fixed point matters: one matching step at equal commanded φ misses the part of λ by which
    the tip turns with the tubes' relative angle."""
    import ctrkin.models.outer_lag as ol

    robot = ctrkin.paper_robot()
    J, local, motion, bounds = _turns(robot)
    saved = ol.ITERATIONS
    try:
        ol.ITERATIONS = 1
        _, b = fit_outer_lag(robot, J, local, motion, bounds, np.ones(len(J), bool))
    finally:
        ol.ITERATIONS = saved
    assert b < 0.8 * B


def test_no_rows_at_rest_or_not_used_means_no_lag():
    robot = ctrkin.paper_robot()
    J, local, motion, bounds = _turns(robot, motions=(1, 1, -1, 1))
    assert fit_outer_lag(robot, J, local, motion, bounds, np.ones(len(J), bool)) == (0.0, 0.0)
    J, local, motion, bounds = _turns(robot)
    assert fit_outer_lag(robot, J, local, motion, bounds, motion != 0) == (0.0, 0.0)


def test_frame_turns_with_the_lagged_outer_tube_and_keeps_old_files():
    robot = ctrkin.paper_robot()
    reg = Registration(np.eye(3), np.zeros(3), 0.0)
    frame = OuterFrame(reg, (A, B))
    q = np.array([[0.0, 30.0, -20.0, 0.0], [0.0, 30.0, -4.0, 0.0]])
    lam = lag_deg(robot, q, (A, B))
    assert lam == pytest.approx([A + B * 14.5, A])
    np.testing.assert_allclose(frame.outer_angle(robot, q, np.array([1, -1])), 30.0 - lam * [1, -1])
    np.testing.assert_allclose(frame.outer_angle(robot, q, 0), [30.0, 30.0])
    back = OuterFrame.from_dict(frame.to_dict())
    assert back.lag == (A, B)
    old = {k: v for k, v in frame.to_dict().items() if k != "outer_lag_deg"}
    assert OuterFrame.from_dict(old).lag == (0.0, 0.0) and not OuterFrame.from_dict(old).has_lag


def test_lagged_inputs_replace_the_outer_angle_and_older_frames_keep_theirs():
    """OuterFrame.network_joints: αN becomes the frame's angle only for a lagged frame with
    lagged_inputs; folders without the key (before it) keep commanded inputs."""
    reg = Registration(np.eye(3), np.zeros(3), 0.0)
    q = np.array([[10.0, 30.0, -20.0, 0.0], [5.0, 31.0, -4.0, 0.0]])
    angles = np.array([24.0, 32.0])
    lagged = OuterFrame(reg, (A, B), lagged_inputs=True)
    np.testing.assert_array_equal(lagged.network_joints(q, angles), [[10.0, 24.0, -20.0, 0.0],
                                                                   [5.0, 32.0, -4.0, 0.0]])
    assert q[0, 1] == 30.0                                           # the caller's joints untouched
    for frame in (OuterFrame(reg, (A, B)), OuterFrame(reg, (0.0, 0.0), lagged_inputs=True)):
        assert frame.network_joints(q, angles) is q
    assert OuterFrame.from_dict(lagged.to_dict()).lags_inputs
    old = {k: v for k, v in lagged.to_dict().items() if k != "lagged_inputs"}
    assert not OuterFrame.from_dict(old).lags_inputs
