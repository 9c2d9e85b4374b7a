"""Follow-IK features, training perturbations and sub-steps (ctrkin.families.follow.features)."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.errors import ModelError
from ctrkin.families.follow.features import LAYOUT, follow_features, joint_noise, previous_rows, substeps
from ctrkin.models.features import FeatureLayout, sequence_features
from ctrkin.models.frame import OuterFrame
from ctrkin.pose import Registration, quat_from_tangent, tangent_from_quat


def _frame() -> OuterFrame:
    return OuterFrame(Registration(np.eye(3), np.array([1.0, -2.0, 3.0]), 0.0))


def test_layout_names_match_the_features():
    layout = FeatureLayout(task="ik", n_tubes=3, ib=1, family=LAYOUT)
    target = np.array([[10.0, 5.0, 80.0, *quat_from_tangent(np.array([0.1, 0.2, 1.0]))]])
    q = np.array([[30.0, 10.0, -20.0, -12.0, -8.0, -4.0]])
    f = follow_features(_frame(), 3, target, target, q)
    assert f.shape == (1, layout.n_inputs)
    assert layout.output_names == ("step_alpha_1", "step_alpha_2", "step_alpha_3", "step_beta_1",
                                   "step_beta_2", "step_beta_3")
    np.testing.assert_allclose(f[0, 6:12], 0.0)                      # no step at a start
    np.testing.assert_allclose(f[0, 12:16], [np.sin(np.radians(50)), np.cos(np.radians(50)),
                                             np.sin(np.radians(30)), np.cos(np.radians(30))])
    with pytest.raises(ModelError, match="current joints"):
        sequence_features(layout, target, [(0, 1)])
    with pytest.raises(ModelError, match="input buffer 1"):
        FeatureLayout(task="ik", ib=2, family=LAYOUT)


def test_features_turn_with_the_whole_robot():
    """Rotating the target and every tube by the same angle leaves the features unchanged
    (identity registration about the base axis)."""
    frame = OuterFrame(Registration(np.eye(3), np.zeros(3), 0.0))
    tan = np.array([0.2, 0.1, 1.0])
    p = np.array([[12.0, 4.0, 90.0, *quat_from_tangent(tan)]])
    q = np.array([[70.0, 20.0, -10.0, -5.0]])
    c, s = np.cos(np.radians(40)), np.sin(np.radians(40))
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    p2 = np.concatenate([p[:, :3] @ R.T, quat_from_tangent(tangent_from_quat(p[:, 3:]) @ R.T)], axis=1)
    q2 = q + np.array([[40.0, 40.0, 0.0, 0.0]])
    np.testing.assert_allclose(follow_features(frame, 2, p2, p2, q2), follow_features(frame, 2, p, p, q),
                               atol=1e-9)


def test_noise_mixture_and_previous_rows():
    e = joint_noise(np.random.default_rng(0), 20000, 2)
    assert np.mean(np.all(e == 0, axis=1)) == pytest.approx(0.25, abs=0.02)
    assert np.std(e[:, 2:]) == pytest.approx(0.1 * np.std(e[:, :2]), rel=0.05)
    np.testing.assert_array_equal(previous_rows([(0, 3), (3, 5)]), [0, 0, 1, 3, 3])


def test_substeps_interpolate_far_targets():
    a = np.array([0.0, 0.0, 50.0, *quat_from_tangent(np.array([0.0, 0.0, 1.0]))])
    b = np.array([3.0, 4.0, 50.0, *quat_from_tangent(np.array([0.3, 0.0, 1.0]))])
    s = substeps(a, b, 1.0)
    assert len(s) == 5
    np.testing.assert_allclose(s[-1], b, atol=1e-12)
    np.testing.assert_allclose(np.diff(s[:, :3], axis=0), np.tile([[0.6, 0.8, 0.0]], (4, 1)), atol=1e-12)
    assert len(substeps(a, a, 1.0)) == 1


def test_the_layout_is_the_familys_and_old_folders_read_as_it():
    """The follow layout is registered by the family (models/ names no family); a features.json of a
    folder written before (`"follow": true`, tests/inference/old_folders, main 94a32c9) reads as it,
    and is written back with the family's name and the same feature names."""
    import json
    from pathlib import Path

    from ctrkin.models.features import FAMILY_LAYOUTS

    assert LAYOUT in FAMILY_LAYOUTS
    old = Path(__file__).parents[2] / "inference" / "old_folders" / "main_94a32c9" / "ik_follow_mlp"
    stored = json.loads((old / "features.json").read_text())
    assert stored["follow"] is True and "family" not in stored
    layout = FeatureLayout.from_dict(stored)
    assert layout == FeatureLayout(task="ik", n_tubes=2, ib=1, family=LAYOUT)
    written = layout.to_dict()
    assert written["family"] == LAYOUT and "follow" not in written
    assert FeatureLayout.from_dict(written) == layout
    assert written["input_names"] == stored["input_names"]
    assert written["output_names"] == stored["output_names"]
    plain = json.loads((old.parent / "ik_lstm_mlp" / "features.json").read_text())     # "follow": false
    assert FeatureLayout.from_dict(plain).family is None
    with pytest.raises(ModelError, match="not one a model family registered"):
        FeatureLayout(task="ik", ib=1, family="nope")


def test_a_play_layout_ends_with_the_target_path_lags():
    from ctrkin.models.play_lags import target_play_names

    plain = FeatureLayout(task="ik", n_tubes=2, ib=1, family=LAYOUT)
    play = FeatureLayout(task="ik", n_tubes=2, ib=1, family=LAYOUT, play=True)
    assert play.input_names == plain.input_names + tuple(target_play_names())
    assert target_play_names()[:2] == ["play_x_0.3", "play_x_1"]
    target = np.array([[10.0, 5.0, 80.0, *quat_from_tangent(np.array([0.1, 0.2, 1.0]))]])
    q = np.array([[30.0, 10.0, -20.0, -12.0]])
    lags = np.linspace(-1.0, 1.0, len(target_play_names()))[None]
    f = follow_features(_frame(), 2, target, target, q, lags)
    assert f.shape == (1, play.n_inputs)
    np.testing.assert_array_equal(f[0, plain.n_inputs:], lags[0])
    np.testing.assert_array_equal(f[0, :plain.n_inputs], follow_features(_frame(), 2, target, target, q)[0])
    with pytest.raises(ModelError, match="play lags are inputs"):
        FeatureLayout(task="ik", ib=1, play=True)                   # the paper's IK layout takes none


def test_an_outer_angle_layout_adds_sin_cos_of_the_outer_tubes_angle_before_the_lags():
    from ctrkin.models.play_lags import target_play_names

    plain = FeatureLayout(task="ik", n_tubes=2, ib=1, family=LAYOUT)
    both = FeatureLayout(task="ik", n_tubes=2, ib=1, family=LAYOUT, outer_angle=True, play=True)
    assert both.input_names == (*plain.input_names, "sin_alpha_2", "cos_alpha_2", *target_play_names())
    assert FeatureLayout.from_dict(both.to_dict()) == both
    assert "outer_angle: False vs True" in plain.describe_difference(
        FeatureLayout(task="ik", n_tubes=2, ib=1, family=LAYOUT, outer_angle=True))
    target = np.array([[10.0, 5.0, 80.0, *quat_from_tangent(np.array([0.1, 0.2, 1.0]))]])
    lags = np.linspace(-1.0, 1.0, len(target_play_names()))[None]
    for outer in (-20.0, 30.0, 200.0):
        q = np.array([[30.0, outer, -20.0, -12.0]])
        f = follow_features(_frame(), 2, target, target, q, lags, outer_angle=True)[0]
        assert f.shape == (both.n_inputs,)
        np.testing.assert_allclose(f[plain.n_inputs:plain.n_inputs + 2],
                                   [np.sin(np.radians(outer)), np.cos(np.radians(outer))], atol=1e-15)
        np.testing.assert_array_equal(f[:plain.n_inputs], follow_features(_frame(), 2, target, target, q)[0])
        np.testing.assert_array_equal(f[plain.n_inputs + 2:], lags[0])
    with pytest.raises(ModelError, match="absolute angle is an input"):
        FeatureLayout(task="ik", ib=1, outer_angle=True)            # the paper's IK layout takes none
    with pytest.raises(ModelError, match="absolute angle is an input"):
        FeatureLayout(task="fk", ib=2, outer_angle=True)            # an FK has its angles already
