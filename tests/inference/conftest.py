"""Small trained FK and IK models (few epochs, small LSTM) for the inference tests."""

from __future__ import annotations

import pytest

from ctrkin.acquisition.demo import sweep_dataset
from ctrkin.inference.refine_folder import assemble_refined
from ctrkin.robots import paper_robot
from ctrkin.training import TrainConfig, train


@pytest.fixture(scope="session")
def sweeps():
    return sweep_dataset(paper_robot(), translations=(8, 14, 20), outer_alphas=(0, 90), step_deg=4,
                         noise_mm=0.02, seed=2)


@pytest.fixture(scope="session")
def model_dirs(sweeps, tmp_path_factory):
    root = tmp_path_factory.mktemp("models")
    dirs = {}
    for name, cfg in {
        "fk": TrainConfig(task="fk", max_epochs=3, threads=1, options={"structure": "L16|D16"}),
        "ik": TrainConfig(task="ik", ib=3, max_epochs=3, threads=1, options={"structure": "L16|D16"}),
        "fk_cnn": TrainConfig(task="fk", model="cnn", max_epochs=1, threads=1, options={"channels": 8}),
        "fk_default": TrainConfig(task="fk", max_epochs=1, threads=1),
        "fk_branch": TrainConfig(task="fk", model="lstm_mlp_branch", max_epochs=3, threads=1,
                                 options={"structure": "L16|D16", "gate_units": 8}),
    }.items():
        train(sweeps, cfg, root / name, progress=False)
        dirs[name] = root / name
    dirs["ik_refined"] = assemble_refined(dirs["ik"], dirs["fk_branch"], root / "ik_refined")
    return dirs
