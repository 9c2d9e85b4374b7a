"""Model folders written by main 94a32c9, before the model families moved into ctrkin.families, still
load and predict what they predicted then (tests/inference/old_folders/make_old_folders.py made them):
the paper's LSTM-MLP FK and IK, a CNN FK, the snap-aware FK with its fold gate and outer frame, the
follow IK and the IK refined on the snap-aware FK, in batch and streaming over the first sequence."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ctrkin.acquisition.demo import sweep_dataset
from ctrkin.inference import Kinematics
from ctrkin.robots import paper_robot

FOLDERS = Path(__file__).parent / "old_folders" / "main_94a32c9"
NAMES = ("fk_lstm_mlp", "ik_lstm_mlp", "fk_cnn", "fk_lstm_mlp_branch", "ik_follow_mlp", "ik_lstm_mlp_refined")
# float32 networks: another CPU may round the last bits differently; a wrong load is off by millimetres
ATOL = 1e-4


@pytest.fixture(scope="module")
def data():
    ds = sweep_dataset(paper_robot(), translations=(8, 14, 20), outer_alphas=(0, 90), step_deg=8,
                       noise_mm=0.02, seed=3)
    return ds, np.load(FOLDERS / "expected.npz")


@pytest.mark.parametrize("name", NAMES)
def test_a_folder_from_main_predicts_as_it_did(data, name: str) -> None:
    ds, expected = data
    kin = Kinematics.load(FOLDERS / name)
    first = ds.sequence_bounds()[0]
    x = ds.joints() if kin.task == "fk" else ds.poses()
    res = kin.predict(ds)
    kin.reset()
    steps = [kin.step(v) for v in x[first[0]:first[1]]]
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
