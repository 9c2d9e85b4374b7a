"""An uncertainty.npz written by main dbab9a8 (format 1, before an IK's OOD score took the robot's
joints; tests/inference/old_folders/make_old_uncertainty.py made it) loads with the score it had:
the target pose alone, the same scores in batch and streaming, any joints given ignored. And a
follow IK's joint-aware score streams as it predicts in batch, its own answers standing in for the
robot's joints. Format-2 files (main 458d7e8: parts as column boundaries) keep their scores too."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from ctrkin.data.schema import sequence_bounds
from ctrkin.inference import Kinematics
from ctrkin.models.uncertainty import Uncertainty

OLD = Path(__file__).parent / "old_folders"


def test_a_format_1_ik_uncertainty_keeps_its_pose_score(tmp_path):
    folder = tmp_path / "ik"
    shutil.copytree(OLD / "main_94a32c9" / "ik_lstm_mlp", folder)
    shutil.copy(OLD / "main_dbab9a8" / "ik_lstm_mlp" / "uncertainty.npz", folder)
    inputs = np.load(OLD / "main_94a32c9" / "inputs.npz")
    expected = np.load(OLD / "main_dbab9a8" / "expected.npz")
    kin = Kinematics.load(folder)
    assert kin.uncertainty is not None and kin.uncertainty.inputs == "pose"
    assert not kin.uncertainty.scores_joints
    rows = expected["test_rows"]
    poses, joints = inputs["poses"][rows], inputs["joints"][rows]
    batch = kin.predict_uncertain(poses, joints=joints)
    np.testing.assert_allclose(batch.ood_score, expected["batch"], rtol=0, atol=1e-9)
    kin.reset()
    steps = [kin.step_uncertain(p, joints=q).ood_score for p, q in zip(poses, joints, strict=True)]
    np.testing.assert_allclose(steps, expected["stream"], rtol=0, atol=1e-9)
    kin.uncertainty.save(folder)                     # written again: format 3, the same score
    again = Kinematics.load(folder)
    assert again.uncertainty is not None and again.uncertainty.inputs == "pose"
    np.testing.assert_allclose(again.predict_uncertain(poses).ood_score, expected["batch"], rtol=0, atol=1e-9)


def test_follow_ik_streams_its_joint_aware_score_as_in_batch():
    inputs = np.load(OLD / "main_94a32c9" / "inputs.npz")
    sid, poses, joints = inputs["sequence_id"], inputs["poses"], inputs["joints"]
    bounds = sequence_bounds(sid)
    kin = Kinematics.load(OLD / "main_94a32c9" / "ik_follow_mlp")
    before = np.r_[joints[:1], joints[:-1]]                        # the joints when each pose was asked
    x = np.hstack([poses, before])
    train = np.arange(bounds[3][0])
    cal = np.arange(bounds[3][0], bounds[5][0])
    kin.uncertainty = Uncertainty.fit("ik", 2, x[train], sequence_bounds(sid[train]), x[cal],
                                      sequence_bounds(sid[cal]), np.zeros((len(cal), 4)), max_reference=200)
    a, b = bounds[5]
    start = joints[a]
    batch = kin.predict_uncertain(poses[a:b], start_joints=start)
    kin.reset(joints=start)
    stream = [kin.step_uncertain(p) for p in poses[a:b]]
    np.testing.assert_allclose([s.ood_score for s in stream], batch.ood_score, rtol=0, atol=1e-9)
    np.testing.assert_allclose([s.value.joints for s in stream], batch.value.joints, rtol=0, atol=1e-9)
    given = kin.predict_uncertain(poses[a:b], joints=before[a:b])  # the encoders' joints instead
    kin.reset(joints=start)
    streamed = [kin.step_uncertain(p, joints=q).ood_score
                for p, q in zip(poses[a:b], before[a:b], strict=True)]
    np.testing.assert_allclose(streamed, given.ood_score, rtol=0, atol=1e-9)


def test_format_2_uncertainties_keep_their_parts_and_scores(tmp_path):
    # written by main 458d7e8 (tests/inference/old_folders/make_format2_uncertainty.py): parts saved as
    # (P + 1,) boundaries, read as the spans between them; the same scores, batch and stream, and again
    # once saved as format 3
    inputs = np.load(OLD / "main_94a32c9" / "inputs.npz")
    expected = np.load(OLD / "main_458d7e8" / "expected.npz")
    joints, rows = inputs["joints"], expected["test_rows"]
    before = np.r_[joints[rows[:1]], joints[rows[:-1]]]               # the joints when each pose was asked
    x = {"fk": joints[rows], "ik": np.hstack([inputs["poses"][rows], before])}
    for task, n_parts in (("fk", 2), ("ik", 4)):
        unc = Uncertainty.load(OLD / "main_458d7e8" / f"{task}_lstm_mlp")
        assert unc is not None and unc.parts.shape == (n_parts, 2)
        assert np.array_equal(unc.parts[1:, 0], unc.parts[:-1, 1])      # they tile the columns, as before
        batch = unc.ood_scores(x[task], [(0, len(rows))])
        assert np.array_equal(batch, expected[f"{task}_batch"])
        st = unc.stream()
        steps = [st.step(r) if task == "fk" else st.step(r[:6], r[6:]) for r in x[task]]
        assert np.array_equal(steps, expected[f"{task}_stream"])
        unc.save(tmp_path)
        again = Uncertainty.load(tmp_path)
        assert again is not None and np.array_equal(again.parts, unc.parts)
        assert int(np.load(tmp_path / "uncertainty.npz")["format"]) == 3
        assert np.array_equal(again.ood_scores(x[task], [(0, len(rows))]), batch)
