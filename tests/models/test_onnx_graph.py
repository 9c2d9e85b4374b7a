"""The exported graph answers what the torch path refuses as no answer (issue 27, item 10): a row with
a non-finite input gives NaN, not a finite pose, and an empty batch gives an empty output instead of
aborting the process inside ONNX Runtime."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import onnxruntime as ort
import pytest

from ctrkin.errors import ModelError
from ctrkin.inference import Kinematics, export_onnx


def _feed(sess, windows):
    names = [i.name for i in sess.get_inputs()]
    feed = {"window": windows}
    if "state" in names:
        feed["state"] = np.full(len(windows), 0.5, np.float32)
    if "outer_lag_deg" in names:
        feed["outer_lag_deg"] = np.zeros(len(windows), np.float32)
    return feed


@pytest.mark.parametrize("name", ["fk", "fk_branch", "fk_cnn", "ik"])
def test_non_finite_rows_give_nan_and_the_others_are_unchanged(model_dirs, sweeps, tmp_path, name):
    kin = Kinematics.load(model_dirs[name])
    path = export_onnx(kin, tmp_path / "m.onnx", allow_downgrade=True)   # the graph alone is tested
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    windows = kin.feature_windows(sweeps).astype(np.float32)[:12]
    clean = sess.run(None, _feed(sess, windows))
    bad = windows.copy()
    bad[3] = np.nan                                   # an all-NaN window (torch: NaN; predict: refused)
    bad[5, 0, 1] = np.inf
    bad[7, -1, 0] = -np.inf
    out = sess.run(None, _feed(sess, bad))
    rows = np.array([3, 5, 7])
    for got, ref in zip(out, clean, strict=True):
        assert np.isnan(got[rows]).all()
        keep = np.setdiff1d(np.arange(len(windows)), rows)
        np.testing.assert_array_equal(got[keep], ref[keep])
    with pytest.raises(ModelError, match="NaN or inf"):
        kin.predict(np.full((2, kin.layout.raw_width), np.nan))
    if kin.task == "ik":                              # a target without a unit quaternion (predict: refused)
        quat = windows.copy()
        quat[2, -1, 3:6] = 0.0
        quat[9, 0, 3:6] = (2.0, 0.0, 0.0)
        got = sess.run(None, _feed(sess, quat))[0]
        assert np.isnan(got[[2, 9]]).all()
        np.testing.assert_array_equal(np.delete(got, [2, 9], 0), np.delete(clean[0], [2, 9], 0))
    if len(out) == 2:                                 # a NaN state is no answer either
        feed = _feed(sess, windows)
        feed["state"][4] = np.nan
        y, state = sess.run(None, feed)
        assert np.isnan(y[4]).all() and np.isnan(state[4]) and np.isfinite(np.delete(y, 4, 0)).all()


@pytest.mark.parametrize("name", ["fk", "fk_branch", "ik"])
def test_an_empty_batch_gives_an_empty_output_as_predict_does(model_dirs, tmp_path, name):
    kin = Kinematics.load(model_dirs[name])
    path = export_onnx(kin, tmp_path / "m.onnx", allow_downgrade=True)   # the graph alone is tested
    code = ("import sys, numpy as np, onnxruntime as ort\n"
            "s = ort.InferenceSession(sys.argv[1], providers=['CPUExecutionProvider'])\n"
            "feed = {i.name: np.zeros((0, *i.shape[1:]), np.float32) for i in s.get_inputs()}\n"
            "print(' '.join('x'.join(map(str, o.shape)) for o in s.run(None, feed)))\n")
    run = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]                # was −6: the process aborted
    width = kin.layout.n_outputs
    assert run.stdout.split() == [f"0x{width}"] + (["0"] if name == "fk_branch" else [])
    empty = kin.predict(np.zeros((0, kin.layout.raw_width)))
    assert (empty if kin.task == "fk" else empty.joints).shape == (0, width)
