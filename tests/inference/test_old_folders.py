"""Model folders written by main 94a32c9, before the model families moved into ctrkin.families, still
load and predict what they predicted then (tests/inference/old_folders/make_old_folders.py made them):
the paper's LSTM-MLP FK and IK, a CNN FK, the snap-aware FK with its fold gate and outer frame, the
follow IK and the IK refined on the snap-aware FK, in batch and streaming over the first sequence.
The inputs are those main made (inputs.npz: joints, poses and sequence ids of a TCM sweep dataset),
not the data maker's output today: the mechanics may round the last bits of a pose differently
(main 4e95246 differs by 9e-15 mm), and the refined IK's Levenberg-Marquardt steps on a learned FK
that jumps at the branch turn such a difference into another answer near α = ±180°. For the same
reason the refined IK's own answers are compared only where they cannot depend on the CPU: another
CPU's float32 rounding (1e-5 in the direct IK's joints on an AMD EPYC against the Intel host that
made the folders) changes which of its LM starts wins from row 27 on (436 of 546 rows then differ),
so its parts are compared instead: the direct IK and the FK it refines on, each against what its own
folder predicted, the refinement's settings, the workspace flags, and stream = batch here."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ctrkin.families.refined.refine import RefineSettings
from ctrkin.inference import Kinematics

FOLDERS = Path(__file__).parent / "old_folders" / "main_94a32c9"
NAMES = ("fk_lstm_mlp", "ik_lstm_mlp", "fk_cnn", "fk_lstm_mlp_branch", "ik_follow_mlp")
# float32 networks: another CPU may round the last bits differently; a wrong load is off by millimetres
ATOL = 1e-4


@pytest.fixture(scope="module")
def data():
    return np.load(FOLDERS / "inputs.npz"), np.load(FOLDERS / "expected.npz")


@pytest.mark.parametrize("name", NAMES)
def test_a_folder_from_main_predicts_as_it_did(data, name: str) -> None:
    inputs, expected = data
    kin = Kinematics.load(FOLDERS / name)
    sid = inputs["sequence_id"]
    first = int(np.sum(sid == sid[0]))                       # the first sequence's rows
    x = inputs["joints"] if kin.task == "fk" else inputs["poses"]
    res = kin.predict(x, sid)
    kin.reset()
    steps = [kin.step(v) for v in x[:first]]
    if kin.task == "fk":
        np.testing.assert_allclose(np.asarray(res), expected[f"{name}/batch"], rtol=0, atol=ATOL)
        np.testing.assert_allclose(np.array(steps), expected[f"{name}/stream"], rtol=0, atol=ATOL)
    else:
        np.testing.assert_allclose(res.joints, expected[f"{name}/batch"], rtol=0, atol=ATOL)
        np.testing.assert_array_equal(res.in_workspace, expected[f"{name}/in_workspace"])
        np.testing.assert_allclose(np.array([s.joints for s in steps]), expected[f"{name}/stream"],
                                   rtol=0, atol=ATOL)


def test_the_old_refined_folder_refines_with_the_parts_it_had(data) -> None:
    inputs, expected = data
    kin = Kinematics.load(FOLDERS / "ik_lstm_mlp_refined")
    pred, sid, poses = kin.predictor, inputs["sequence_id"], inputs["poses"]
    direct = pred.direct.predict(poses, sid)               # the IK network it refines: ik_lstm_mlp's
    np.testing.assert_allclose(direct.joints, expected["ik_lstm_mlp/batch"], rtol=0, atol=ATOL)
    fk = Kinematics.load(FOLDERS / "ik_lstm_mlp_refined" / "fk")  # the FK it refines on: the branch FK's
    np.testing.assert_allclose(np.asarray(fk.predict(inputs["joints"], sid)),
                               expected["fk_lstm_mlp_branch/batch"], rtol=0, atol=ATOL)
    saved = json.loads((FOLDERS / "ik_lstm_mlp_refined" / "refine.json").read_text())
    assert pred.settings.to_dict() == RefineSettings.from_dict(saved).to_dict()
    res = kin.predict(poses, sid)
    np.testing.assert_array_equal(res.in_workspace, expected["ik_lstm_mlp_refined/in_workspace"])
    first = int(np.sum(sid == sid[0]))
    kin.reset()
    steps = np.array([kin.step(v).joints for v in poses[:first]])
    np.testing.assert_array_equal(steps, res.joints[:first])
    assert np.isfinite(res.residual_mm).all()


def test_the_old_folders_are_the_families_they_were() -> None:
    kinds = {name: repr(Kinematics.load(FOLDERS / name)) for name in (*NAMES, "ik_lstm_mlp_refined")}
    assert "fold_gate" in kinds["fk_lstm_mlp_branch"] and "refined" in kinds["ik_lstm_mlp_refined"]
    assert "model='follow_mlp'" in kinds["ik_follow_mlp"] and "model='cnn'" in kinds["fk_cnn"]
