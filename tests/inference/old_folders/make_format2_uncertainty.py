"""Make the format-2 uncertainty files of tests/inference/test_old_uncertainty.py (run once, on main
458d7e8, the last uncertainty format 2: parts as (P + 1,) column boundaries; kept to say how they were
made).

    python tests/inference/old_folders/make_format2_uncertainty.py tests/inference/old_folders/main_458d7e8

The paper's LSTM-MLP FK and IK of main_94a32c9 calibrated on the sequences of its inputs.npz (the first
three what they trained on, the next two the calibration rows, level 0.6: two sequences cannot give
0.9) with 100 reference rows (small files), each with main's default parts (FK: configuration,
history; IK: pose, joints, pose history, joint history), the IK scoring the pose and the joints of
the row before; and expected.npz, the OOD scores main gave the last sequence in batch and streaming.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ctrkin.data.schema import sequence_bounds
from ctrkin.inference import Kinematics
from ctrkin.models.ood import joints_before
from ctrkin.models.uncertainty import Uncertainty

OLD = Path(__file__).parent / "main_94a32c9"


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    inputs = np.load(OLD / "inputs.npz")
    sid, poses, joints = inputs["sequence_id"], inputs["poses"], inputs["joints"]
    bounds = sequence_bounds(sid)
    rows = [np.arange(a, b) for a, b in bounds]
    train, cal, test = np.concatenate(rows[:3]), np.concatenate(rows[3:5]), rows[5]
    x = {"fk": joints, "ik": np.hstack([poses, joints_before(joints, bounds)])}
    expected = {"test_rows": test}
    for task in ("fk", "ik"):
        kin = Kinematics.load(OLD / f"{task}_lstm_mlp")
        pred = kin.predict(joints, sid)[:, :3] if task == "fk" else kin.predict(poses, sid).joints
        err = pred - (poses[:, :3] if task == "fk" else joints)
        unc = Uncertainty.fit(task, 2, x[task][train], sequence_bounds(sid[train]), x[task][cal],
                              sequence_bounds(sid[cal]), err[cal], level=0.6, max_reference=100)
        (out / f"{task}_lstm_mlp").mkdir(exist_ok=True)
        unc.save(out / f"{task}_lstm_mlp")
        seq = x[task][test]
        stream = unc.stream()
        expected[f"{task}_batch"] = unc.ood_scores(seq, [(0, len(test))])
        expected[f"{task}_stream"] = np.array([stream.step(r) if task == "fk" else stream.step(r[:6], r[6:])
                                               for r in seq])
    np.savez_compressed(out / "expected.npz", **expected)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
