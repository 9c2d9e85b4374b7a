"""Make the model folders of tests/inference/test_old_folders.py (run once, on main 94a32c9, before
the model families moved into ctrkin.families; kept to say how the folders were made; its imports
are today's paths: on main they were ctrkin.training.demo and ctrkin.inference.refine_folder).

    python tests/inference/old_folders/make_old_folders.py tests/inference/old_folders/main_94a32c9

Small networks on a small TCM dataset: the paper's LSTM-MLP FK and IK, a CNN FK, the snap-aware FK
(fold gate, outer frame), the follow IK and the IK refined on the snap-aware FK; inputs.npz, the
dataset's joints, poses and sequence ids; and expected.npz, what each predicted from them (batch,
and streaming over the first sequence) on main.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np

from ctrkin.acquisition.demo import sweep_dataset
from ctrkin.families.refined.folder import assemble_refined
from ctrkin.inference import Kinematics
from ctrkin.robots import paper_robot
from ctrkin.training import TrainConfig, train


def dataset():
    return sweep_dataset(paper_robot(), translations=(8, 14, 20), outer_alphas=(0, 90), step_deg=8,
                         noise_mm=0.02, seed=3)


CONFIGS = {
    "fk_lstm_mlp": TrainConfig(task="fk", max_epochs=2, threads=1, options={"structure": "L8|D8"}),
    "ik_lstm_mlp": TrainConfig(task="ik", max_epochs=2, threads=1, options={"structure": "L8|D8"}),
    "fk_cnn": TrainConfig(task="fk", model="cnn", max_epochs=1, threads=1, options={"channels": 4}),
    "fk_lstm_mlp_branch": TrainConfig(task="fk", model="lstm_mlp_branch", max_epochs=2, threads=1,
                                      options={"structure": "L8|D8", "gate_units": 4}),
    "ik_follow_mlp": TrainConfig(task="ik", model="follow_mlp", max_epochs=4, patience=4, threads=1,
                                 options={"structure": "|D16,D16"}),
}


def main(out: Path) -> None:
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    ds = dataset()
    for name, cfg in CONFIGS.items():
        train(ds, cfg, out / name, progress=False)
        (out / name / "checkpoint.pt").unlink(missing_ok=True)      # not in the manifest; 3x the weights
    assemble_refined(out / "ik_lstm_mlp", out / "fk_lstm_mlp_branch", out / "ik_lstm_mlp_refined")
    first = ds.sequence_bounds()[0]
    sid = ds.frame["sequence_id"].to_numpy()
    np.savez_compressed(out / "inputs.npz", joints=ds.joints(), poses=ds.poses(), sequence_id=sid)
    expected = {}
    for name in [*CONFIGS, "ik_lstm_mlp_refined"]:
        kin = Kinematics.load(out / name)
        x = ds.joints() if kin.task == "fk" else ds.poses()
        res = kin.predict(ds)
        kin.reset()
        steps = [kin.step(v) for v in x[first[0]:first[1]]]
        if kin.task == "fk":
            expected[f"{name}/batch"] = np.asarray(res)
            expected[f"{name}/stream"] = np.array(steps)
        else:
            expected[f"{name}/batch"] = res.joints
            expected[f"{name}/in_workspace"] = res.in_workspace
            expected[f"{name}/stream"] = np.array([s.joints for s in steps])
    np.savez_compressed(out / "expected.npz", **expected)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
