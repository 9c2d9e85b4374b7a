"""The play operators of an FK's inputs (ctrkin.models.play_lags): the operator against its definition,
streaming against the path, and an FK model with play-lag inputs in batch, streaming and probes."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.errors import ModelError
from ctrkin.models.features import FeatureLayout, sequence_features, step_features
from ctrkin.models.play_lags import INPUT_ANGLE_WIDTHS_DEG, PlayState, path_lags, play_names


def _joints(rng: np.random.Generator, t: int = 120) -> np.ndarray:
    """A 2-tube joint path (T, 4) that turns both ways and slides: reversals inside the widest play."""
    a1 = np.cumsum(rng.normal(0.0, 6.0, t))
    a2 = np.cumsum(rng.normal(0.0, 3.0, t))
    b1 = -20.0 + np.cumsum(rng.normal(0.0, 0.1, t))
    return np.column_stack([a1, a2, b1, np.full(t, -5.0)])


def test_a_play_operator_holds_its_output_inside_the_dead_band_and_follows_outside():
    # x rises 0 → 10, falls back to 4, rises to 12: with r = 2 the output trails x by 2 while x moves
    # on, and stays put while x turns back within 2r
    x = np.r_[np.arange(0.0, 11.0), np.arange(9.0, 3.0, -1.0), np.arange(5.0, 13.0)]
    q = np.column_stack([x, np.zeros_like(x), np.full_like(x, -20.0), np.full_like(x, -5.0)])
    lag = path_lags(q, [(0, len(x))], 2, angle_widths=(2.0,)).inner[:, 0] * 2.0
    y = x - lag
    expect = np.empty_like(x)
    prev = x[0]
    for t, v in enumerate(x):
        prev = min(max(prev, v - 2.0), v + 2.0)
        expect[t] = prev
    np.testing.assert_array_equal(y, expect)
    assert np.all(y[10:15] == 8.0)         # turned back at 10: held while x falls 4° (2r) to 6
    assert y[15] == 7.0 and y[16] == 6.0   # then follows 2 above it
    assert np.all(np.abs(lag) <= 2.0)


def test_streaming_lags_equal_the_path_and_a_peek_changes_nothing(rng):
    q = _joints(rng)
    want = path_lags(q, [(0, len(q))], 2).columns()
    st = PlayState(2)
    got = []
    for row in q:
        peeked = st.peek(np.stack([row, row + 1.0]))
        lags, y = st.after(row)
        np.testing.assert_array_equal(peeked[0], lags)
        st.advance(y)
        got.append(lags)
    np.testing.assert_allclose(np.array(got), want, rtol=0, atol=1e-12)
    st.reset()
    assert not st.after(q[5])[0].any()                   # at rest: every lag 0


def test_target_lags_stream_as_they_run_along_a_path_and_follow_its_runs(rng):
    from ctrkin.models.play_lags import TARGET_WIDTHS_MM, TargetPlay, target_lags

    p = np.cumsum(rng.normal(0.0, 0.8, (60, 3)), axis=0)
    whole = target_lags(p, [(0, 60)])
    assert whole.shape == (60, 3 * len(TARGET_WIDTHS_MM)) and np.all(np.abs(whole) <= 1.0 + 1e-12)
    np.testing.assert_array_equal(whole[0], 0.0)                      # at rest
    play = TargetPlay()
    np.testing.assert_allclose([play.advance(x) for x in p], whole, atol=1e-12)
    # the z lag of the narrowest operator after a rise of more than its width: taken up
    assert target_lags(np.c_[np.zeros(3), np.zeros(3), [0.0, 0.2, 1.0]], [(0, 3)])[2, 8] == pytest.approx(1.0)
    # two sequences of one run are one path; of two runs, the second starts at rest
    two = [(0, 30), (30, 60)]
    np.testing.assert_allclose(target_lags(p, two, runs=np.zeros(60)), whole, atol=1e-12)
    apart = target_lags(p, two, runs=np.r_[np.zeros(30), np.ones(30)])
    np.testing.assert_array_equal(apart[30], 0.0)
    # a glitch row keeps the last believed position
    skip = np.zeros(60, bool)
    skip[10] = True
    glitched = p.copy()
    glitched[10] += 50.0
    believed = p.copy()
    believed[10] = p[9]
    held = target_lags(glitched, [(0, 60)], skip=skip)
    np.testing.assert_array_equal(held, target_lags(believed, [(0, 60)]))


def test_the_play_layout_names_its_inputs_and_reads_older_layouts_without_them():
    lay = FeatureLayout(task="fk", n_tubes=2, ib=2, play=True)
    plain = FeatureLayout(task="fk", n_tubes=2, ib=2)
    assert lay.input_names[:plain.n_inputs] == plain.input_names      # Δα0 keeps its index
    assert list(lay.input_names[plain.n_inputs:]) == play_names(2)
    assert len(play_names(2)) == 2 * len(INPUT_ANGLE_WIDTHS_DEG) + 3
    assert FeatureLayout.from_dict(lay.to_dict()) == lay
    old = plain.to_dict()
    del old["play"]                                      # a folder written before play lags
    assert FeatureLayout.from_dict(old) == plain
    assert lay.describe_difference(plain) == ["play: True vs False"]
    with pytest.raises(ModelError, match="paper's FK layout and of the families"):
        FeatureLayout(task="ik", play=True)


def test_step_features_with_the_streamed_lags_equal_the_sequence_features(rng):
    lay = FeatureLayout(task="fk", n_tubes=2, ib=2, play=True)
    q = _joints(rng, 60)
    feats = sequence_features(lay, q, [(0, 30), (30, 60)])          # each sequence from rest
    st = PlayState(2)
    for t, row in enumerate(q):
        if t in (0, 30):
            st.reset()
        lags, y = st.after(row)
        st.advance(y)
        prev = None if t in (0, 30) else q[t - 1]
        np.testing.assert_allclose(step_features(lay, row, prev, lags), feats[t], rtol=0, atol=1e-12)
    with pytest.raises(ModelError, match="play lags"):
        step_features(lay, q[0], None)


@pytest.fixture(scope="module")
def play_fk(sweeps, tmp_path_factory):
    from ctrkin.inference import Kinematics
    from ctrkin.training import TrainConfig, train

    out = tmp_path_factory.mktemp("play_fk") / "fk"
    cfg = TrainConfig(task="fk", model="lstm_mlp_branch", max_epochs=2, threads=1, play_lags=True,
                      target_frame="outer", options={"structure": "L16|D16", "gate_units": 8})
    train(sweeps, cfg, out, progress=False)
    return Kinematics.load(out)


def test_the_fused_step_of_a_play_fk_is_the_reference_path_and_shares_its_state(play_fk, sweeps):
    from ctrkin.inference import Kinematics

    fused, ref = play_fk.copy(), Kinematics.load(play_fk.path, fused=False)
    assert fused.predictor.fused and not ref.predictor.fused
    a, b = sweeps.sequence_bounds()[2]
    q = sweeps.joints()[a:b]
    for kin in (fused, ref):
        kin.reset()
    for t, row in enumerate(q):
        given = list(row) if t % 7 == 3 else row        # a list: this step takes the reference path
        np.testing.assert_array_equal(fused.step(given), ref.step(row))
    fused.reset(continue_run=True)                      # the operators carry over, not from rest
    ref.reset(continue_run=True)
    np.testing.assert_array_equal(fused.step(q[-1] + 2.0 * np.r_[1.0, 0.0, 0.0, 0.0]),
                                  ref.step(q[-1] + 2.0 * np.r_[1.0, 0.0, 0.0, 0.0]))


def test_a_play_fk_streams_what_it_predicts_and_probes_what_it_would_step(play_fk, sweeps, rng):
    kin = play_fk
    assert kin.predictor.layout.play
    a, b = sweeps.sequence_bounds()[1]
    q = sweeps.joints()[a:b]
    batch = np.asarray(kin.predict(q))
    kin.reset()
    stream = []
    for t, row in enumerate(q):
        if t == 40:                            # a probe of candidates, then the step to the first one
            cand = np.stack([row, row + np.r_[3.0, 0.0, 0.0, 0.0]])
            probed, _ = kin.predictor.probe(cand)
        stream.append(kin.step(row))
        if t == 40:
            np.testing.assert_allclose(probed[0], stream[-1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(batch, np.array(stream), rtol=0, atol=1e-4)   # float32 batch, float64 step


def test_a_play_fk_follows_a_datasets_runs_and_exports_with_the_lags_in_its_window(play_fk, sweeps, tmp_path):
    import onnxruntime as ort

    from ctrkin.inference.onnx_export import export_onnx

    kin = play_fk
    by_rows = np.asarray(kin.predict(sweeps))
    assert np.isfinite(by_rows).all() and by_rows.shape == (len(sweeps.frame), 6)
    path = export_onnx(kin, tmp_path / "fk.onnx", allow_downgrade=True)     # the fold gate stays out
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    a, b = sweeps.sequence_bounds()[1]
    q = sweeps.joints()[a:b]
    windows = kin.feature_windows(q).astype(np.float32)
    assert windows.shape[2] == kin.layout.n_inputs and windows[:, :, -len(play_names(2)):].any()
    state = np.full(1, 0.5, np.float32)                  # a sequence start
    out = []
    for w in windows:
        y, state = sess.run(None, {"window": w[None], "state": state})
        out.append(y[0])
    np.testing.assert_allclose(np.array(out), np.asarray(kin.predict(q, gate="learned")), rtol=0, atol=1e-3)
