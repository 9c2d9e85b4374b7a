"""Shared fixtures. Every random draw in the tests is seeded."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.robots import paper_robot
from tests.small_models import six_sweeps, small_configs


@pytest.fixture(scope="session")
def robot():
    return paper_robot()


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(scope="session")
def sweeps():
    """6 rotation sweeps (d = 8, 14, 20 mm; outer α 0, 90°) at 4° steps, 0.02 mm tracker noise."""
    return six_sweeps()


@pytest.fixture(scope="session")
def model_dirs(sweeps, tmp_path_factory):
    """Small trained FK and IK models (few epochs, small LSTM), and the IK refined on the snap-aware FK
    (imported here: the tests of other stages need no torch)."""
    from ctrkin.families.refined import assemble_refined
    from ctrkin.training import train

    root = tmp_path_factory.mktemp("models")
    dirs = {}
    for name, cfg in small_configs().items():
        train(sweeps, cfg, root / name, progress=False)
        dirs[name] = root / name
    dirs["ik_refined"] = assemble_refined(dirs["ik"], dirs["fk_branch"], root / "ik_refined")
    return dirs


@pytest.fixture(scope="session")
def quick_ds():
    """8 rotation sweeps (d = 8, 12, 16, 20 mm; outer α 0, 180°) at 3° steps, 0.02 mm tracker noise."""
    from ctrkin.acquisition.demo import sweep_dataset

    return sweep_dataset(paper_robot(), translations=(8, 12, 16, 20), outer_alphas=(0, 180), step_deg=3,
                         noise_mm=0.02, seed=1)
