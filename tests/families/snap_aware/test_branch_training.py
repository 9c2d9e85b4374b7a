"""The snap-aware model on a small snapping dataset: both jumps of an unseen full turn, sharp."""

from __future__ import annotations

import numpy as np

from ctrkin.acquisition.demo import sweep_dataset
from ctrkin.data import Split
from ctrkin.evaluation.snapping import azimuth_series, snap_score
from ctrkin.inference import Kinematics
from ctrkin.robots import paper_robot
from ctrkin.training import TrainConfig, train


def test_branch_model_finds_both_jumps_of_a_turn_it_never_saw(tmp_path):
    """Trained on full turns at d = 20 mm at four outer angles, tested on a turn at an outer angle
    between them: the snap-aware model (its fold gate) must predict both snaps (forward and back)
    within ±2 steps, streaming as in batch. The paper's LSTM-MLP trained identically and the
    snap-aware model's learned gate are reported beside it, not asserted."""
    ds = sweep_dataset(paper_robot(), translations=(20.0,), outer_alphas=(0, 90, 180, 270, 45), step_deg=2)
    sid = ds.frame["sequence_id"].to_numpy()
    train_rows, test_rows = np.nonzero(sid < 4)[0], np.nonzero(sid == 4)[0]
    assert ds.frame["snap"].to_numpy()[test_rows].sum() == 2
    ds.split = Split(train_rows, test_rows, test_rows, "sequence", 0, (0.8, 0.2, 0.0))
    joints, truth = ds.joints()[test_rows], ds.poses(true=True)[test_rows]
    bounds = [(0, len(test_rows))]
    ref = azimuth_series(truth, joints, 2, bounds)
    scores = {}
    for model in ("lstm_mlp_branch", "lstm_mlp"):
        cfg = TrainConfig(task="fk", model=model, options={"structure": "L32|D32"}, max_epochs=60,
                          patience=60, batch_size=64, lr=3e-3, lr_schedule="cosine", threads=1,
                          output_activation="linear")
        train(ds, cfg, tmp_path / model, progress=False)
        kin = Kinematics.load(tmp_path / model)
        pred = kin.predict(joints)
        scores[model] = snap_score(azimuth_series(pred, joints, 2, bounds), ref, bounds)
        if model == "lstm_mlp_branch":
            assert kin.fold_gate is not None and (tmp_path / model / "fold_gate.json").is_file()
            kin.reset()
            np.testing.assert_allclose(np.array([kin.step(q) for q in joints]), pred, atol=1e-4)
            learned = kin.predict(joints, gate="learned")
            scores["learned gate"] = snap_score(azimuth_series(learned, joints, 2, bounds), ref, bounds)
    print({m: (s.precision, s.recall, s.magnitude_error_deg) for m, s in scores.items()})
    b = scores["lstm_mlp_branch"]
    assert b.n_reference == 2 and b.n_matched == 2 and b.n_predicted == 2, b
    assert b.magnitude_error_deg < 10.0, b
