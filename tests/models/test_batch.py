"""FK predict's one-pass features and poses (ctrkin.models.batch.fk_padded_rows, fk_poses) equal the
numpy path they replace (sequence_features, clip_deltas, MinMax, padded_rows; MinMax.inverse,
postprocess), and a model's predict is unchanged by them."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.inference import Kinematics
from ctrkin.models.batch import fk_padded_rows, fk_poses, padded_rows
from ctrkin.models.features import FeatureLayout, delta_columns, postprocess, sequence_features
from ctrkin.models.normalize import MinMax


@pytest.mark.parametrize(("encoding", "ib", "delta"), [("minmax", 2, True), ("phase", 3, True),
                                                        ("minmax", 1, False)])
def test_fk_padded_rows_equals_the_numpy_path(encoding, ib, delta, rng):
    layout = FeatureLayout(task="fk", n_tubes=2, ib=ib, delta=delta, angle_encoding=encoding)
    raw = np.c_[np.cumsum(rng.normal(0, 6, (50, 2)), axis=0), rng.uniform(-30, 0, (50, 2))]
    bounds = [(0, 1), (1, 20), (20, 50)]                 # a one-row sequence, shorter than the buffer
    norm = MinMax.fit(sequence_features(layout, raw[10:14], [(0, 4)]))     # deltas outside its range
    cols = delta_columns(layout)
    lo, hi = norm.lo[cols], norm.hi[cols]
    feats = sequence_features(layout, raw, bounds)
    if delta:
        assert ((feats[:, cols] < lo) | (feats[:, cols] > hi)).any()     # the clip is exercised
        feats[:, cols] = np.clip(feats[:, cols], lo, hi)
    ref, ref_starts = padded_rows(norm.transform(feats), bounds, ib)
    starts = np.array([0, 1, 20, 50], dtype=np.int64)
    d = (float(lo[0]), float(hi[0])) if delta else (0.0, 0.0)
    got, got_starts = fk_padded_rows(raw, starts, ib, 2, encoding == "phase", delta, norm.lo, norm.span, *d)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got_starts, ref_starts)
    np.testing.assert_allclose(got, ref.astype(np.float32), rtol=0, atol=1e-6)


def test_fk_poses_equals_inverse_and_postprocess(rng):
    layout = FeatureLayout(task="fk")
    norm = MinMax(rng.normal(0, 5, 6), rng.uniform(0.5, 3, 6))
    yn = rng.random((40, 6)).astype(np.float32)
    yn[3, 3:6] = 0.0                                       # a zero quaternion stays as it is
    ref = postprocess(layout, norm.inverse(yn))
    np.testing.assert_allclose(fk_poses(yn, norm.lo, norm.span), ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["fk", "fk_default"])
def test_predict_unchanged_by_the_one_pass_path(model_dirs, sweeps, name):
    """A model's predict through the one-pass path equals the numpy path: a Dataset of several
    sequences and an array split by sequence_id."""
    kin = Kinematics.load(model_dirs[name])
    pred = kin.predictor
    assert pred._chains_fast
    joints = sweeps.joints()[:300]
    sid = np.repeat([0, 1, 2], [1, 120, 179])
    fast = kin.predict(sweeps), kin.predict(joints, sequence_id=sid), kin.predict(joints)
    pred._chains_fast = False
    slow = kin.predict(sweeps), kin.predict(joints, sequence_id=sid), kin.predict(joints)
    for a, b in zip(fast, slow, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
