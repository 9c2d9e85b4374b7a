"""Small TCM-made datasets for the training tests (seeded; ~1 s to make)."""

from __future__ import annotations

import pytest

from ctrkin.acquisition.demo import sweep_dataset
from ctrkin.robots import paper_robot


@pytest.fixture(scope="session")
def quick_ds():
    """8 rotation sweeps (d = 8, 12, 16, 20 mm; outer α 0, 180°) at 3° steps, 0.02 mm tracker noise."""
    return sweep_dataset(paper_robot(), translations=(8, 12, 16, 20), outer_alphas=(0, 180), step_deg=3,
                         noise_mm=0.02, seed=1)
