"""μ among the calibrated parameters (issue 20, goal 4): fitted on the continued TCM."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from ctrkin import follow, paper_robot
from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.calibration import calibrate
from ctrkin.calibration.friction import sequences
from ctrkin.calibration.params import ALL_GROUPS, FRICTION, GROUPS, default_groups
from ctrkin.data import Dataset, schema
from ctrkin.geometry import Registration

TRUE_MU = 0.25
NOISE_MM = 0.05


def _rubbing_dataset() -> Dataset:
    """Two rotation sweeps (d = 8 and 12 mm, 3° steps) of the paper robot with μ = 0.25 between its
    tubes, seen through a known registration with 0.05 mm noise."""
    robot = dataclasses.replace(paper_robot(), friction=TRUE_MU)
    reg = Registration.from_rotvec(np.array([0.1, -0.2, 0.3]), np.array([5.0, -3.0, 40.0]))
    rng = np.random.default_rng(0)
    frames = []
    for k, d in enumerate((8.0, 12.0)):
        Q = rotation_sweep(2, d, step_deg=3.0)
        tr = follow(robot, Q)
        pos = reg.apply_points(tr.tip_positions) + rng.normal(scale=NOISE_MM, size=(len(Q), 3))
        frames.append(pd.DataFrame({
            "sequence_id": np.full(len(Q), k, dtype=np.int64), "step": np.arange(len(Q), dtype=np.int64),
            **{c: Q[:, j] for j, c in enumerate(schema.joint_columns(2))},
            "x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2], "q0": 1.0, "qx": 0.0, "qy": 0.0,
            "snap": False, "outlier": False}))
    return Dataset(pd.concat(frames, ignore_index=True), paper_robot(), meta={"orientation": "absent"})


@pytest.fixture(scope="module")
def rubbing() -> Dataset:
    return _rubbing_dataset()


def test_friction_is_a_default_group_only_for_a_robot_with_friction() -> None:
    assert default_groups(paper_robot()) == GROUPS
    assert default_groups(dataclasses.replace(paper_robot(), friction=0.1)) == (*GROUPS, FRICTION)
    assert FRICTION in ALL_GROUPS and "bending_stiffness" in ALL_GROUPS   # both only when named


def test_calibration_recovers_the_friction_between_the_tubes(rubbing: Dataset) -> None:
    """Registration by least squares, then μ on the continued TCM along the whole sequences: close
    to the true 0.25, and the continued fit far better than the frictionless one."""
    res = calibrate(rubbing, groups=("registration", "friction"), max_nfev=30, prior=False)
    got = dict(zip(res.params.names, res.x, strict=True))
    assert abs(got["friction_mu"] - TRUE_MU) < 0.03, got["friction_mu"]
    fr = res.friction
    assert fr["samples"] == len(rubbing.frame)
    assert fr["rms_mm"] < 0.5 * fr["rms_frictionless_mm"]
    assert fr["rms_mm"] < 4 * NOISE_MM * np.sqrt(3)
    assert 0 < fr["std"] < 0.03
    assert res.model.robot.friction == pytest.approx(got["friction_mu"])
    cont = res.model.predict_continued(rubbing.joints(), rubbing.sequence_bounds())
    err = np.linalg.norm(cont[:, :3] - rubbing.poses()[:, :3], axis=1)
    assert np.sqrt(np.mean(err ** 2)) == pytest.approx(fr["rms_mm"], rel=0.05)


def test_friction_fit_takes_whole_sequences_within_a_budget() -> None:
    bounds = [(0, 100), (100, 250), (250, 300), (300, 500)]
    assert sequences(bounds, None, max_samples=1000) == bounds
    some = sequences(bounds, None, max_samples=260)
    assert sum(b - a for a, b in some) <= 260 and some
    assert sequences(bounds, np.array([120, 130, 310])) == [(100, 250), (300, 500)]
