"""Per-step features (eq. 1-2), windows that never cross sequences, min-max normalisation."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.errors import ModelError
from ctrkin.models.features import (
    FeatureLayout,
    postprocess,
    sequence_features,
    step_features,
    window_index,
    windows,
)
from ctrkin.models.normalize import MinMax


def test_paper_two_tube_feature_names_are_exact():
    lay = FeatureLayout(task="fk", n_tubes=2, ib=2)
    assert lay.input_names == ("alpha_1", "alpha_2", "beta_1", "beta_2", "alpha_0", "delta_alpha_0")
    assert lay.output_names == ("x", "y", "z", "q0", "qx", "qy")
    assert FeatureLayout(task="ik").output_names == ("alpha_1", "alpha_2", "beta_1", "beta_2")


def test_alpha0_and_delta_follow_eq_1_2_and_reset_at_sequence_start(rng):
    lay = FeatureLayout(task="fk", n_tubes=3, ib=2)
    q = np.c_[rng.uniform(0, 360, (10, 3)), rng.uniform(-30, -1, (10, 3))]
    bounds = [(0, 4), (4, 10)]
    f = sequence_features(lay, q, bounds)
    a0 = q[:, 0] - q[:, 2]                                   # α0 = α1 − αN
    np.testing.assert_allclose(f[:, 6], a0)
    np.testing.assert_allclose(f[:, :6], q)
    expected = np.r_[0.0, np.diff(a0[:4]), 0.0, np.diff(a0[4:])]
    np.testing.assert_allclose(f[:, 7], expected)
    for a, b in bounds:                                        # streaming twin, row by row
        for t in range(a, b):
            np.testing.assert_allclose(step_features(lay, q[t], q[t - 1] if t > a else None), f[t])


def test_sincos_and_ik_layouts(rng):
    lay = FeatureLayout(task="fk", n_tubes=2, angle_encoding="sincos")
    q = np.array([[90.0, 0.0, -10.0, 0.0], [180.0, 0.0, -10.0, 0.0]])
    f = sequence_features(lay, q, [(0, 2)])
    assert lay.input_names[:2] == ("sin_alpha_1", "cos_alpha_1")
    np.testing.assert_allclose(f[0, :2], [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(f[1, -1], 90.0)                # Δα0 stays in degrees
    ik = FeatureLayout(task="ik", n_tubes=2)
    p = rng.normal(size=(5, 6))
    g = sequence_features(ik, p, [(0, 5)])
    np.testing.assert_allclose(g[:, :6], p)
    np.testing.assert_allclose(g[1:, 6:], np.diff(p, axis=0))
    np.testing.assert_allclose(g[0, 6:], 0.0)
    with pytest.raises(ModelError, match="FK inputs only"):
        FeatureLayout(task="ik", angle_encoding="sincos")


def test_windows_pad_start_and_never_cross_a_boundary():
    feats = np.arange(7, dtype=float)[:, None]
    w = windows(feats, [(0, 3), (3, 7)], ib=3)[:, :, 0]
    np.testing.assert_array_equal(w, [[0, 0, 0], [0, 0, 1], [0, 1, 2],
                                      [3, 3, 3], [3, 3, 4], [3, 4, 5], [4, 5, 6]])
    assert window_index([(0, 2)], 1).tolist() == [[0], [1]]


def test_wrong_raw_width_is_refused():
    lay = FeatureLayout(task="fk", n_tubes=2)
    with pytest.raises(ModelError, match=r"\(T, 4\)"):
        sequence_features(lay, np.zeros((3, 6)), [(0, 3)])
    with pytest.raises(ModelError, match="ib"):
        FeatureLayout(ib=0)


def test_minmax_maps_training_rows_to_unit_interval(rng):
    x = np.c_[rng.uniform(-5, 7, 50), np.full(50, 3.0)]
    n = MinMax.fit(x)
    z = n.transform(x)
    np.testing.assert_allclose(z[:, 0].min(), 0.0)
    np.testing.assert_allclose(z[:, 0].max(), 1.0)
    np.testing.assert_allclose(z[:, 1], 0.0)                  # constant column: no division by zero
    np.testing.assert_allclose(n.inverse(z), x)
    again = MinMax.from_dict(n.to_dict())
    np.testing.assert_array_equal(again.lo, n.lo)


def test_postprocess_makes_unit_quaternions():
    lay = FeatureLayout(task="fk")
    y = postprocess(lay, np.array([[1.0, 2.0, 3.0, 0.9, 0.3, 0.1]]))
    np.testing.assert_allclose(np.linalg.norm(y[0, 3:]), 1.0)
    np.testing.assert_allclose(y[0, :3], [1, 2, 3])
