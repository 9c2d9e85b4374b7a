"""The tracker-frame position field (ctrkin.models.field) and the equivariant FK inputs it goes with."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.errors import ModelError
from ctrkin.models.features import FeatureLayout, sequence_features
from ctrkin.models.field import PositionField, exponents


def _smooth(p: np.ndarray) -> np.ndarray:
    """A smooth warp (mm) over a 40 mm workspace: what a polynomial of degree 3 holds exactly."""
    u = p / 20.0
    return np.column_stack([0.8 * u[:, 0] * u[:, 1] - 0.3 * u[:, 2] ** 3, 0.5 * u[:, 0] ** 2 * u[:, 2],
                            0.4 * u[:, 1] - 0.2 * u[:, 0] * u[:, 1] * u[:, 2]])


def test_the_field_recovers_a_smooth_warp_and_chooses_its_degree_by_cross_validation(rng):
    p = rng.uniform(-20.0, 20.0, (3000, 3)) + np.array([0.0, 0.0, 60.0])
    measured = p + _smooth(p) + rng.normal(0.0, 0.02, p.shape)
    groups = np.repeat(np.arange(30), 100)                         # 30 "sequences"
    f = PositionField.fit(p, measured, groups)
    assert f.degree >= 3
    held = rng.uniform(-18.0, 18.0, (500, 3)) + np.array([0.0, 0.0, 60.0])
    err = np.linalg.norm(f(held) - _smooth(held), axis=1)
    assert np.sqrt(np.mean(err ** 2)) < 0.02                       # the warp, not the noise
    assert f.cv_rms_mm < 0.1 * f.cv_rms_without_mm
    again = PositionField.from_dict(f.to_dict())
    np.testing.assert_array_equal(again(held), f(held))
    pose = np.r_[held[0], 1.0, 0.0, 0.0]
    # the streaming kernel (repeated products) against numpy's powers: the same w to round-off
    np.testing.assert_allclose(f.apply_one(pose.copy())[:3], held[0] + f(held[:1])[0], rtol=0, atol=1e-12)
    rows = np.column_stack([held, np.tile([1.0, 0.0, 0.0], (len(held), 1))])
    want = np.array([f.apply_one(r.copy()) for r in rows])
    np.testing.assert_array_equal(f.apply_rows(rows.copy()), want)


def test_no_field_is_chosen_where_the_residuals_are_noise(rng):
    p = rng.uniform(-20.0, 20.0, (2000, 3))
    f = PositionField.fit(p, p + rng.normal(0.0, 0.1, p.shape), np.repeat(np.arange(20), 100))
    assert np.sqrt(np.mean(np.sum(f(p) ** 2, axis=1))) < 0.03
    assert exponents(2).shape == (10, 3) and exponents(4).shape == (35, 3)
    with pytest.raises(ModelError, match="at least 10"):
        PositionField.fit(p[:5], p[:5], np.zeros(5))
    with pytest.raises(ModelError, match="position-field"):
        PositionField.from_dict({"centre": [0, 0]})


def test_equivariant_inputs_do_not_change_when_every_tube_turns_alike(rng):
    lay = FeatureLayout(task="fk", n_tubes=3, ib=2, angle_encoding="phase", equivariant=True)
    assert "alpha_1" not in lay.input_names and "alpha_3" not in lay.input_names
    assert "alpha_2_rel" in lay.input_names
    q = np.column_stack([np.cumsum(rng.normal(0, 5, 50)), np.cumsum(rng.normal(0, 5, 50)),
                         np.cumsum(rng.normal(0, 5, 50)), np.full(50, -30.0), np.full(50, -20.0),
                         np.full(50, -5.0)])
    turned = q.copy()
    turned[:, :3] += 73.0
    np.testing.assert_allclose(sequence_features(lay, q, [(0, 50)]),
                               sequence_features(lay, turned, [(0, 50)]), rtol=0, atol=1e-9)
    with pytest.raises(ModelError, match="equivariant"):
        FeatureLayout(task="fk", angle_encoding="sincos", equivariant=True)


def test_an_equivariant_fk_fits_its_field_and_streams_what_it_predicts(sweeps, tmp_path):
    from ctrkin.inference import Kinematics
    from ctrkin.inference.onnx_export import export_onnx
    from ctrkin.training import TrainConfig, train

    cfg = TrainConfig(task="fk", max_epochs=2, threads=1, equivariant=True, target_frame="outer",
                      angle_encoding="phase", options={"structure": "L16|D16"})
    train(sweeps, cfg, tmp_path / "fk", progress=False)
    kin = Kinematics.load(tmp_path / "fk")
    frame = kin.predictor.frame
    assert frame is not None and frame.field is not None and not kin.predictor.fused
    a, b = sweeps.sequence_bounds()[0]
    q = sweeps.joints()[a:b]
    batch = np.asarray(kin.predict(q))
    kin.reset()
    np.testing.assert_allclose(batch, np.array([kin.step(r) for r in q]), rtol=0, atol=1e-4)
    with pytest.raises(ModelError, match="equivariant"):
        export_onnx(kin, tmp_path / "fk.onnx")
