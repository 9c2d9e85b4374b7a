"""Per-tube bending stiffness (`calibrate --fit ...,bending_stiffness`): a robot whose inner tube is
stiffer than its description is recovered, relative to the outer tube, from noisy positions; its
Jacobian column (forward differences) agrees with a fully finite-difference Jacobian."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from ctrkin.calibration import ParameterSet, calibrate
from ctrkin.calibration.fit import _Jacobian, initial_registration
from ctrkin.data import Dataset, schema
from tests.lab_logs import configurations, nylon_robot, to_ctrkin

TRUE_SCALE = 1.6       # the inner tube's E is 1.6 times what the robot file says
NOISE_MM = 0.05


def _dataset(n: int = 60, seed: int = 1) -> Dataset:
    nominal = nylon_robot()
    inner = dataclasses.replace(nominal.tubes[0], youngs_modulus=nominal.tubes[0].youngs_modulus * TRUE_SCALE)
    truth = dataclasses.replace(nominal, tubes=(inner, nominal.tubes[1]))
    ps = ParameterSet(truth, ("registration",))
    model = ps.model(np.array([0.3, -0.2, 1.1, 20.0, -35.0, 110.0]))
    joints = nominal.project_joints(to_ctrkin(nominal, configurations(n, seed=seed)))
    pos = model.predict(joints)[:, :3] + np.random.default_rng(seed).normal(scale=NOISE_MM, size=(n, 3))
    frame = pd.DataFrame({"sequence_id": np.zeros(n, np.int64), "step": np.arange(n, dtype=np.int64),
                          **{c: joints[:, k] for k, c in enumerate(schema.joint_columns(2))},
                          "x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2], "q0": 1.0, "qx": 0.0, "qy": 0.0,
                          "snap": False, "outlier": False})
    return Dataset(frame, nominal, meta={"orientation": "absent"})


def test_bending_stiffness_of_the_inner_tube_is_recovered():
    ds = _dataset()
    res = calibrate(ds, groups=("registration", "bending_stiffness"), max_nfev=40, prior=False)
    got = dict(zip(res.params.names, res.x, strict=True))
    assert list(got) == ["reg_rot_x", "reg_rot_y", "reg_rot_z", "reg_t_x", "reg_t_y", "reg_t_z",
                         "bending_scale_1"]
    assert got["bending_scale_1"] == pytest.approx(TRUE_SCALE, rel=0.05)
    assert res.mean_mm < 3 * NOISE_MM * np.sqrt(3) < res.nominal_mean_mm
    assert res.model.robot.tubes[1].youngs_modulus == ds.robot.tubes[1].youngs_modulus   # the reference


def test_its_jacobian_column_matches_forward_differences():
    ds = _dataset(n=12)
    ps = ParameterSet(ds.robot, ("registration", "precurvature", "bending_stiffness"))
    joints, meas = ds.joints(), ds.poses()[:, :3]
    reg = initial_registration(ds.robot, joints, meas)
    x = ps.nominal(reg)
    x[ps.names.index("bending_scale_1")] = 1.3
    mixed = _Jacobian(ps, joints, meas, reg).jacobian(x)
    fd = _Jacobian(ps, joints, meas, reg, analytic=False).jacobian(x)
    np.testing.assert_allclose(mixed, fd, rtol=1e-3, atol=1e-3)
