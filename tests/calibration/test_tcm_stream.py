"""CalibratedTCM streamed one step at a time (TCMStream) against predict_continued, with friction:
the carried equilibrium gives the batch's poses, a reset starts again from rest."""

from __future__ import annotations

import dataclasses

import numpy as np

from ctrkin import paper_robot
from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.calibration.model import CalibratedTCM
from ctrkin.geometry import Registration


def _model() -> CalibratedTCM:
    robot = dataclasses.replace(paper_robot(), friction=0.3)
    c, s = np.cos(0.3), np.sin(0.3)
    reg = Registration(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), np.array([5.0, -2.0, 30.0]))
    return CalibratedTCM(robot, np.array([1.0, -2.0, 0.5, 0.0]), 1.5, reg)


def test_stream_equals_predict_continued_and_reset_starts_from_rest():
    tcm = _model()
    q = rotation_sweep(2, 14.0, step_deg=6.0, turns=0.5)      # forward and back: history matters
    batch = tcm.predict_continued(q, [(0, len(q))])
    assert np.isfinite(batch).all()
    stream = tcm.stream()
    np.testing.assert_allclose(np.array([stream.step(x) for x in q]), batch, atol=1e-6)
    # continued past the end, the state is the end's; after reset the first step is a fresh solve
    half = len(q) // 2
    stream.reset()
    from_rest = tcm.predict_continued(q[half:], [(0, len(q) - half)])
    np.testing.assert_allclose(stream.step(q[half]), from_rest[0], atol=1e-6)
    assert np.abs(batch[half, :3] - from_rest[0, :3]).max() > 1e-3    # the history was felt


def test_to_toml_reads_back(tmp_path):
    tcm = _model()
    path = tmp_path / "cal.toml"
    path.write_text(tcm.to_toml("paper-calibrated", purpose="a test", unused=None))
    back = CalibratedTCM.from_file(path)
    assert back.robot.name == "paper-calibrated"
    assert {**back.robot.to_dict(), "name": ""} == {**tcm.robot.to_dict(), "name": ""}
    np.testing.assert_array_equal(back.joint_offsets, tcm.joint_offsets)
    assert back.marker_mm == tcm.marker_mm
    np.testing.assert_allclose(back.registration.rotation, tcm.registration.rotation, atol=0)
    np.testing.assert_allclose(back.registration.translation, tcm.registration.translation, atol=0)
