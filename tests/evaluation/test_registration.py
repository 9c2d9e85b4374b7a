"""Rigid registration recovers a known transform; the TCM baseline is the point-wise solve."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ctrkin import paper_robot, solve
from ctrkin.evaluation.registration import Registration
from ctrkin.evaluation.tcm_baseline import TCMBaseline
from ctrkin.pose import tangent_angle_error


def test_fit_recovers_rotation_and_translation(rng) -> None:
    rot = Rotation.from_rotvec([0.02, -0.01, 0.3]).as_matrix()
    t = np.array([1.0, -2.0, 0.5])
    a = rng.normal(0, 10, (50, 3))
    reg = Registration.fit(a, a @ rot.T + t)
    np.testing.assert_allclose(reg.rotation, rot, atol=1e-12)
    np.testing.assert_allclose(reg.translation, t, atol=1e-10)
    assert reg.rms_mm < 1e-10


def test_apply_rotates_tangents() -> None:
    rot = Rotation.from_rotvec([0.0, 0.2, 0.0]).as_matrix()
    reg = Registration(rot, np.zeros(3))
    pose = np.array([[0, 0, 10.0, 1.0, 0, 0]])
    out = reg.apply(pose)
    np.testing.assert_allclose(out[0, :3], rot @ [0, 0, 10.0])
    assert abs(tangent_angle_error(out, pose)[0] - np.degrees(0.2)) < 1e-9


def test_tcm_baseline_fits_registration_and_times_points(rng) -> None:
    robot = paper_robot()
    Q = np.array([[a, 0.0, -10.0, -2.0] for a in np.linspace(0, 300, 12)])
    truth = np.array([solve(robot, q).tip_pose for q in Q])
    rot = Rotation.from_rotvec([0.01, 0.02, -0.5]).as_matrix()
    measured = Registration(rot, np.array([3.0, 1.0, -4.0])).apply(truth)
    tcm = TCMBaseline(robot)
    reg = tcm.fit_registration(Q, measured)
    assert reg.rms_mm < 1e-6
    pred = tcm.predict(Q)
    np.testing.assert_allclose(pred[:, :3], measured[:, :3], atol=1e-6)
    assert tcm.last_times.shape == (12,) and (tcm.last_times > 0).all()
