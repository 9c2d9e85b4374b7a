"""Split-conformal intervals and the OOD score (ctrkin.models.uncertainty): the conformal rank, the
coverage on exchangeable errors, streaming equal to batch, the file round trip."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ctrkin.errors import ModelError
from ctrkin.models.uncertainty import (
    HISTORY,
    Uncertainty,
    conformal_radius,
    grouped_radius,
    sequence_features,
)


def _walks(rng: np.random.Generator, count: int, steps: int, d: tuple[float, float] = (4.0, 12.0),
           step_deg: float = 3.0) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Random joint walks (count·steps, 4) of a two-tube robot and their sequences."""
    rows, bounds = [], []
    for k in range(count):
        a = np.cumsum(rng.uniform(-step_deg, step_deg, (steps, 2)), axis=0) + rng.uniform(-180, 180, 2)
        d_t = np.clip(rng.uniform(*d) + np.cumsum(rng.uniform(-0.1, 0.1, steps)), *d)
        rows.append(np.column_stack([a, -d_t, np.zeros(steps)]))
        bounds.append((k * steps, (k + 1) * steps))
    return np.vstack(rows), bounds


def test_conformal_radius_is_the_stated_rank():
    s = np.arange(1.0, 20.0)                     # n = 19: ⌈20·0.9⌉ = 18th smallest
    assert conformal_radius(s, 0.9) == 18.0
    assert conformal_radius(np.arange(5.0), 0.9) == math.inf      # too few for the level


def test_grouped_radius_weighs_sequences_alike():
    # 19 sequences of one row each: the row-wise rank; one long sequence of large errors counts once
    s = np.arange(1.0, 20.0)
    assert grouped_radius(s, [(i, i + 1) for i in range(19)], 0.9) == conformal_radius(s, 0.9)
    long = np.r_[s, np.full(100, 50.0)]
    runs = [(i, i + 1) for i in range(19)] + [(19, 119)]
    assert grouped_radius(long, runs, 0.9) == 19.0          # m = 20: level 0.945, weight 1/20 each


def test_fk_intervals_cover_exchangeable_errors():
    rng = np.random.default_rng(0)
    x, b = _walks(rng, 8, 50)
    cal_x, cal_b = _walks(rng, 150, 10)                    # m = 150 sequences: level 0.9·151/150
    unc = Uncertainty.fit("fk", 2, x, b, cal_x, cal_b, rng.normal(0, 0.3, (len(cal_x), 3)))
    test = rng.normal(0, 0.3, (20000, 3))
    cover = unc.covers(test, np.zeros_like(test)).mean()
    assert 0.88 <= cover <= 0.92
    few_x, few_b = _walks(rng, 8, 50)                      # 8 sequences cannot give 90 %: (8+1)/8·0.9 > 1
    assert Uncertainty.fit("fk", 2, x, b, few_x, few_b, np.zeros((len(few_x), 3))).radius == math.inf
    assert unc.half_widths().shape == (3,)


def test_ik_box_scales_by_joint_and_wraps_angles():
    rng = np.random.default_rng(1)
    x, b = _walks(rng, 4, 40)
    pose_x = np.hstack([rng.normal(0, 1, (len(x), 6)), x])          # the target pose and the joints
    err = rng.normal(0, 1, (len(x), 4)) * np.array([5.0, 5.0, 0.2, 0.2])
    unc = Uncertainty.fit("ik", 2, pose_x, b, pose_x, b, err)
    assert unc.joint_scale[0] > 10 * unc.joint_scale[2]          # deg against mm
    q = np.array([[0.0, 0.0, -5.0, 0.0]])
    assert unc.covers(q + np.array([360.0, 0, 0, 0]), q)[0]              # a whole turn is no error


def test_ood_score_grows_outside_the_trained_ranges_and_histories():
    rng = np.random.default_rng(2)
    x, b = _walks(rng, 40, 60)
    cal_x, cal_b = _walks(rng, 20, 60)
    unc = Uncertainty.fit("fk", 2, x, b, cal_x, cal_b, rng.normal(0, 0.3, (len(cal_x), 3)))
    held, hb = _walks(rng, 20, 60)
    far, fb = _walks(rng, 4, 60, d=(16.0, 20.0))            # beyond the trained translations
    fast, sb = _walks(rng, 4, 60, step_deg=15.0)            # steps five times larger
    inside = unc.ood_scores(held, hb)
    assert np.median(unc.ood_scores(far, fb)) > np.quantile(inside, 0.99)
    assert np.median(unc.ood_scores(fast, sb)) > np.quantile(inside, 0.99)
    assert np.mean(inside > unc.threshold) < 0.05         # 1 % on the calibration walks


def test_stream_equals_batch_and_file_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    x, b = _walks(rng, 4, 30)
    unc = Uncertainty.fit("fk", 2, x, b, x[:60], [(0, 30), (30, 60)], rng.normal(0, 1, (60, 3)))
    seq = x[30:60]
    batch = unc.ood_scores(seq, [(0, len(seq))])
    st = unc.stream()
    assert np.array_equal([st.step(q) for q in seq], batch)           # the same kernels: to the bit
    st.reset()
    assert st.step(seq[5]) == unc.ood_scores(seq[5:6], [(0, 1)])[0]
    assert np.array_equal(unc.ood_scores(seq, []), unc.ood_scores(seq, [(t, t + 1) for t in range(len(seq))]))
    unc.save(tmp_path)
    back = Uncertainty.load(tmp_path)
    assert back is not None and back.radius == unc.radius and back.threshold == unc.threshold
    assert np.array_equal(back.reference, unc.reference)
    assert Uncertainty.load(tmp_path / "nothing") is None
    assert sequence_features("joints", 2, seq, [(0, len(seq))]).shape[1] == 2 + 2 + HISTORY * 3


def test_ik_score_sees_joint_histories_the_pose_cannot():
    # the same poses with the joints walking, and with the inner tube also jumping back and forth by 12°
    # every step (the training walks' steps are ≤ 3° a tube): the joint-aware score flags that history,
    # which the poses do not show
    rng = np.random.default_rng(4)
    x, b = _walks(rng, 40, 60)
    cal_x, cal_b = _walks(rng, 20, 60)
    held, hb = _walks(rng, 20, 60)
    rev = held.copy()
    rev[:, 0] += np.tile(np.r_[0.0, 12.0], len(rev) // 2)
    poses = {k: rng.uniform(-1, 1, (len(v), 6)) for k, v in (("x", x), ("cal", cal_x), ("held", held))}
    err = np.zeros((len(cal_x), 4))
    unc = Uncertainty.fit("ik", 2, np.hstack([poses["x"], x]), b, np.hstack([poses["cal"], cal_x]), cal_b,
                          err)
    assert unc.inputs == "pose+joints" and len(unc.parts) == 5   # pose, joints, translations, the histories
    inside = unc.ood_scores(np.hstack([poses["held"], held]), hb)
    outside = unc.ood_scores(np.hstack([poses["held"], rev]), hb)
    assert np.median(outside) > np.quantile(inside, 0.99)
    with pytest.raises(ModelError, match="columns"):
        Uncertainty.fit("ik", 2, poses["x"], b, poses["cal"], cal_b, err)   # pose+joints needs the joints


def test_ik_stream_with_joints_equals_batch_and_round_trips(tmp_path):
    rng = np.random.default_rng(5)
    q, b = _walks(rng, 4, 30)
    x = np.hstack([rng.normal(0, 1, (len(q), 6)), q])
    for split in ("blocks", "config-history", "fine", "blocks+translations"):
        unc = Uncertainty.fit("ik", 2, x, b, x[:60], [(0, 30), (30, 60)], rng.normal(0, 1, (60, 4)),
                              split=split)
        seq = x[30:60]
        st = unc.stream()
        batch = unc.ood_scores(seq, [(0, len(seq))])
        assert np.array_equal([st.step(r[:6], r[6:]) for r in seq], batch)
        with pytest.raises(ModelError, match="joints"):
            st.step(seq[0, :6])
    unc.save(tmp_path)
    back = Uncertainty.load(tmp_path)
    assert back is not None and back.inputs == "pose+joints" and np.array_equal(back.parts, unc.parts)
    assert np.allclose(back.ood_scores(seq, [(0, len(seq))]), batch, atol=0)
    three = np.hstack([rng.normal(0, 1, (40, 6)), np.cumsum(rng.uniform(-3, 3, (40, 6)), axis=0)])  # N = 3
    unc3 = Uncertainty.fit("ik", 3, three, [(0, 40)], three[:20], [(0, 20)], np.zeros((20, 6)), split="fine")
    st3 = unc3.stream()
    assert np.array_equal([st3.step(r[:6], r[6:]) for r in three], unc3.ood_scores(three, [(0, 40)]))


def test_bad_level_refused():
    x = np.zeros((4, 4))
    with pytest.raises(ModelError, match="level"):
        Uncertainty.fit("fk", 2, x, [(0, 4)], x, [(0, 4)], np.zeros((4, 3)), level=1.5)
