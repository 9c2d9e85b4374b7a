"""Rig descriptions for the hardware tests (written as dicts; the TOML parsing is tested apart)."""

from __future__ import annotations

import copy
from typing import Any

import pytest

from ctrkin.hardware.rig import RigDescription, parse_rig

CANOPEN_RIG: dict[str, Any] = {
    "name": "test-canopen",
    "robot": "paper",
    "home": [0.0, 0.0, -20.0, 0.0],
    "actuator": {"kind": "canopen", "simulate": True, "simulation_speedup": 20.0, "timeout_s": 20.0,
                 "drives": [
                     {"joint": "alpha_1", "node_id": 1, "gear_ratio": 35.0, "max_velocity": 90.0,
                      "velocity": 60.0},
                     {"joint": "alpha_2", "node_id": 2, "gear_ratio": 35.0, "max_velocity": 90.0,
                      "velocity": 60.0},
                     {"joint": "beta_1", "node_id": 3, "gear_ratio": 5.0, "lead_mm": 1.0, "min": -90.0,
                      "max": 0.0, "max_velocity": 10.0, "velocity": 10.0},
                     {"joint": "beta_2", "node_id": 4, "gear_ratio": 5.0, "lead_mm": 1.0, "min": -40.0,
                      "max": 0.0, "max_velocity": 10.0, "velocity": 10.0, "direction": -1}]},
    "tracker": {"kind": "virtual", "readings": 3},
}


@pytest.fixture
def canopen_rig() -> RigDescription:
    return parse_rig(copy.deepcopy(CANOPEN_RIG), source="test-canopen.toml")
