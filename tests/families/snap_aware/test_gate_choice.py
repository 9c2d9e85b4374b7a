"""Which gate a snap-aware FK uses: the fold gate unless the validation sequences prefer the learned
one with confidence (ctrkin.families.snap_aware.gate_choice), and a model folder that keeps its fold
gate aside."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

import ctrkin
from ctrkin.families.snap_aware.fold_gate import FOLD_GATE_FILE
from ctrkin.families.snap_aware.gate_choice import LEVEL, choose_gate, judge_gates
from ctrkin.util.folders import write_manifest


def _rows(errors_fold: list[float], errors_learned: list[float], per: int = 50
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Positions along x with one constant error per sequence for each gate: (fold, learned, target,
    sequence)."""
    seq = np.repeat(np.arange(len(errors_fold)), per)
    target = np.zeros((len(seq), 3))
    fold, learned = target.copy(), target.copy()
    fold[:, 0] = np.repeat(errors_fold, per)
    learned[:, 0] = np.repeat(errors_learned, per)
    return fold, learned, target, seq


def test_the_learned_gate_is_chosen_only_where_it_is_better_with_confidence() -> None:
    # better on every sequence: chosen
    c = choose_gate(*_rows([2.0] * 8, [1.0] * 8))
    assert not c.use_fold and c.p_learned_better == 1.0
    assert c.fold_mm == pytest.approx(2.0) and c.learned_mm == pytest.approx(1.0)
    # better on average, but by one sequence of eight: the resamples without it disagree
    c = choose_gate(*_rows([1.0] * 7 + [5.0], [1.2] * 7 + [1.0]))
    assert c.learned_mm < c.fold_mm and c.use_fold and c.p_learned_better < LEVEL
    # a tie: the fold gate stays
    c = choose_gate(*_rows([1.0, 2.0, 1.0, 2.0], [2.0, 1.0, 2.0, 1.0]))
    assert c.use_fold
    # one validation sequence cannot say: the fold gate stays
    c = choose_gate(*_rows([3.0], [1.0]))
    assert c.use_fold and c.sequences == 1
    assert c.to_dict()["gate"] == "fold"


def test_a_folder_whose_validation_chose_the_learned_gate(model_dirs, sweeps, tmp_path) -> None:
    """fold_gate.json with in_use false: the model switches by its learned gate in batch and streaming,
    `gate="fold"` still reaches the fold gate, and the choice on the folder's own rows is reported
    (judge_gates, as training makes it)."""
    folder = tmp_path / "fk_branch"
    shutil.copytree(model_dirs["fk_branch"], folder)
    original = ctrkin.Kinematics.load(folder)
    joints = sweeps.joints()
    fold = original.predict(joints)
    learned = original.predict(joints, gate="learned")
    assert np.abs(fold - learned).max() > 0            # the two gates differ on these sweeps
    d = json.loads((folder / FOLD_GATE_FILE).read_text())
    assert d["in_use"] is True
    (folder / FOLD_GATE_FILE).write_text(json.dumps({**d, "in_use": False}))
    write_manifest(folder, skip=("checkpoint.pt",))       # as training writes the folder
    kin = ctrkin.Kinematics.load(folder)
    assert kin.fold_gate is None and "learned gate" in repr(kin)
    np.testing.assert_array_equal(kin.predict(joints), learned)
    np.testing.assert_array_equal(kin.predict(joints, gate="fold"), fold)
    kin.reset()
    stream = np.array([kin.step(q) for q in joints[:40]])
    np.testing.assert_allclose(stream, kin.predict(joints[:40]), atol=1e-4)
    rows, target = np.arange(0, len(joints), 3), sweeps.poses()
    choice = judge_gates(kin.predictor, sweeps, rows, target)
    by_fold, by_learned = kin.predict(sweeps, gate="fold"), kin.predict(sweeps, gate="learned")
    expect = choose_gate(by_fold[rows, :3], by_learned[rows, :3], target[rows, :3],
                         sweeps.frame["sequence_id"].to_numpy()[rows])
    assert choice == expect and choice.sequences == len(sweeps.sequence_bounds())


def test_training_reports_the_choice(model_dirs) -> None:
    metrics = json.loads((model_dirs["fk_branch"] / "metrics.json").read_text())
    gate = json.loads((model_dirs["fk_branch"] / FOLD_GATE_FILE).read_text())
    assert metrics["gate"]["gate"] == ("fold" if gate["in_use"] else "learned")
    keys = {"val_position_rmse_fold_mm", "val_position_rmse_learned_mm", "p_learned_better"}
    assert keys <= set(metrics["gate"])
