"""The cleaning rules of the paper (Sec. III.A) on small arrays with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.data import cleaning
from ctrkin.data.cleaning import CleaningConfig
from ctrkin.errors import DatasetError

CFG = CleaningConfig()


def _sweep_joints(m: int = 40, step: float = 2.0) -> np.ndarray:
    q = np.zeros((m, 4))
    q[:, 0] = np.arange(m) * step
    q[:, 2] = -12.0
    return q


def test_repeat_groups_by_identical_joints_or_by_step():
    q = np.repeat(_sweep_joints(4), 3, axis=0)
    seq = np.zeros(12, dtype=int)
    np.testing.assert_array_equal(cleaning.repeat_groups(seq, q, None, 1e-6), np.repeat(np.arange(4), 3))
    seq[6:] = 1  # a new sequence always starts a new sample
    q[3:6] = q[0]
    np.testing.assert_array_equal(cleaning.repeat_groups(seq, q, None, 1e-6), [0, 0, 0, 0, 0, 0, 1, 1, 1,
                                                                               2, 2, 2])
    # a step groups readings only where their joints agree too (issue 27 item 9: readings of two
    # configurations that the log numbered as one step were averaged into a pose neither had)
    step = np.array([0, 0, 1, 1, 1, 2, 2, 3, 3, 3, 4, 4])
    np.testing.assert_array_equal(cleaning.repeat_groups(np.zeros(12, int), q, step, 1e-6),
                                  [0, 0, 1, 1, 1, 2, 3, 4, 4, 5, 6, 6])
    np.testing.assert_array_equal(np.nonzero(cleaning.distinct_in_step(np.zeros(12, int), q, step, 1e-6))[0],
                                  [6, 9])


def test_average_rejects_a_bad_reading_and_estimates_noise():
    rng = np.random.default_rng(0)
    s, r, sigma = 300, 5, 0.05
    groups = np.repeat(np.arange(s), r)
    truth = rng.normal(scale=10.0, size=(s, 3))
    pos = truth[groups] + rng.normal(scale=sigma, size=(s * r, 3))
    pos[7] += [0.0, 6.0, 0.0]  # one tracker glitch among the readings of sample 1
    tangent = np.tile([0.0, 0.0, 1.0], (s * r, 1))
    joints = np.repeat(_sweep_joints(s), r, axis=0)
    out = cleaning.average_readings(groups, joints, pos, tangent, CFG)
    assert out.rejected == 1
    np.testing.assert_array_equal(out.n_readings[:3], [5, 4, 5])
    assert np.abs(out.position - truth).max() < 5 * sigma
    np.testing.assert_allclose(out.position[0], pos[:5].mean(axis=0))
    assert out.position_std_mm == pytest.approx(sigma, rel=0.05)
    np.testing.assert_array_equal(out.first, np.arange(s) * r)


def test_average_of_tangents_is_the_normalised_mean():
    tangent = np.array([[0.1, 0.0, 1.0], [-0.1, 0.0, 1.0]])
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    out = cleaning.average_readings(np.zeros(2, int), np.zeros((2, 4)), np.zeros((2, 3)), tangent, CFG)
    np.testing.assert_allclose(out.tangent, [[0.0, 0.0, 1.0]], atol=1e-12)
    assert out.tangent_std_deg == pytest.approx(np.degrees(np.arctan(0.1)) * np.sqrt(2))


def test_glitch_is_a_spike_not_a_step():
    q = _sweep_joints()
    q[10, 0] += 90.0   # encoder glitch on alpha_1
    q[25, 2] -= 4.0    # encoder glitch on beta_1
    q[30:, 3] = -3.0   # a real motion of beta_2: a step, kept
    q[30:, 2] = -15.0
    np.testing.assert_array_equal(np.nonzero(cleaning.glitch_mask(q, 2, CFG))[0], [10, 25])


def test_glitch_threshold_follows_the_joint_step_size():
    q = _sweep_joints(step=10.0)
    q[10, 0] += 30.0  # three steps off: below 5 typical steps, so not a glitch
    assert not cleaning.glitch_mask(q, 2, CFG).any()
    q[10, 0] += 30.0  # six steps off
    assert np.nonzero(cleaning.glitch_mask(q, 2, CFG))[0].tolist() == [10]


def test_pose_outlier_is_a_spike_and_a_snap_is_kept():
    rng = np.random.default_rng(1)
    t = np.linspace(0, np.pi, 60)
    pos = np.column_stack([10 * np.cos(t), 10 * np.sin(t), 50 + t]) + rng.normal(scale=0.03, size=(60, 3))
    pos[40:, :2] *= -1  # a snap: the tip jumps to the other side and stays
    tangent = np.tile([0.0, 0.0, 1.0], (60, 1))
    assert not cleaning.pose_outlier_mask(pos, tangent, CFG).any()
    pos[20] += [0.0, 0.0, 3.0]
    tangent[33] = [np.sin(0.5), 0.0, np.cos(0.5)]  # 29° off its neighbours
    np.testing.assert_array_equal(np.nonzero(cleaning.pose_outlier_mask(pos, tangent, CFG))[0], [20, 33])


def test_snaps_follow_the_papers_10_degree_definition():
    m = 30
    q = _sweep_joints(m, step=1.0)
    az = np.radians(np.r_[np.arange(15) * 1.0, 100 + np.arange(15) * 1.0])  # T(L) jumps by 86° at 15
    pos = np.column_stack([8 * np.cos(az), 8 * np.sin(az), np.full(m, 55.0)])
    np.testing.assert_array_equal(np.nonzero(cleaning.snap_mask(q, pos, 2, CFG))[0], [15])
    big = q.copy()
    big[15:, 0] += 40.0  # a 40° joint step: not a snap by the definition
    assert not cleaning.snap_mask(big, pos, 2, CFG).any()
    assert not cleaning.snap_mask(q, pos * [0.1, 0.1, 1.0], 2, CFG).any()  # tip on the axis


@pytest.mark.parametrize("kw, msg", [({"mad_k": 0.0}, "mad_k must be a positive number"),
                                     ({"pose_window": 4}, "pose_window must be an odd integer"),
                                     ({"outliers": "hide"}, "outliers must be 'drop' or 'flag'"),
                                     ({"snap_min_radius_mm": -1.0}, "snap_min_radius_mm must be >= 0")])
def test_cleaning_config_is_validated(kw, msg):
    with pytest.raises(DatasetError, match=msg):
        CleaningConfig(**kw)


def test_pose_rule_does_not_reach_across_joint_jumps():
    """Two sweeps in one sequence, the second starting far away: no sample of either is an outlier
    (the window of a sweep's last samples would otherwise mix the two motions)."""
    from ctrkin.data.cleaning import CleaningConfig, continuous_runs, pose_outlier_mask

    a = np.arange(-45.0, 50.0, 5.0)
    joints = np.zeros((2 * len(a), 4))
    joints[:, 0] = np.r_[a, a]
    joints[len(a):, 2] = 5.0
    ang = np.radians(joints[:, 0])
    pos = np.column_stack([20 * np.cos(ang), 20 * np.sin(ang), 100 + 10 * (joints[:, 2] > 0)])
    cfg = CleaningConfig()
    runs = continuous_runs(joints, 2, cfg)
    assert runs == [(0, len(a)), (len(a), 2 * len(a))]
    assert not any(pose_outlier_mask(pos[r0:r1], np.tile([0, 0, 1.0], (r1 - r0, 1)), cfg).any()
                   for r0, r1 in runs)
