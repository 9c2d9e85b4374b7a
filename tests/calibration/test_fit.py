"""Calibration recovers known parameters of a virtual robot from noisy positions."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from ctrkin.calibration import CalibratedTCM, ParameterSet, calibrate, leave_one_sequence_out
from ctrkin.cli.main import cli
from ctrkin.data import Dataset, schema
from ctrkin.errors import CtrkinError
from tests.lab_logs import configurations, nylon_robot, to_ctrkin

GROUPS = ("registration", "precurvature", "alpha_offset", "beta_offset", "marker")
TRUE = {"reg_rot_x": 0.3, "reg_rot_y": -0.2, "reg_rot_z": 1.1, "reg_t_x": 20.0, "reg_t_y": -35.0,
        "reg_t_z": 110.0, "curvature_scale_1": 0.85, "curvature_scale_2": 1.1, "alpha_offset_1": 6.0,
        "beta_offset_1": 2.0, "marker_mm": 5.0}
NOISE_MM = 0.05
# Tolerances: 2-6 standard errors of the fit at this noise and sample count (asserted below)
TOL = {"curvature_scale_1": 0.02, "curvature_scale_2": 0.02, "alpha_offset_1": 1.0,
       "beta_offset_1": 0.5, "marker_mm": 1.0}


def _virtual_dataset(n: int = 90, seed: int = 0) -> tuple[Dataset, ParameterSet]:
    robot = nylon_robot()
    ps = ParameterSet(robot, GROUPS)
    truth = ps.model(np.array([TRUE[k] for k in ps.names]))
    joints = robot.project_joints(to_ctrkin(robot, configurations(n, seed=seed)))
    pos = truth.predict(joints)[:, :3] + np.random.default_rng(seed).normal(scale=NOISE_MM, size=(n, 3))
    seq = np.repeat(np.arange(3), n // 3)
    frame = pd.DataFrame({"sequence_id": seq.astype(np.int64),
                          "step": np.tile(np.arange(n // 3), 3).astype(np.int64),
                          **{c: joints[:, k] for k, c in enumerate(schema.joint_columns(2))},
                          "x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2], "q0": 1.0, "qx": 0.0, "qy": 0.0,
                          "snap": False, "outlier": False})
    ds = Dataset(frame, robot, meta={"orientation": "absent", "sequence_labels": ["a", "b", "c"]})
    return ds, ps


@pytest.fixture(scope="module")
def virtual():
    return _virtual_dataset()


def test_calibration_recovers_known_parameters(virtual):
    ds, _ = virtual
    res = calibrate(ds, groups=GROUPS, max_nfev=40, prior=False)   # the prior assumes ~1 mm errors
    got = dict(zip(res.params.names, res.x, strict=True))
    for name, tol in TOL.items():
        assert abs(got[name] - TRUE[name]) < tol, (name, got[name], TRUE[name])
    assert res.mean_mm < 2.5 * NOISE_MM * np.sqrt(3)      # at the noise floor
    assert res.nominal_mean_mm > 5 * res.mean_mm           # the nominal robot is clearly worse
    assert np.all(np.isfinite(res.std)) and np.all(res.std[6:] < np.array(list(TOL.values())))


def test_leave_one_sequence_out_is_near_the_noise_floor(virtual):
    ds, _ = virtual
    loso = leave_one_sequence_out(ds, groups=GROUPS, max_nfev=30, prior=False)
    assert set(loso["per_sequence"]) == {"a", "b", "c"}
    assert loso["mean_mm"] < 0.3


def test_calibrate_cli_writes_a_normal_robot_file(tmp_path, virtual):
    ds, _ = virtual
    ds.save(tmp_path / "ds")
    out = tmp_path / "cal.toml"
    r = CliRunner().invoke(cli, ["calibrate", "--data", str(tmp_path / "ds"), "--out", str(out),
                                 "--fit", ",".join(GROUPS), "--max-evaluations", "30", "--no-prior"])
    assert r.exit_code == 0, r.output
    assert "curvature_scale_1" in r.output
    from ctrkin.robots.robot import Robot

    robot = Robot.from_toml(out)                       # loads as an ordinary robot
    assert abs(robot.tubes[0].curvature - 0.014 * TRUE["curvature_scale_1"]) < 0.014 * 0.02
    model = CalibratedTCM.from_file(out)
    err = np.linalg.norm(model.predict(ds.joints())[:, :3] - ds.poses()[:, :3], axis=1)
    assert err.mean() < 0.2
    r = CliRunner().invoke(cli, ["evaluate", "--data", str(tmp_path / "ds"), "--predictor", str(out),
                                 "--predictor", "tcm", "--out", str(tmp_path / "ev")])
    assert r.exit_code == 0, r.output
    assert "orientation: not measured" in r.output
    assert (tmp_path / "ev" / "cal" / "tips.png").is_file()        # named after the predictor (issue 22)


def test_analytic_registration_and_marker_columns_match_finite_differences(virtual):
    from ctrkin.calibration.fit import _Jacobian, initial_registration

    ds, ps = virtual
    joints, meas = ds.joints()[:20], ds.poses()[:20, :3]
    problem = _Jacobian(ps, joints, meas, initial_registration(ps.robot, joints, meas))
    x = np.array([TRUE[k] for k in ps.names]) + 0.01
    jac = problem.jacobian(x)
    for k, name in enumerate(ps.names):
        if not (name.startswith("reg_") or name == "marker_mm"):
            continue
        h = 1e-5
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        fd = (problem.residuals(xp) - problem.residuals(xm)) / (2 * h)
        np.testing.assert_allclose(jac[:, k], fd, atol=1e-4, err_msg=name)


def test_prior_rows_pull_physical_parameters_only(virtual):
    from ctrkin.calibration.fit import PRIOR_SCALE_MM, _Jacobian, initial_registration

    ds, ps = virtual
    sigma = ps.prior_sigma()
    assert np.all(np.isinf(sigma[:6])) and np.all(np.isfinite(sigma[6:]))
    joints, meas = ds.joints()[:5], ds.poses()[:5, :3]
    problem = _Jacobian(ps, joints, meas, initial_registration(ps.robot, joints, meas))
    x = ps.nominal() + 1.0
    r = problem.residuals(x)
    assert r.shape == (15 + len(x),)
    np.testing.assert_allclose(r[15:], PRIOR_SCALE_MM / sigma)    # 0 for the registration


def test_nested_loso_chooses_the_prior_strength_without_the_held_out_sequence(virtual, monkeypatch):
    import ctrkin.calibration.fit as fit

    ds, _ = virtual
    seen: list[tuple[float, frozenset[int]]] = []
    inner = fit._inner_loso

    def spy(robot, groups, joints, measured, sid, rows, max_nfev, scale):
        seen.append((scale, frozenset(np.unique(sid[rows]).tolist())))
        return inner(robot, groups, joints, measured, sid, rows, max_nfev, scale)

    monkeypatch.setattr(fit, "_inner_loso", spy)
    loso = leave_one_sequence_out(ds, groups=GROUPS, max_nfev=15, prior_scales=(1.0, 100.0))
    # each outer fold scored each candidate on its two training sequences only
    assert sorted(seen) == sorted((c, frozenset(s)) for c in (1.0, 100.0)
                                  for s in ({1, 2}, {0, 2}, {0, 1}))
    # noise 0.05 mm and a 1 mm-scaled prior: the weak prior (true values are far from nominal) wins
    assert set(loso["prior_scale"].values()) == {100.0}
    assert loso["mean_mm"] < 0.3
    with pytest.raises(CtrkinError, match="at least 3 sequences"):
        leave_one_sequence_out(ds, groups=GROUPS, prior=False, prior_scales=(1.0, 2.0))


def test_calibrate_cli_nested_prior_scales(tmp_path, virtual):
    ds, _ = virtual
    ds.save(tmp_path / "ds")
    args = ["calibrate", "--data", str(tmp_path / "ds"), "--out", str(tmp_path / "cal.toml"),
            "--fit", ",".join(GROUPS), "--max-evaluations", "10", "--loso"]
    r = CliRunner().invoke(cli, [*args, "--prior-scales", "1,100"])
    assert r.exit_code == 0, r.output
    assert "prior scale chosen by nested leave-one-sequence-out: a 100, b 100, c 100" in r.output
    r = CliRunner().invoke(cli, [*args, "--prior-scales", "1,x"])
    assert r.exit_code != 0 and "--prior-scales" in r.output and "0.5,1,2" in r.output
