"""Fixtures for the dataset tests: a small valid dataset, and a robot log of a real (TCM) sweep."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import ctrkin
from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.data import Dataset, schema
from ctrkin.robots import Robot


def synthetic_frame(robot: Robot, lengths: tuple[int, ...] = (12, 8, 10, 6, 9),
                    seed: int = 0) -> pd.DataFrame:
    """Valid joints (a rotation at fixed translation per sequence) and arbitrary unit-quaternion
    poses: enough for format and split tests, which do not look at the physics."""
    rng = np.random.default_rng(seed)
    n = robot.n_tubes
    parts = []
    for k, m in enumerate(lengths):
        q = np.zeros((m, 2 * n))
        q[:, 0] = np.arange(m) * 3.0
        q[:, n] = -rng.uniform(2.0, 20.0)
        quat = rng.normal(size=(m, 3))
        quat /= np.linalg.norm(quat, axis=1, keepdims=True)
        parts.append(pd.DataFrame({
            "sequence_id": np.full(m, k, dtype=np.int64), "step": np.arange(m, dtype=np.int64),
            **{c: q[:, j] for j, c in enumerate(schema.joint_columns(n))},
            "x": rng.normal(size=m), "y": rng.normal(size=m), "z": 50 + rng.normal(size=m),
            "q0": quat[:, 0], "qx": quat[:, 1], "qy": quat[:, 2],
            "snap": rng.random(m) < 0.1, "outlier": np.zeros(m, dtype=bool)}))
    return pd.concat(parts, ignore_index=True)


@pytest.fixture
def small_dataset(robot) -> Dataset:
    return Dataset(frame=synthetic_frame(robot), robot=robot,
                   meta={"protocol": "test", "protocol_params": {"k": 1}, "seed": 7})


@pytest.fixture(scope="session")
def sweep():
    """(Q (T, 4), tip poses (T, 6)) of a 5° rotation sweep at d = 12 mm, solved by continuation."""
    robot = ctrkin.paper_robot()
    q = rotation_sweep(2, 12.0, step_deg=5)
    return q, ctrkin.follow(robot, q).tip_poses


def readings(q: np.ndarray, poses: np.ndarray, n_readings: int = 5, noise_mm: float = 0.0,
             seed: int = 0, dt: float = 0.1) -> pd.DataFrame:
    """A log with `n_readings` tracker readings per joint sample, columns named like the fields:
    time (s), alpha_i (deg), beta_i (mm), x, y, z (mm), q0, qx, qy."""
    rng = np.random.default_rng(seed)
    n = q.shape[1] // 2
    rep_q = np.repeat(q, n_readings, axis=0)
    rep_p = np.repeat(poses, n_readings, axis=0)
    rep_p[:, :3] += rng.normal(scale=noise_mm, size=(len(rep_p), 3)) if noise_mm > 0 else 0.0
    t = np.repeat(np.arange(len(q)) * dt, n_readings) + np.tile(np.arange(n_readings) * dt / 10, len(q))
    return pd.DataFrame({"time": t, **{c: rep_q[:, j] for j, c in enumerate(schema.joint_columns(n))},
                         **{c: rep_p[:, j] for j, c in enumerate(schema.POSE_COLUMNS)}})
