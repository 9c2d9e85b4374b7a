"""The exact tip sensitivities (calibration/sensitivity.py) against central finite differences of
the point-wise TCM, and the calibration Jacobian built from them against its finite-difference
twin."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ctrkin.calibration.fit import _Jacobian, initial_registration
from ctrkin.calibration.params import ParameterSet
from ctrkin.calibration.sensitivity import tip_jacobian
from ctrkin.mechanics.pointwise import _integrate, cold_solution, prepare
from ctrkin.mechanics.settings import DEFAULT_SETTINGS
from ctrkin.robots.robot import Robot
from ctrkin.robots.tube import Section
from tests.lab_logs import configurations, nylon_robot, to_ctrkin

H = 1e-5         # central-difference step (relative for c, absolute otherwise)
# Central differences of a tip that moves ~10 mm per unit parameter: truncation ~H² · 10³ and
# round-off ~1e-12 / H leave ~1e-7; the sensitivities are exact for the same discrete map.
ATOL = 1e-6


def _tip(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pb = prepare(robot, q, DEFAULT_SETTINGS, checked=True)
    x, conv, *_ = cold_solution(pb, DEFAULT_SETTINGS)
    assert conv
    tip, tan, _, _ = _integrate(pb, x, record=False)
    return tip, tan


def _perturbed(robot: Robot, q: np.ndarray, kind: str, i: int, h: float) -> tuple[Robot, np.ndarray]:
    tubes, q = list(robot.tubes), q.copy()
    n = robot.n_tubes
    if kind == "c":
        t = tubes[i]
        tubes[i] = dataclasses.replace(t, curvature=t.curvature * (1 + h),
                                       sections=tuple(Section(s.length, s.curvature * (1 + h))
                                                      for s in t.sections))
    elif kind == "rho":
        tubes[i] = dataclasses.replace(tubes[i], poisson_ratio=tubes[i].poisson_ratio + h)
    elif kind == "alpha":
        q[i] += np.degrees(h)
    elif kind == "beta":
        q[n + i] += h
    out = dataclasses.replace(robot, tubes=tuple(tubes))
    if kind == "e":
        tl = list(robot.transmission_length)
        tl[i] += h
        out = dataclasses.replace(out, transmission_length=tuple(tl))
    return out, q


@pytest.mark.parametrize("transmission", ["compliant", "rigid"])
def test_tip_jacobian_matches_central_differences(transmission):
    robot = dataclasses.replace(nylon_robot(), transmission=transmission,
                                transmission_length=(30.0, 60.0) if transmission == "compliant" else ())
    joints = robot.project_joints(to_ctrkin(robot, configurations(4, seed=3)))
    n = robot.n_tubes
    for q in joints:
        pb = prepare(robot, q, DEFAULT_SETTINGS, checked=True)
        x, conv, *_ = cold_solution(pb, DEFAULT_SETTINGS)
        assert conv
        tip, jp, tan, jt = tip_jacobian(pb, x)
        tip0, tan0 = _tip(robot, q)
        np.testing.assert_allclose(tip, tip0, atol=1e-12)       # the same discrete map
        np.testing.assert_allclose(tan, tan0, atol=1e-12)
        for col, (kind, i) in enumerate((k, i) for k in ("c", "rho", "alpha", "beta", "e") for i in range(n)):
            if kind == "e" and transmission == "rigid":    # no transmission to lengthen
                assert not jp[:, col].any() and not jt[:, col].any()
                continue
            plus, minus = _perturbed(robot, q, kind, i, H), _perturbed(robot, q, kind, i, -H)
            (tp, ap), (tm, am) = _tip(*plus), _tip(*minus)
            np.testing.assert_allclose(jp[:, col], (tp - tm) / (2 * H), atol=ATOL, err_msg=f"{kind}{i}")
            np.testing.assert_allclose(jt[:, col], (ap - am) / (2 * H), atol=ATOL, err_msg=f"{kind}{i}")


def test_calibration_jacobian_analytic_matches_finite_difference_columns():
    robot = dataclasses.replace(nylon_robot(), transmission_length=(40.0, 80.0))
    ps = ParameterSet(robot)
    joints = robot.project_joints(to_ctrkin(robot, configurations(12, seed=5)))
    meas = ps.model(ps.nominal()).robot_frame(joints)[0] + 1.0
    reg = initial_registration(robot, joints, meas)
    x = ps.nominal(reg)
    for name, value in {"curvature_scale_1": 0.9, "curvature_scale_2": 1.1, "stiffness_ratio_1": 1.3,
                        "alpha_offset_1": 5.0, "beta_offset_1": 2.0, "marker_mm": 4.0}.items():
        x[ps.names.index(name)] = value
    exact = _Jacobian(ps, joints, meas, reg, analytic=True)
    central = []
    for k in range(x.size):     # central differences of the residuals, one parameter at a time
        xp, xm = x.copy(), x.copy()
        xp[k] += H
        xm[k] -= H
        central.append((exact.residuals(xp) - exact.residuals(xm)) / (2 * H))
    jac = exact.jacobian(x)
    np.testing.assert_allclose(jac, np.column_stack(central), atol=1e-4 * np.abs(jac).max())
