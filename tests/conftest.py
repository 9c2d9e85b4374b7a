"""Shared fixtures. Every random draw in the tests is seeded."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.robots import paper_robot


@pytest.fixture(scope="session")
def robot():
    return paper_robot()


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
