"""Make the uncertainty file of tests/inference/test_old_uncertainty.py (run once, on main dbab9a8,
before the IK's OOD score took the robot's joints; kept to say how it was made).

    python tests/inference/old_folders/make_old_uncertainty.py tests/inference/old_folders/main_dbab9a8

The paper's LSTM-MLP IK of main_94a32c9 calibrated on the sequences of its inputs.npz (the first
three what it trained on, the next two the calibration rows, level 0.6: two sequences cannot give
0.9) with 100 reference rows (a small file), saved as main wrote it (uncertainty format 1: the IK's
score on the target pose alone); and expected.npz, the OOD scores main gave the last sequence in
batch and streaming.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ctrkin.data.schema import sequence_bounds
from ctrkin.inference import Kinematics
from ctrkin.models.uncertainty import Uncertainty

OLD = Path(__file__).parent / "main_94a32c9"


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    inputs = np.load(OLD / "inputs.npz")
    sid, poses = inputs["sequence_id"], inputs["poses"]
    kin = Kinematics.load(OLD / "ik_lstm_mlp")
    bounds = sequence_bounds(sid)
    pred = kin.predict(poses, sid).joints
    err = pred - inputs["joints"]
    rows = [np.arange(a, b) for a, b in bounds]
    train, cal, test = np.concatenate(rows[:3]), np.concatenate(rows[3:5]), rows[5]

    def runs(r: np.ndarray) -> list[tuple[int, int]]:
        return sequence_bounds(sid[r])

    unc = Uncertainty.fit("ik", 2, poses[train], runs(train), poses[cal], runs(cal), err[cal], level=0.6,
                          max_reference=100)
    (out / "ik_lstm_mlp").mkdir(exist_ok=True)
    unc.save(out / "ik_lstm_mlp")
    stream = unc.stream()
    np.savez_compressed(out / "expected.npz", test_rows=test,
                        batch=unc.ood_scores(poses[test], [(0, len(test))]),
                        stream=np.array([stream.step(p) for p in poses[test]]))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
