"""One stream per Kinematics (issue 27, items 11 and 24): a batch predict between two steps leaves the
stream as it was, for every family; a second thread that steps or resets a stream another thread
holds is refused (not mixed in), and `copy()` gives each thread a stream of its own."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from ctrkin.errors import ModelError
from ctrkin.inference import Kinematics
from ctrkin.training import TrainConfig, train

NAMES = ("fk", "fk_branch", "fk_cnn", "ik", "ik_refined", "follow")


@pytest.fixture(scope="module")
def models(model_dirs, sweeps, tmp_path_factory):
    out = tmp_path_factory.mktemp("streams") / "follow"
    cfg = TrainConfig(task="ik", model="follow_mlp", max_epochs=2, threads=1, options={"structure": "|D32"})
    train(sweeps, cfg, out, progress=False)
    return {**dict(model_dirs), "follow": out}


def _inputs(kin, sweeps, seq=2, n=16):
    a, _ = sweeps.sequence_bounds()[seq]
    return sweeps.joints()[a:a + n] if kin.task == "fk" else sweeps.poses(true=True)[a:a + n]


def _answer(r):
    return np.asarray(r) if isinstance(r, np.ndarray) else r.joints


def _stream(kin, xs):
    return np.array([_answer(kin.step(x)) for x in xs])


# --- item 11 ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", NAMES)
def test_predict_between_steps_leaves_the_stream_alone(models, sweeps, name):
    kin = Kinematics.load(models[name])
    xs = _inputs(kin, sweeps)
    other = _inputs(kin, sweeps, seq=4)
    kin.reset()
    clean = _stream(kin, xs)
    kin.reset()
    first = _stream(kin, xs[:8])
    kin.predict(other)                                   # a batch of another sequence in between
    if kin.task == "ik" and "start_joints" in kin.predictor.accepts["predict"]:
        kin.predict(other, start_joints=sweeps.joints()[0])
    rest = _stream(kin, xs[8:])
    np.testing.assert_array_equal(np.concatenate([first, rest]), clean)


# --- item 24 ---------------------------------------------------------------------------------------
def _in_thread(fn):
    """Run fn() in a new thread; its result, or the exception it raised."""
    out: list[object] = []

    def run():
        try:
            out.append(fn())
        except Exception as e:  # handed back to the test
            out.append(e)

    t = threading.Thread(target=run, name="second")
    t.start()
    t.join()
    return out[0]


@pytest.mark.parametrize("name", ["fk", "follow"])
def test_a_second_thread_is_refused_not_mixed(models, sweeps, name):
    kin = Kinematics.load(models[name])
    xs = _inputs(kin, sweeps)
    kin.reset()
    clean = _stream(kin, xs)
    kin.reset()
    first = _stream(kin, xs[:8])
    for call in (lambda: kin.step(xs[0]), lambda: kin.reset()):
        err = _in_thread(call)
        assert isinstance(err, ModelError) and "kin.copy()" in str(err) and "'MainThread'" in str(err)
    rest = _stream(kin, xs[8:])                           # the refused thread changed nothing
    np.testing.assert_array_equal(np.concatenate([first, rest]), clean)


def test_each_thread_streams_its_own_copy(models, sweeps):
    kin = Kinematics.load(models["fk_branch"])
    xs, ys = _inputs(kin, sweeps, seq=1), _inputs(kin, sweeps, seq=3)
    kin.reset()
    ref_x = _stream(kin, xs)
    kin.reset()
    ref_y = _stream(kin, ys)
    kin.reset()
    results: dict[str, np.ndarray] = {}
    barrier = threading.Barrier(2)

    def run(key, k, seq):
        k.reset()
        out = []
        for x in seq:                      # the two threads' steps interleave
            barrier.wait()
            out.append(k.step(x))
        results[key] = np.array(out)

    threads = [threading.Thread(target=run, args=("x", kin, xs)),
               threading.Thread(target=run, args=("y", kin.copy(), ys))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    np.testing.assert_array_equal(results["x"], ref_x)
    np.testing.assert_array_equal(results["y"], ref_y)


def test_a_sequence_moves_between_threads_only_when_handed_over(models, sweeps):
    kin = Kinematics.load(models["fk"])
    xs = _inputs(kin, sweeps)
    kin.reset()
    clean = _stream(kin, xs)
    kin.reset()
    first = _stream(kin, xs[:8])

    def continue_here():
        kin.hand_over()
        return _stream(kin, xs[8:12])

    middle = _in_thread(continue_here)
    assert isinstance(middle, np.ndarray)
    # the second thread has ended: the sequence is free again for this one
    rest = _stream(kin, xs[12:])
    np.testing.assert_array_equal(np.concatenate([first, middle, rest]), clean)
    kin.reset()
    assert isinstance(_in_thread(lambda: kin.step(xs[0])), np.ndarray)   # a new sequence: any thread


def test_a_deep_copy_or_pickle_holds_no_threads_stream(models, sweeps):
    """copy.deepcopy and pickle of a Kinematics in use work (they recursed in __getattr__ before) and
    give a stream no thread holds."""
    import copy
    import pickle

    kin = Kinematics.load(models["fk"])
    xs = _inputs(kin, sweeps)
    kin.reset()
    first = _stream(kin, xs[:4])
    for twin in (copy.deepcopy(kin), pickle.loads(pickle.dumps(kin))):
        rest = _in_thread(lambda t=twin: _stream(t, xs[4:]))
        assert isinstance(rest, np.ndarray)
        kin.reset()
        np.testing.assert_array_equal(np.concatenate([first, rest]), _stream(kin, xs))
        kin.reset()
        first = _stream(kin, xs[:4])
