"""A trained model calibrated, saved with its uncertainty and streamed with it
(ctrkin.inference.uncertainty; the method: tests/models/test_uncertainty.py)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from ctrkin import Kinematics
from ctrkin.errors import ModelError
from ctrkin.inference.uncertainty import calibrate, ood_scores, predict_rows


def _parts(ds):
    sid = ds.frame["sequence_id"].to_numpy()
    ids = np.unique(sid)
    return (np.flatnonzero(np.isin(sid, ids[:3])), np.flatnonzero(np.isin(sid, ids[3:5])),
            np.flatnonzero(sid == ids[5]))


@pytest.mark.parametrize("name", ["fk", "ik"])
def test_calibrated_model_saved_loaded_and_streamed(model_dirs, sweeps, tmp_path, name):
    folder = tmp_path / name
    shutil.copytree(model_dirs[name], folder)
    kin = Kinematics.load(folder)
    assert kin.uncertainty is None                       # never calibrated: loads as before
    with pytest.raises(ModelError, match="no calibrated uncertainty"):
        kin.step_uncertain(sweeps.joints()[0] if name == "fk" else sweeps.poses()[0])
    train_rows, cal_rows, test_rows = _parts(sweeps)
    # two calibration sweeps cannot give a 90 % interval (the correction counts sequences: 0.9·3/2 > 1)
    assert calibrate(kin, sweeps, train_rows, cal_rows).radius == np.inf
    unc = calibrate(kin, sweeps, train_rows, cal_rows, level=0.6)         # 0.6·3/2 = 0.9
    assert np.isfinite(unc.radius) and unc.n_calibration == len(cal_rows)
    pred, truth = predict_rows(kin, sweeps)
    err = np.abs(pred[cal_rows] - truth[cal_rows])
    assert np.mean(unc.covers(pred[cal_rows], truth[cal_rows])) >= 0.9      # the conformal rank
    assert err.size
    unc.save(folder)
    kin = Kinematics.load(folder)
    assert kin.uncertainty is not None and kin.uncertainty.radius == unc.radius
    x = (sweeps.joints() if name == "fk" else sweeps.poses())[test_rows]
    # an IK scores the robot's joints beside the pose: those when each pose was asked (the row before;
    # the sequence's first row its own, where the robot starts)
    q = {"joints": sweeps.joints()[np.r_[test_rows[0], test_rows[:-1]]]} if name == "ik" else {}
    batch = kin.predict_uncertain(x, **q)
    kin.reset()
    steps = [kin.step_uncertain(v, joints=None if name == "fk" else q["joints"][t]) for t, v in enumerate(x)]
    assert np.array_equal([s.ood_score for s in steps], batch.ood_score)      # the same kernels: to the bit
    assert np.allclose(batch.ood_score, ood_scores(unc, kin, sweeps, test_rows), atol=1e-9)
    assert np.array_equal(steps[0].half_width, unc.half_widths())
    assert kin.copy().uncertainty is kin.uncertainty


def test_calibration_rows_must_be_held_out(model_dirs, sweeps):
    kin = Kinematics.load(model_dirs["fk"])
    rows = np.arange(50)
    with pytest.raises(ModelError, match="held out"):
        calibrate(kin, sweeps, rows, rows[10:20])
