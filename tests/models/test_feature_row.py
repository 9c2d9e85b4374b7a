"""The compiled one-step paper features (ctrkin.models.feature_row) equal sequence_features row by row,
for two and three tubes, with and without the phase pair and Δα0."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.models.feature_row import paper_feature_row
from ctrkin.models.features import FeatureLayout, sequence_features


@pytest.mark.parametrize(("n", "encoding", "delta"), [(2, "minmax", True), (2, "phase", True),
                                                       (3, "phase", False), (3, "minmax", True)])
def test_feature_row_equals_sequence_features(n, encoding, delta, rng):
    layout = FeatureLayout(task="fk", n_tubes=n, ib=2, delta=delta, angle_encoding=encoding)
    raw = np.c_[np.cumsum(rng.normal(0, 20, (40, n)), axis=0), rng.uniform(-30, 0, (40, n))]
    bounds = [(0, 15), (15, 40)]
    ref = sequence_features(layout, raw, bounds)
    got = np.full_like(ref, np.nan)
    for a, b in bounds:
        for t in range(a, b):
            prev = raw[t - 1] if t > a else raw[t]
            phase = encoding == "phase"
            a0 = paper_feature_row(raw[t], n, prev[0] - prev[n - 1], t > a, phase, delta, got[t])
            assert a0 == raw[t, 0] - raw[t, n - 1]
    np.testing.assert_array_equal(got, ref)
    if delta:
        assert (got[[0, 15], -1] == 0.0).all() and (got[1:15, -1] != 0.0).all()   # eq. (2) at a start
