"""FK models trained with a calibrated TCM under them (TrainConfig.tcm_prior, ctrkin.models.tcm_prior):
the folder stores the prior, the prediction is the network's residual plus the prior, batch equals
streaming, and what cannot hold the prior (IK, probe, ONNX, a folder without a readable prior) is
refused with a message naming the option."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest
from tests.small_models import six_sweeps

from ctrkin.calibration.model import CalibratedTCM
from ctrkin.data import Split
from ctrkin.errors import ModelError
from ctrkin.inference import Kinematics, export_onnx
from ctrkin.models import tcm_prior
from ctrkin.models.tcm_prior import TCM_PRIOR_FILE, dataset_prior
from ctrkin.training import TrainConfig, train
from ctrkin.util.folders import write_manifest

SMALL = {"max_epochs": 3, "threads": 1, "options": {"structure": "L16|D16"}}
TINY_BUDGET = (200, 8, 2_000)      # reproduce's tiny calibration budget: seconds, not the quick's ~10 s


@pytest.fixture(scope="module")
def prior_models(tmp_path_factory):
    """The six sweeps and two small FK models trained with tcm_prior: the snap-aware model (outer
    tube's frame) and the paper's LSTM-MLP (tracker frame), the prior calibrated on a tiny budget."""
    ds = six_sweeps()
    root = tmp_path_factory.mktemp("prior_models")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(tcm_prior, "PRIOR_BUDGET", TINY_BUDGET)
        train(ds, TrainConfig(task="fk", model="lstm_mlp_branch", tcm_prior=True,
                              **{**SMALL, "options": {"structure": "L16|D16", "gate_units": 8}}),
              root / "branch", progress=False)
        train(ds, TrainConfig(task="fk", tcm_prior=True, **SMALL), root / "paper", progress=False)
    return ds, root


def _without_prior(kin: Kinematics) -> Kinematics:
    """The same network and normalisation with no prior: its predictions are the residual alone."""
    from ctrkin.families.registry import predictor
    from ctrkin.models.predictor import Opened

    return Kinematics(predictor(Opened(dataclasses.replace(kin.bundle, prior=None), None, None, False)))


def test_prior_budget_is_reproduce_quick():
    from ctrkin.evaluation.reproduce import CALIBRATION_BUDGET

    assert tcm_prior.PRIOR_BUDGET == CALIBRATION_BUDGET["quick"]


@pytest.mark.parametrize("name", ["branch", "paper"])
def test_folder_stores_the_prior_and_a_reload_predicts_what_training_reported(prior_models, name):
    ds, root = prior_models
    folder = root / name
    assert (folder / TCM_PRIOR_FILE).is_file()
    assert json.loads((folder / "config.json").read_text())["train"]["tcm_prior"] is True
    kin = Kinematics.load(folder)
    assert kin.bundle.prior is not None and not kin.predictor.fused
    # training's metrics decode the snap-aware model's branch by its learned gate
    pred = kin.predict(ds, gate="learned") if name == "branch" else kin.predict(ds)
    metrics = json.loads((folder / "metrics.json").read_text())
    split = Split.load(folder / "split.json")
    for part in ("train", "val"):
        rows = getattr(split, part)
        err = np.linalg.norm(pred[rows, :3] - ds.poses()[rows, :3], axis=1)
        rmse = float(np.sqrt(np.mean(err ** 2)))
        assert rmse == pytest.approx(metrics[part]["vs_measured"]["position_mm_rmse"], rel=1e-3, abs=1e-3)


def test_tracker_frame_prediction_is_residual_plus_prior(prior_models):
    ds, root = prior_models
    kin = Kinematics.load(root / "paper")
    prior = dataset_prior(CalibratedTCM.from_file(root / "paper" / TCM_PRIOR_FILE), ds)
    full, residual = kin.predict(ds), _without_prior(kin).predict(ds)
    np.testing.assert_allclose(full[:, :3] - residual[:, :3], prior[:, :3], atol=1e-9)
    np.testing.assert_allclose(full[:, 3:], residual[:, 3:], atol=1e-12)   # orientation: no prior
    # the prior is near the data, the residual alone is not a pose of the robot
    tip = ds.poses()[:, :3]
    assert np.median(np.linalg.norm(prior[:, :3] - tip, axis=1)) < 1.0
    assert np.median(np.linalg.norm(residual[:, :3] - tip, axis=1)) > 10.0


def test_outer_frame_prediction_adds_the_prior_in_the_same_frame(prior_models):
    """The snap-aware model learns in the outer tube's frame: the prior is taken to it with the same
    angles, so the full prediction less the residual's is the prior less the registration's
    translation (to_world's affine part counted once)."""
    ds, root = prior_models
    kin = Kinematics.load(root / "branch")
    prior = dataset_prior(kin.bundle.prior, ds)
    # the model without a folder has no fold gate: both decode the branch by the learned gate
    full, residual = kin.predict(ds, gate="learned"), _without_prior(kin).predict(ds)
    t = kin.bundle.frame.registration.translation
    np.testing.assert_allclose(full[:, :3] - residual[:, :3], prior[:, :3] - t, atol=1e-9)


@pytest.mark.parametrize("name", ["branch", "paper"])
def test_batch_equals_streaming(prior_models, name):
    ds, root = prior_models
    kin = Kinematics.load(root / name)
    bounds = ds.sequence_bounds()[:2]
    rows = np.arange(bounds[0][0], bounds[1][1])
    joints = ds.joints()[rows]
    sid = ds.frame["sequence_id"].to_numpy()[rows]
    batch = kin.predict(joints, sequence_id=sid)
    streamed = []
    for t, q in enumerate(joints):
        if t == 0 or sid[t] != sid[t - 1]:
            kin.reset()
        streamed.append(kin.step(q))
    np.testing.assert_allclose(np.array(streamed)[:, :3], batch[:, :3], atol=1e-3)    # float32 network
    np.testing.assert_allclose(np.array(streamed)[:, 3:], batch[:, 3:], atol=1e-4)


def test_ik_refuses_the_option():
    with pytest.raises(ModelError, match="tcm_prior applies to FK models only"):
        TrainConfig(task="ik", tcm_prior=True)


def test_probe_and_onnx_export_are_refused(prior_models, tmp_path):
    ds, root = prior_models
    kin = Kinematics.load(root / "branch")
    assert not kin.probes
    kin.reset()
    with pytest.raises(ModelError, match="tcm_prior"):
        kin.probe(ds.joints()[:3])
    with pytest.raises(ModelError, match="tcm_prior"):
        kin.probe_tips(ds.joints()[:3])
    for allow_downgrade in (False, True):       # the prior is named before the fold gate's downgrade
        with pytest.raises(ModelError, match="tcm_prior"):
            export_onnx(kin, tmp_path / "fk.onnx", allow_downgrade=allow_downgrade)
    assert not (tmp_path / "fk.onnx").exists()


@pytest.mark.parametrize("damage", ["malformed", "missing"])
def test_a_folder_without_a_readable_prior_is_refused(prior_models, tmp_path, damage):
    _, root = prior_models
    folder = tmp_path / "model"
    shutil.copytree(root / "paper", folder)
    path = folder / TCM_PRIOR_FILE
    if damage == "malformed":
        path.write_text("this is = not [a robot file\n")
        match = "not a readable calibrated robot file"
    else:
        path.unlink()
        match = f"lacks {TCM_PRIOR_FILE}"
    write_manifest(folder, skip=("checkpoint.pt",))     # the files as one unit again: the prior is what fails
    with pytest.raises(ModelError, match=match):
        Kinematics.load(folder)
