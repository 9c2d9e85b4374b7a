"""The fused FK step (ctrkin.models.fused) equals the reference path bit for bit: on random joint
sequences with snaps, glitches, refused steps, restarts and carried-over runs, for the paper's
LSTM-MLP and the snap-aware model (fold gate, learned gate, outer frame with and without its outer
lag, phase encoding, in the tracker frame, with the offset head form, and with a position field)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from tests.small_models import with_position_field

from ctrkin.errors import JointError, ModelError
from ctrkin.families.registry import open_bundle
from ctrkin.families.snap_aware.fold_gate import FoldGate
from ctrkin.inference import Kinematics
from ctrkin.models.fk_predictor import FUSED_ROWS
from ctrkin.models.frame import OuterFrame
from ctrkin.training import TrainConfig, train


@pytest.fixture(scope="module")
def fused_dirs(model_dirs, sweeps, tmp_path_factory):
    """The session's FK models and a snap-aware one with the phase encoding."""
    root = tmp_path_factory.mktemp("fused")
    cfg = TrainConfig(task="fk", model="lstm_mlp_branch", angle_encoding="phase", max_epochs=1, threads=1,
                      target_frame="outer", options={"structure": "L8|D8", "gate_units": 4})
    train(sweeps, cfg, root / "phase", progress=False)
    train(sweeps, replace(cfg, target_frame="tracker"), root / "tracker", progress=False)
    train(sweeps, replace(cfg, options={**cfg.options, "heads": "offset"}), root / "offset", progress=False)
    return {"fk": model_dirs["fk"], "fk_default": model_dirs["fk_default"],
            "fk_branch": model_dirs["fk_branch"], "phase": root / "phase", "tracker": root / "tracker",
            "offset": root / "offset"}


def _load(folder, name: str, fused: bool) -> Kinematics:
    """name "learned": the snap-aware model without its fold gate (Kinematics from the bundle alone),
    so that its learned gate decides; "lagged…": its outer frame given an outer lag λ(β) = 2° +
    0.4°/mm · overlap (ctrkin.models.outer_lag), with the fold gate and lagged inputs (as trained) or
    ("lagged_learned") without either (commanded inputs: a folder from before lagged_inputs); "slide":
    its fold gate given a slide memory; "field": its frame given a position field."""
    if name == "field":
        return with_position_field(Kinematics.load(folder, fused=fused))
    if name == "learned":
        return Kinematics(open_bundle(folder), fused=fused)
    if name == "lagged":               # the frame replaced after loading: the fused step follows
        kin = Kinematics.load(folder, fused=fused)
        assert kin.frame is not None
        kin.predictor.frame = replace(kin.frame, lag=(2.0, 0.4))
        assert kin.frame.lags_inputs
        return kin
    if name == "slide":                # a fold gate with a slide memory (its play operators of d)
        kin = Kinematics.load(folder, fused=fused)
        gate = kin.predictor.fold_gate
        kin.predictor.fold_gate = replace(gate, widen_deg=gate.widen_deg + 10.0,
                                          slide_weights_deg=(6.0, 4.0, 0.5))
        return kin
    if name == "lagged_learned":       # and a fold gate attached after construction, then removed
        bundle = open_bundle(folder)
        assert bundle.frame is not None
        lagged = replace(bundle, frame=OuterFrame(bundle.frame.registration, (2.0, 0.4)))
        kin = Kinematics(lagged, fused=fused)
        kin.predictor.fold_gate = FoldGate.load(folder)
        kin.predictor.fold_gate = None
        return kin
    return Kinematics.load(folder, fused=fused)


def _joint_path(sweeps, rng: np.random.Generator, steps: int) -> np.ndarray:
    """A random path (steps, 4) through the trained translations: the inner tube turning back and forth
    through the bistable band (snaps) at random step sizes, the outer tube moving now and then, and
    encoder glitches (single-step spikes of up to 40°)."""
    q = sweeps.joints()
    betas = q[rng.integers(0, len(q), steps // 50 + 1), 2:]
    a1 = np.cumsum(rng.choice([-1.0, 1.0], steps) * rng.uniform(0.2, 6.0, steps)
                   * np.repeat(rng.choice([-1.0, 1.0], steps // 60 + 1), 60)[:steps]) + 180.0
    a2 = np.repeat(rng.uniform(0.0, 90.0, steps // 40 + 1), 40)[:steps]
    path = np.c_[a1 + a2, a2, np.repeat(betas, 50, axis=0)[:steps]]
    glitch = rng.random(steps) < 0.02
    path[glitch, 0] += rng.uniform(-40.0, 40.0, glitch.sum())
    return path


def _run(kin: Kinematics, script: list[tuple[str, object]]) -> list[object]:
    """Play a script of ("reset", kwargs) / ("step", joints) / ("list", joints: through the reference
    path, a list) on kin; a refused step gives its exception type."""
    out: list[object] = []
    for what, arg in script:
        if what == "reset":
            assert isinstance(arg, dict)
            kin.reset(**arg)
            continue
        try:
            y = kin.step(list(arg) if what == "list" else arg)
            p = kin.predictor
            out.append((y, p._gate_state, p._engine.state, p._outer_motion))
        except (JointError, ModelError) as e:
            out.append(type(e))
    return out


def _script(sweeps, seed: int) -> list[tuple[str, object]]:
    rng = np.random.default_rng(seed)
    script: list[tuple[str, object]] = []
    bad = [np.array([0.0, 0.0, -40.0, 5.0]), np.array([np.nan, 0.0, -20.0, -5.0]),
           np.array([1e12, 0.0, -20.0, -5.0]), np.array([5000.0, 0.0, -20.0, -5.0])]
    resets = [{}, {"outer_motion": 1}, {"outer_motion": -1}, {"continue_run": True},
              {"outer_motion": -1, "continue_run": True}]
    for k, kwargs in enumerate(resets):
        script.append(("reset", kwargs))
        path = _joint_path(sweeps, rng, 300)
        if k == 2:
            path[:, :2] += 720.0                          # outside the trained range: whole turns off
        for t, q in enumerate(path):
            script.append(("list" if t % 7 == 3 else "step", q))
            if t % 61 == 30:
                script.append(("step", bad[(t // 61 + k) % len(bad)]))
    return script


@pytest.mark.parametrize("name", ["fk", "fk_default", "fk_branch", "phase", "tracker", "offset", "learned",
                                  "lagged", "lagged_learned", "slide", "field"])
def test_fused_step_equals_the_reference_path(fused_dirs, sweeps, name):
    folder = fused_dirs["fk_branch" if name in ("learned", "lagged", "lagged_learned", "slide", "field")
                        else name]
    fast, ref = _load(folder, name, True), _load(folder, name, False)
    assert fast.fused and not ref.fused
    learned = name in ("learned", "lagged_learned")
    branch = learned or name in ("fk_branch", "phase", "tracker", "offset", "lagged", "slide", "field")
    assert (getattr(fast, "fold_gate", None) is not None) == (branch and not learned)   # a family attribute
    assert (fast.frame is not None and fast.frame.has_lag) == name.startswith("lagged")
    script = _script(sweeps, seed=7)
    got, want = _run(fast, script), _run(ref, script)
    assert len(got) == len(want) > 1500
    refused = [w for w in want if isinstance(w, type)]
    assert len(refused) >= 20 and {JointError, ModelError} <= set(refused)
    for k, (g, w) in enumerate(zip(got, want, strict=True)):
        if isinstance(w, type):
            assert g is w, k
        else:
            assert isinstance(g, tuple)
            np.testing.assert_array_equal(g[0], w[0], err_msg=f"step {k}")
            assert g[1:] == w[1:], k
    states = {w[2] for w in want if not isinstance(w, type)}
    if name.startswith("lagged"):      # the lag turned the frame both ways: m_N took both signs
        assert {w[3] for w in want if not isinstance(w, type)} >= {-1, 1}
    if learned:                        # the gate decided every step (this briefly trained one says 1)
        assert states <= {0.0, 1.0}
    elif branch:                       # the fold gate: the path crossed folds, both branches were used
        assert states == {0.0, 1.0}


def test_probe_sees_the_fused_history(fused_dirs, sweeps):
    """probe() after fused steps answers as after reference steps (one streaming state)."""
    fast = Kinematics.load(fused_dirs["fk_branch"])
    ref = Kinematics.load(fused_dirs["fk_branch"], fused=False)
    path = _joint_path(sweeps, np.random.default_rng(3), 60)
    for kin in (fast, ref):
        kin.reset(outer_motion=1)
        for q in path[:50]:
            kin.step(q)
    for a, b in zip(fast.probe(path[50:]), ref.probe(path[50:]), strict=True):
        np.testing.assert_array_equal(a, b)


def test_models_outside_the_fused_scope_keep_the_reference_path(model_dirs):
    assert not Kinematics.load(model_dirs["fk_cnn"]).fused
    assert not Kinematics.load(model_dirs["ik"]).fused


@pytest.fixture(scope="module")
def outer_fk(sweeps, tmp_path_factory):
    """A paper-family FK model learned in the outer tube's frame (no lag, no branch state)."""
    folder = tmp_path_factory.mktemp("outer_fk") / "fk"
    train(sweeps, TrainConfig(task="fk", max_epochs=1, threads=1, target_frame="outer",
                              options={"structure": "L8|D8"}), folder, progress=False)
    return folder


@pytest.mark.parametrize("name", ["fk", "fk_default", "outer", "outer_field"])
def test_short_predict_is_the_fused_step(fused_dirs, outer_fk, sweeps, name):
    """predict on up to FUSED_ROWS rows runs the fused step (issue 26): the poses `step` gives from a
    reset, bit for bit, within float32 round-off of the torch batch path, the stream untouched; rows
    the fast checks refuse go to the batch path, which raises its own message."""
    folder = outer_fk if name.startswith("outer") else fused_dirs[name]
    kin, ref = Kinematics.load(folder), Kinematics.load(folder, fused=False)
    if name == "outer_field":
        kin, ref = with_position_field(kin), with_position_field(ref)
    assert kin.predictor._fused.stateless and (kin.frame is not None) == name.startswith("outer")
    path = _joint_path(sweeps, np.random.default_rng(5), 80)
    path[40:, :2] += 720.0                                 # whole turns outside the trained range
    kin.reset()
    stream = [kin.step(q) for q in path[:10]]
    for start, n in [(0, 1), (3, 2), (11, 7), (20, FUSED_ROWS), (45, FUSED_ROWS), (50, 5)]:
        rows = path[start:start + n]
        got = kin.predict(rows)
        twin = kin.copy()
        twin.reset()
        np.testing.assert_array_equal(got, np.array([twin.step(q) for q in rows]), err_msg=f"{start}+{n}")
        np.testing.assert_allclose(got, ref.predict(rows), atol=2e-4, err_msg=f"{start}+{n}")
    longer = path[:FUSED_ROWS + 1]                         # the batch path, float32
    np.testing.assert_allclose(kin.predict(longer)[:FUSED_ROWS], kin.predict(longer[:FUSED_ROWS]), atol=2e-4)
    # the stream went on where it was: predict did not touch it
    fresh = with_position_field(Kinematics.load(folder)) if name == "outer_field" else Kinematics.load(folder)
    fresh.reset()
    want = [fresh.step(q) for q in path[:12]]
    np.testing.assert_array_equal(np.array(stream + [kin.step(q) for q in path[10:12]]), np.array(want))
    for bad in [np.array([[np.nan, 0.0, -20.0, -5.0]]), np.array([[0.0, 0.0, -40.0, 5.0]]),
                np.r_[path[:3], [[1e12, 0.0, -20.0, -5.0]]], np.r_[path[:3], [[np.inf, 0.0, -20.0, -5.0]]]]:
        with pytest.raises((JointError, ModelError)) as got_error:
            kin.predict(bad)
        with pytest.raises((JointError, ModelError)) as want_error:
            ref.predict(bad)
        assert str(got_error.value) == str(want_error.value)


def test_copies_keep_one_state_for_both_paths(fused_dirs, sweeps):
    """After copy.deepcopy or pickle of a model mid-sequence, the engine's state arrays are views of
    the fused step's buffers again (a copy would otherwise give the reference path and probe() a
    stale history): probe() after more fused steps answers as on the original."""
    import copy
    import pickle

    kin = Kinematics.load(fused_dirs["fk_branch"])
    path = _joint_path(sweeps, np.random.default_rng(4), 40)
    kin.reset(outer_motion=1)
    for q in path[:20]:
        kin.step(q)
    twins = [copy.deepcopy(kin), pickle.loads(pickle.dumps(kin))]
    for q in path[20:30]:
        kin.step(q)
    want = kin.probe(path[30:])
    for twin in twins:
        engine, fused = twin.predictor._engine, twin.predictor._fused
        assert np.shares_memory(engine._h[0], fused.state.buf)
        assert np.shares_memory(engine._x, fused.state.buf)
        for q in path[20:30]:
            twin.step(q)
        for a, b in zip(twin.probe(path[30:]), want, strict=True):
            np.testing.assert_array_equal(a, b)
