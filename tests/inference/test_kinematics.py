"""Kinematics: batch equals streaming, save -> load, wrong robot refused, IK workspace, ONNX."""

from __future__ import annotations

import numpy as np
import onnxruntime as ort
import pytest
from tests.small_models import with_position_field

import ctrkin
from ctrkin.data import Dataset
from ctrkin.errors import ModelError
from ctrkin.inference import Kinematics, export_onnx
from ctrkin.robots import Robot

STREAM_TOL = 1e-5   # batch (torch float32) vs streaming (float64 engine)
ONNX_TOL = 1e-4


def _stream(kin, raw, bounds):
    out = []
    for a, b in bounds:
        kin.reset()
        for t in range(a, b):
            r = kin.step(raw[t])
            out.append(r if kin.task == "fk" else r.joints)
    return np.array(out)


@pytest.mark.parametrize("name", ["fk", "fk_default", "fk_cnn", "fk_branch"])
def test_fk_batch_equals_streaming(model_dirs, sweeps, name):
    kin = ctrkin.Kinematics.load(model_dirs[name])
    batch = kin.predict(sweeps)
    stream = _stream(kin, sweeps.joints(), sweeps.sequence_bounds())
    assert batch.shape == (len(sweeps.frame), 6)
    assert np.abs(batch - stream).max() < STREAM_TOL          # mm and unit-quaternion components
    np.testing.assert_allclose(np.linalg.norm(batch[:, 3:], axis=1), 1.0, atol=1e-9)


def test_ik_batch_equals_streaming(model_dirs, sweeps):
    kin = Kinematics.load(model_dirs["ik"])
    res = kin.predict(sweeps)
    stream = _stream(kin, sweeps.poses(), sweeps.sequence_bounds())
    span = kin.bundle.y_norm.span      # α reaches 450°: float32 resolves 3e-5° there, so compare
    assert np.abs((res.joints - stream) / span).max() < STREAM_TOL    # relative to the output range
    assert res.joints.shape == (len(sweeps.frame), 4)


def test_save_load_gives_identical_predictions(model_dirs, sweeps, tmp_path):
    kin = Kinematics.load(model_dirs["fk"])
    copy = tmp_path / "copy"
    kin.bundle.save(copy)
    again = Kinematics.load(copy)
    np.testing.assert_array_equal(kin.predict(sweeps), again.predict(sweeps))
    assert again.layout == kin.layout and again.robot.fingerprint() == kin.robot.fingerprint()


def test_wrong_robot_and_layout_are_refused(model_dirs, sweeps):
    kin = Kinematics.load(model_dirs["fk"])
    d = sweeps.robot.to_dict()
    d["tubes"][0]["curvature"] = 0.05
    other = Robot.from_dict(d)
    ds = Dataset(sweeps.frame, other, {})
    with pytest.raises(ModelError, match=r"curvature: 0\.037\d* vs 0\.05"):
        kin.predict(ds)
    with pytest.raises(ModelError, match=r"\(T, 4\)"):
        kin.predict(np.zeros((5, 6)))
    with pytest.raises(ModelError, match=r"\(4,\)"):
        kin.step(np.zeros(3))


def test_missing_folder_says_what_to_do(tmp_path):
    with pytest.raises(ModelError, match="ctrkin train"):
        Kinematics.load(tmp_path)


def test_ik_reports_targets_outside_the_trained_workspace(model_dirs, sweeps):
    kin = Kinematics.load(model_dirs["ik"])
    split = sweeps.get_split()
    poses = sweeps.poses()
    inside = kin.predict(poses[split.train[:40]])
    assert inside.in_workspace.mean() > 0.95
    far = poses[:5].copy()
    far[:, 0] += 40.0                                    # 40 mm beside anything seen in training
    res = kin.predict(far)
    assert not res.in_workspace.any()
    assert "outside the training range" in res.reasons[0] and "x =" in res.reasons[0]
    assert res.joints.shape == (5, 4)                  # joints still returned, but flagged
    with pytest.raises(ModelError, match="outside the trained workspace"):
        kin.predict(far, strict=True)
    kin.reset()
    step = kin.step(far[0])
    assert step.in_workspace is False and step.reason
    with pytest.raises(ModelError):
        kin.step(far[1], strict=True)


@pytest.mark.parametrize("name", ["fk", "ik", "fk_cnn"])
def test_onnx_equals_pytorch(model_dirs, sweeps, tmp_path, name):
    kin = Kinematics.load(model_dirs[name])
    path = export_onnx(kin, tmp_path / f"{name}.onnx")
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    meta = sess.get_modelmeta().custom_metadata_map
    assert meta["ctrkin.task"] == kin.task and meta["ctrkin.robot_fingerprint"] == kin.robot.fingerprint()
    windows = kin.feature_windows(sweeps).astype(np.float32)
    ref = kin.predict(sweeps)
    ref = ref if kin.task == "fk" else ref.joints
    scale = 1.0 if kin.task == "fk" else kin.bundle.y_norm.span   # IK: relative to the output range
    for n in (1, 7, len(windows)):
        out = sess.run(None, {"window": windows[:n]})[0]
        if kin.task == "ik":     # the graph gives the network's joints; predict projects them on the limits
            out = kin.robot.project_joints(out.astype(np.float64))
        assert np.abs((out - ref[:n]) / scale).max() < ONNX_TOL


@pytest.fixture(scope="module")
def offset_fk(sweeps, tmp_path_factory):
    """A snap-aware FK with the offset head form (heads=offset), briefly trained."""
    from ctrkin.training import TrainConfig, train

    folder = tmp_path_factory.mktemp("offset_fk") / "fk"
    train(sweeps, TrainConfig(task="fk", model="lstm_mlp_branch", max_epochs=1, threads=1,
                              options={"structure": "L8|D8", "gate_units": 4, "heads": "offset"}),
          folder, progress=False)
    return folder


@pytest.mark.parametrize("heads", ["separate", "offset", "field"])
def test_onnx_branch_model_carries_its_state(model_dirs, offset_fk, sweeps, tmp_path, heads):
    """The snap-aware model's graph takes the previous branch state and returns the new one; fed
    back step by step it gives predict's poses with the learned gate (in the tracker frame: the outer
    frame is in the graph; the fold gate is not in the graph); also with the offset head form, and
    with a position field in the frame (also in the graph)."""
    kin = Kinematics.load(offset_fk if heads == "offset" else model_dirs["fk_branch"])
    if heads == "field":
        kin = with_position_field(kin)
    assert kin.frame is not None
    path = export_onnx(kin, tmp_path / "b.onnx", allow_downgrade=True)   # the learned gate, knowingly
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    windows = kin.feature_windows(sweeps).astype(np.float32)
    ref = kin.predict(sweeps, gate="learned")
    out = np.empty_like(ref)
    for a, b in sweeps.sequence_bounds():
        state = np.array([0.5], np.float32)
        for t in range(a, b):
            y, state = sess.run(None, {"window": windows[t:t + 1], "state": state})
            out[t] = y[0]
    assert np.abs(out - ref).max() < ONNX_TOL


@pytest.mark.parametrize(("lagged", "turns", "field"), [(False, 0.0, False), (True, 0.0, False),
                                                      (True, 720.0, False), (False, 0.0, True)])
def test_probe_equals_step(model_dirs, sweeps, lagged, turns, field):
    """probe(K candidates) returns what step would for each, and advances nothing; also with an
    outer lag and lagged inputs, for candidates that turn the outer motor either way or not, on
    a sequence two turns outside the trained range (shifted by whole turns: m_N follows αN as given),
    and with a position field in the frame."""
    load = (lambda: _lagged(model_dirs, inputs=True)) if lagged else (
        lambda: with_position_field(Kinematics.load(model_dirs["fk_branch"])) if field
        else Kinematics.load(model_dirs["fk_branch"]))
    kin = load()
    q = sweeps.joints()[:40].copy()
    q[:, :2] += turns
    kin.reset()
    for row in q[:20]:
        kin.step(row)
    cands = q[20:25].copy()
    cands[:, 1] += [-2.0, -1.0, 0.0, 1.0, 2.0]
    poses, _ = kin.probe(cands)
    for k, c in enumerate(cands):
        twin = load()
        twin.reset()
        for row in q[:20]:
            twin.step(row)
        np.testing.assert_allclose(twin.step(c), poses[k], atol=1e-9)
    np.testing.assert_allclose(kin.step(cands[0]), poses[0], atol=1e-9)   # probe left the stream as it was


def test_branch_states_override_the_gate(model_dirs, sweeps):
    kin = Kinematics.load(model_dirs["fk_branch"])
    n = len(sweeps.frame)
    zero = kin.predict(sweeps, branch_states=np.zeros(n))
    one = kin.predict(sweeps, branch_states=np.ones(n))
    gated = kin.predict(sweeps)
    assert np.abs(zero - one).max() > 1e-6          # two heads
    from_heads = np.where(np.all(np.isclose(gated, zero), axis=1) | np.all(np.isclose(gated, one), axis=1),
                          True, False)
    assert from_heads.all()                          # the gate only chooses between them
    with pytest.raises(ModelError, match="shape"):
        kin.predict(sweeps, branch_states=np.zeros(3))
    with pytest.raises(ModelError, match="branch model"):
        Kinematics.load(model_dirs["fk"]).predict(sweeps, branch_states=np.zeros(n))


def test_batch_predict_accepts_sequence_ids(model_dirs, sweeps):
    kin = Kinematics.load(model_dirs["fk"])
    sid = sweeps.frame["sequence_id"].to_numpy()
    np.testing.assert_allclose(kin.predict(sweeps.joints(), sequence_id=sid), kin.predict(sweeps))
    one = kin.predict(sweeps.joints())             # as one long sequence: differs only at the seams
    starts = [a for a, _ in sweeps.sequence_bounds()]
    same = np.setdiff1d(np.arange(len(sid)), np.r_[starts, np.add(starts, 1)])
    np.testing.assert_allclose(one[same], kin.predict(sweeps)[same], atol=1e-6)



def test_streaming_workspace_check_matches_batch(model_dirs, sweeps):
    kin = Kinematics.load(model_dirs["ik"])
    poses = sweeps.poses()[:200].copy()
    poses[50:80, 1] += np.linspace(0.0, 30.0, 30)        # a detour out of the workspace and back
    batch = kin.predict(poses)
    assert 0 < batch.in_workspace.sum() < len(poses)
    kin.reset()
    flags = [kin.step(p).in_workspace for p in poses]
    np.testing.assert_array_equal(flags, batch.in_workspace)


def _lagged(model_dirs, inputs: bool = False, lag: tuple[float, float] = (0.8, 0.4)):
    """The snap-aware model with an outer-tube lag λ = 0.8° + 0.4°/mm · overlap put into its frame;
    inputs: its network sees αN − λ·m_N (OuterFrame.lagged_inputs) as models trained since do."""
    from dataclasses import replace

    kin = Kinematics.load(model_dirs["fk_branch"])
    kin.predictor.frame = replace(kin.frame, lag=lag, lagged_inputs=inputs)
    return kin


def _outer_moves(sweeps):
    """Two sequences of sweep joints whose outer motor turns forward, then back, then rests."""
    q = sweeps.joints()[:120].copy()
    q[:, 1] += np.r_[np.arange(40), 40 - np.arange(40), np.zeros(40)]
    return np.r_[q, q], np.repeat([0, 1], len(q))


def test_outer_lag_turns_the_frame_batch_and_streaming_alike(model_dirs, sweeps):
    """With a lag (and commanded inputs, as folders from before lagged_inputs) the frame turns with
    αN − λ(β)·m_N: batch equals streaming, rows at rest are unchanged, and rows after an outer turn
    are turned about the registered axis by ∓λ."""
    from ctrkin.models.motion import outer_motion
    from ctrkin.robots.overlap import curved_overlap

    kin, plain = _lagged(model_dirs), _lagged(model_dirs, lag=(0.0, 0.0))
    q, sid = _outer_moves(sweeps)
    batch, ref = kin.predict(q, sequence_id=sid), plain.predict(q, sequence_id=sid)
    bounds = [(0, 120), (120, 240)]
    assert np.abs(batch - _stream(kin, q, bounds)).max() < STREAM_TOL
    m = outer_motion(q, bounds, kin.layout.n_tubes)        # +1 while it turns forward, then −1
    assert (m == 1).sum() > 30 and (m == -1).sum() > 60 and (m == 0).sum() == 2
    assert np.abs(batch[m == 0] - ref[m == 0]).max() < 1e-9
    R = kin.frame.registration.rotation
    lam = 0.8 + 0.4 * curved_overlap(kin.robot, q)
    for k in np.nonzero(m != 0)[0][::17]:
        a, b = R.T @ (ref[k, :3] - kin.frame.registration.translation), R.T @ (
            batch[k, :3] - kin.frame.registration.translation)
        turn = np.degrees(np.arctan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1]))
        assert turn == pytest.approx(-lam[k] * m[k], abs=1e-6)


def test_lagged_inputs_see_the_outer_tubes_angle(model_dirs, sweeps):
    """With lagged inputs the network sees αN − λ(β)·m_N as its αN: the model answers at joints q
    exactly as the same network without a lag answers at q with αN so turned (same branch states),
    and batch equals streaming."""
    from ctrkin.models.motion import outer_motion
    from ctrkin.robots.overlap import curved_overlap

    kin, plain = _lagged(model_dirs, inputs=True), _lagged(model_dirs, lag=(0.0, 0.0))
    q, sid = _outer_moves(sweeps)
    bounds = [(0, 120), (120, 240)]
    m = outer_motion(q, bounds, kin.layout.n_tubes)
    turned = q.copy()
    turned[:, 1] -= (0.8 + 0.4 * curved_overlap(kin.robot, q)) * m
    states = (np.arange(len(q)) // 30 % 2).astype(float)
    got = kin.predict(q, sequence_id=sid, branch_states=states)
    want = plain.predict(turned, sequence_id=sid, branch_states=states)
    assert np.abs(got - want).max() < 1e-9
    commanded = _lagged(model_dirs).predict(q, sequence_id=sid, branch_states=states)
    assert np.abs(got - commanded)[m != 0].max() > 1e-3          # the inputs did change
    batch = kin.predict(q, sequence_id=sid)
    assert np.abs(batch - _stream(kin, q, bounds)).max() < STREAM_TOL


@pytest.mark.parametrize("inputs", [False, True])
def test_onnx_takes_the_outer_lag(model_dirs, sweeps, tmp_path, inputs):
    """A frame with a lag exports an "outer_lag_deg" input; fed λ(β)·m_N it gives predict's poses.
    With lagged inputs the window's αN already is the frame's angle: no such input."""
    import json

    from ctrkin.models.motion import outer_motion
    from ctrkin.models.outer_lag import lag_deg

    kin = _lagged(model_dirs, inputs=inputs)
    path = export_onnx(kin, tmp_path / "lag.onnx", allow_downgrade=True)   # the graph's lag input is tested
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    meta = {p.key: p.value for p in __import__("onnx").load(str(path)).metadata_props}
    assert json.loads(meta["ctrkin.outer_lag_deg"]) == [0.8, 0.4]
    assert json.loads(meta["ctrkin.lagged_inputs"]) is inputs
    assert ("outer_lag_deg" in {i.name for i in sess.get_inputs()}) is not inputs
    q, sid = _outer_moves(sweeps)
    bounds = [(0, 120), (120, 240)]
    ref = kin.predict(q, sequence_id=sid, gate="learned")
    motion = outer_motion(q, bounds, kin.layout.n_tubes)
    lag = (lag_deg(kin.robot, q, kin.frame.lag) * motion).astype(np.float32)
    windows = kin.feature_windows(q, sequence_id=sid).astype(np.float32)
    out = np.empty_like(ref)
    for a, b in bounds:
        state = np.array([0.5], np.float32)
        for t in range(a, b):
            feed = {"window": windows[t:t + 1], "state": state}
            if not inputs:
                feed["outer_lag_deg"] = lag[t:t + 1]
            y, state = sess.run(None, feed)
            out[t] = y[0]
    assert np.abs(out - ref).max() < ONNX_TOL


def test_a_fold_gate_with_a_slide_memory_streams_as_in_batch(model_dirs, sweeps):
    """The snap-aware FK whose fold gate has a slide memory (ctrkin.families.snap_aware.fold_gate):
    streaming (fused and reference path) gives what batch predicts (the memory's operators reset with
    each run), and the memory moves the switches on the sweeps (they slide)."""
    from dataclasses import replace

    kin = ctrkin.Kinematics.load(model_dirs["fk_branch"])
    gate = kin.predictor.fold_gate
    plain = kin.predict(sweeps)
    kin.predictor.fold_gate = replace(gate, widen_deg=gate.widen_deg + 10.0,
                                      slide_weights_deg=(6.0, 4.0, 0.0))
    ref = ctrkin.Kinematics.load(model_dirs["fk_branch"], fused=False)
    ref.predictor.fold_gate = kin.predictor.fold_gate
    assert kin.fused and not ref.fused
    batch = kin.predict(sweeps)
    for k in (kin, ref):
        stream = _stream(k, sweeps.joints(), sweeps.sequence_bounds())
        assert np.abs(batch - stream).max() < STREAM_TOL
    assert np.abs(batch - plain).max() > 1e-3
