"""Model folders written by main 94a32c9, before the model families moved into ctrkin.families, still
load and predict what they predicted then (tests/inference/old_folders/make_old_folders.py made them):
the paper's LSTM-MLP FK and IK, a CNN FK, the snap-aware FK with its fold gate and outer frame, the
follow IK and the IK refined on the snap-aware FK, in batch and streaming over the first sequence.
The inputs are those main made (inputs.npz: joints, poses and sequence ids of a TCM sweep dataset),
not the data maker's output today: the mechanics may round the last bits of a pose differently
(main 4e95246 differs by 9e-15 mm), and the refined IK's Levenberg-Marquardt steps on a learned FK
that jumps at the branch turn such a difference into another answer near α = ±180°."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ctrkin.inference import Kinematics

FOLDERS = Path(__file__).parent / "old_folders" / "main_94a32c9"
NAMES = ("fk_lstm_mlp", "ik_lstm_mlp", "fk_cnn", "fk_lstm_mlp_branch", "ik_follow_mlp", "ik_lstm_mlp_refined")
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


def test_the_old_folders_are_the_families_they_were() -> None:
    kinds = {name: repr(Kinematics.load(FOLDERS / name)) for name in NAMES}
    assert "fold_gate" in kinds["fk_lstm_mlp_branch"] and "refined" in kinds["ik_lstm_mlp_refined"]
    assert "model='follow_mlp'" in kinds["ik_follow_mlp"] and "model='cnn'" in kinds["fk_cnn"]
