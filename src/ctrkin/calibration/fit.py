"""Least-squares calibration (scipy.optimize.least_squares, trust-region reflective, bounded).

Residuals: measured minus predicted marker position (mm) of every sample, the TCM solved point-wise
with no history. Orientation is not fitted (the comet-lab markers do not measure the tip tangent;
evaluation still reports it where a dataset has it).

Jacobian (`_Jacobian`): analytic. Registration and marker columns from the robot-frame solution
at x (∂p/∂t = I, ∂p/∂θk = (∂R/∂θk) m, ∂p/∂d = R t_tip; ∂R/∂θk of the rotation vector by a central
difference of the 3 × 3 matrix, no solve); mechanics columns (precurvature, stiffness ratio,
offsets, transmission length) from the exact tip sensitivities of the TCM (sensitivity.py: forward
mode through the RK4 map plus the implicit function theorem for the shooting unknowns), one
tangent integration per sample at the converged solution instead of one solve per sample and
parameter (8–15 times faster on the comet-lab sets; `analytic=False` keeps forward differences).

With the prior (params.py), residuals (x − x_nominal) / σ_prior · PRIOR_SCALE_MM are appended:
a maximum a posteriori fit for a position error of about PRIOR_SCALE_MM per coordinate.

Friction (group "friction"): a point-wise solve carries no friction load, so μ is fitted after the
other groups on the calibrated robot followed along whole training sequences (friction.py).

Uncertainties: standard errors from the Gauss-Newton covariance σ² (JᵀJ)⁻¹ (prior rows included),
σ² = SSR / (m − p) of the position residuals, at the solution; parameters on a bound are reported
with it. Leave-one-sequence-out (LOSO): each sequence in turn is predicted by a calibration fitted
to the others, starting from nominal values.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ctrkin.calibration.friction import MAX_SAMPLES, fit_friction, sequences
from ctrkin.calibration.model import CalibratedTCM
from ctrkin.calibration.params import FRICTION, GROUPS, ParameterSet, default_groups
from ctrkin.calibration.sensitivity import tip_jacobian
from ctrkin.data.dataset import Dataset
from ctrkin.errors import CtrkinError
from ctrkin.geometry import Registration
from ctrkin.mechanics.pointwise import Equilibrium
from ctrkin.robots.robot import Robot

NAN_PENALTY_MM = 100.0   # residual of a sample whose TCM solve did not converge
PRIOR_SCALE_MM = 1.0     # position error per coordinate the prior is weighed against
PROJECTION_STEP_MM = 1e-6  # step through the piecewise-linear mechanical stops (no TCM solve)


@dataclass(eq=False)
class CalibrationResult:
    """params: the fitted set; x (P,) values, std (P,) standard errors, at_bound (P,) flags;
    model: the calibrated predictor; rms_mm / mean_mm: fit error on all samples; nominal_mean_mm:
    the nominal robot with a fitted registration; loso: per-sequence held-out errors (mm);
    friction: the μ fit on the continued TCM (friction.fit_friction), empty without the group."""

    params: ParameterSet
    x: np.ndarray
    std: np.ndarray
    at_bound: np.ndarray
    model: CalibratedTCM
    rms_mm: float
    mean_mm: float
    nominal_mean_mm: float
    n_samples: int
    nfev: int
    loso: dict[str, Any] = field(default_factory=dict)
    friction: dict[str, Any] = field(default_factory=dict)

    def table(self) -> list[dict[str, Any]]:
        return [{"name": name, "unit": unit, "nominal": nom, "value": float(v), "std": float(s),
                 "at_bound": bool(b)}
                for (name, unit, nom, _, _), v, s, b in zip(self.params.layout(), self.x, self.std,
                                                              self.at_bound, strict=True)]

    def to_dict(self) -> dict[str, Any]:
        return {"parameters": self.table(), "rms_mm": self.rms_mm, "mean_mm": self.mean_mm,
                "nominal_mean_mm": self.nominal_mean_mm, "n_samples": self.n_samples,
                "evaluations": self.nfev, "groups": list(self.params.groups), "loso": self.loso,
                "friction": self.friction,
                "method": "scipy least_squares (trf), analytic Jacobian (TCM tip sensitivities), "
                          "positions only" + ("; μ by a bounded scalar search on the continued TCM"
                                              if self.friction else "")}


def _positions(ds: Dataset, rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    j, p = ds.joints(), ds.poses()[:, :3]
    return (j, p) if rows is None else (j[rows], p[rows])


def initial_registration(robot: Robot, joints: np.ndarray, measured: np.ndarray) -> Registration:
    """Kabsch fit of the nominal robot's tips to the measured positions (the starting point)."""
    pred, _ = CalibratedTCM(robot).robot_frame(joints)
    return Registration.fit(pred, measured)


class _Jacobian:
    """Residual function and Jacobian of one fit, sharing the solves at the current x."""

    def __init__(self, ps: ParameterSet, joints: np.ndarray, measured: np.ndarray,
                 registration: Registration, analytic: bool = True, step: float = 1e-4) -> None:
        self.ps, self.joints, self.measured, self.reg = ps, joints, measured, registration
        # the exact tangent (sensitivity.py) is that of the planar TCM without the clearance tilt;
        # a point-wise solve has no friction history, so friction does not enter it
        planar = all(not s.curvature_y for t in ps.robot.tubes for s in t.sections)
        self.analytic, self.step = analytic and planar and not ps.robot.clearance, step
        self.lo, self.hi = ps.bounds()
        self._key: bytes | None = None
        self.x_nominal = ps.nominal()
        self.prior_weight = PRIOR_SCALE_MM / ps.prior_sigma()    # 0 where no prior
        self._cache: tuple[np.ndarray, np.ndarray, list[Equilibrium | None], CalibratedTCM] | None = None

    def _at(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[Equilibrium | None], CalibratedTCM]:
        key = np.asarray(x, float).tobytes()
        if key != self._key or self._cache is None:
            model = self.ps.model(x, self.reg)
            pos, tan, eqs = model.solve(self.joints)
            self._key, self._cache = key, (pos, tan, eqs, model)
        return self._cache

    def _tracker(self, pos: np.ndarray, model: CalibratedTCM) -> np.ndarray:
        return pos @ model.registration.rotation.T + model.registration.translation

    def residuals(self, x: np.ndarray) -> np.ndarray:
        pos, _, _, model = self._at(x)
        r = self.measured - self._tracker(pos, model)
        r = np.where(np.isfinite(r), r, NAN_PENALTY_MM).ravel()
        return np.r_[r, self.prior_weight * (np.asarray(x, float) - self.x_nominal)]

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        pos, tan, eqs, model = self._at(x)
        rot = model.registration.rotation
        names = self.ps.names
        jac = np.zeros((pos.shape[0], 3, len(names)))
        mech = [k for k, name in enumerate(names) if not name.startswith("reg_") and name != "marker_mm"]
        for k, name in enumerate(names):
            if name.startswith("reg_t_"):
                jac[:, "xyz".index(name[-1]), k] = 1.0
            elif name.startswith("reg_rot_"):
                jac[:, :, k] = pos @ _rotvec_derivative(x, names, "xyz".index(name[-1])).T
            elif name == "marker_mm":
                jac[:, :, k] = tan @ rot.T
        # per-tube bending stiffness has no exact sensitivity (sensitivity.py): forward differences
        by_difference = [k for k in mech if names[k].startswith("bending_scale_") or not self.analytic]
        exact = [k for k in mech if k not in by_difference]
        if exact:
            dm = self._mechanics_analytic(x, eqs, model)[:, :, exact]
            jac[:, :, exact] = np.einsum("ij,tjk->tik", rot, dm)
        if by_difference:
            base = self._tracker(pos, model)
            for k in by_difference:
                h = self.step * max(1.0, abs(float(x[k])))
                if x[k] + h > self.hi[k]:
                    h = -h
                xp = np.array(x, float)
                xp[k] += h
                mp = self.ps.model(xp, self.reg)
                jac[:, :, k] = (self._tracker(mp.robot_frame(self.joints)[0], mp) - base) / h
        jac = np.where(np.isfinite(jac), jac, 0.0)
        return np.r_[-jac.reshape(-1, len(names)),      # residual = measured − predicted
                     np.diag(self.prior_weight)]

    def _mechanics_analytic(self, x: np.ndarray, eqs: list[Equilibrium | None], model: CalibratedTCM
                            ) -> np.ndarray:
        """(T, 3, P) ∂(marker position, robot frame)/∂x from the exact tip sensitivities
        (sensitivity.py), chained through the parameter map of params.py: curvature scale s
        (κ = s κ_nominal: ∂/∂s = ∂/∂c / s), stiffness ratio (= ρ), α offsets (deg → rad), β offsets
        (through the mechanical stops, Robot.project_joints) and transmission lengths (= e)."""
        names = self.ps.names
        n = self.ps.robot.n_tubes
        v = dict(zip(names, np.asarray(x, float), strict=True))
        basis = np.zeros((5 * n, len(names)))     # d(basis)/d(parameter) for one sample
        for k, name in enumerate(names):
            tube = int(name.rsplit("_", 1)[1]) - 1 if name[-1].isdigit() else -1
            if name.startswith("curvature_scale_"):
                basis[tube, k] = 1.0 / v[name]
            elif name.startswith("stiffness_ratio_"):
                basis[n + tube, k] = 1.0
            elif name.startswith("alpha_offset_"):
                basis[2 * n + tube, k] = np.pi / 180.0
            elif name.startswith("transmission_length_"):
                basis[4 * n + tube, k] = 1.0
        beta_cols = [(k, int(name.rsplit("_", 1)[1]) - 1) for k, name in enumerate(names)
                     if name.startswith("beta_offset_")]
        q_log = np.atleast_2d(self.joints) + model.joint_offsets
        q_model = model.robot.project_joints(q_log)
        out = np.zeros((len(eqs), 3, len(names)))
        for t, eq in enumerate(eqs):
            if eq is None:
                continue
            _, jp, _, jt = tip_jacobian(eq.problem, eq.x)
            jm = jp + model.marker_mm * jt                      # p_marker = p + d t
            b = basis.copy()
            for k, i in beta_cols:   # the stops are piecewise linear in β: exact off their corners
                e = np.zeros(2 * n)
                e[n + i] = PROJECTION_STEP_MM
                dq = (model.robot.project_joints(q_log[t:t + 1] + e)[0] - q_model[t]) / PROJECTION_STEP_MM
                b[3 * n:4 * n, k] = dq[n:]
            out[t] = jm @ b
        return out


def _rotvec_derivative(x: np.ndarray, names: list[str], axis: int) -> np.ndarray:
    """∂R/∂θ_axis (3, 3) of the registration's rotation vector (central difference of the 3 × 3
    matrix, no TCM solve)."""
    from scipy.spatial.transform import Rotation

    rv = np.array([x[names.index(f"reg_rot_{a}")] for a in "xyz"], float)
    e = np.zeros(3)
    e[axis] = 1e-6
    return (Rotation.from_rotvec(rv + e).as_matrix() - Rotation.from_rotvec(rv - e).as_matrix()) / 2e-6


def _fit(ps: ParameterSet, joints: np.ndarray, measured: np.ndarray, max_nfev: int
         ) -> tuple[np.ndarray, Any]:
    reg0 = initial_registration(ps.robot, joints, measured)
    x0 = ps.nominal(reg0)
    lo, hi = ps.bounds()
    x0 = np.clip(x0, lo, hi)

    problem = _Jacobian(ps, joints, measured, reg0)
    sol = least_squares(problem.residuals, x0, jac=problem.jacobian, bounds=(lo, hi), x_scale="jac",
                        max_nfev=max_nfev, method="trf")
    return sol.x, sol


def calibrate(ds: Dataset, robot: Robot | None = None, groups: tuple[str, ...] | None = None,
              rows: np.ndarray | None = None, max_nfev: int = 60, prior: bool = True,
              friction_samples: int = MAX_SAMPLES) -> CalibrationResult:
    """Fit `groups` (params.py; default: params.default_groups, μ included when the nominal robot
    has friction) of `robot` (default: the dataset's) to the dataset's positions; rows: the samples
    to fit (default all; μ is fitted on the whole sequences holding them, up to friction_samples
    samples); prior: the Gaussian prior about the nominal values (params.py)."""
    robot = robot or ds.robot
    groups = default_groups(robot) if groups is None else tuple(groups)
    if robot.n_tubes != ds.n_tubes:
        raise CtrkinError(f"robot has {robot.n_tubes} tubes but the dataset {ds.n_tubes}")
    joints, measured = _positions(ds, rows)
    if len(joints) < 10:
        raise CtrkinError(f"calibration needs at least 10 samples, got {len(joints)}")
    ps = ParameterSet(robot, tuple(groups), prior=prior)
    pw = ps.point_wise()
    x, sol = _fit(pw, joints, measured, max_nfev)
    m, p = 3 * len(joints), x.size
    ssr = float(sol.fun[:m] @ sol.fun[:m])
    try:
        cov = np.linalg.pinv(sol.jac.T @ sol.jac) * ssr / max(m - p, 1)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        std = np.full(p, np.nan)
    model = pw.model(x)
    err = np.linalg.norm(model.predict(joints)[:, :3] - measured, axis=1)
    friction: dict[str, Any] = {}
    if FRICTION in ps.groups:
        mu, friction = fit_friction(model, ds.joints(), ds.poses(),
                                    sequences(ds.sequence_bounds(), rows,
                                              max_samples=friction_samples))
        x, std = np.r_[x, mu], np.r_[std, friction["std"]]
        model = ps.model(x, model.registration)
    lo, hi = ps.bounds()
    at_bound = ((np.abs(x - lo) < 1e-6 * np.maximum(1, np.abs(lo)))
                | (np.abs(x - hi) < 1e-6 * np.maximum(1, np.abs(hi))))
    nominal = ParameterSet(robot, ("registration",))
    xn, _ = _fit(nominal, joints, measured, max_nfev)
    err_n = np.linalg.norm(nominal.model(xn).predict(joints)[:, :3] - measured, axis=1)
    return CalibrationResult(ps, x, std, at_bound, model, float(np.sqrt(np.nanmean(err**2))),
                             float(np.nanmean(err)), float(np.nanmean(err_n)), len(joints), int(sol.nfev),
                             friction=friction)


def leave_one_sequence_out(ds: Dataset, robot: Robot | None = None, groups: tuple[str, ...] = GROUPS,
                           max_nfev: int = 60, prior: bool = True,
                           prior_scales: tuple[float, ...] = (1.0,)) -> dict[str, Any]:
    """Per sequence: fit `groups` on the other sequences, report the mean tip distance (mm) on it
    (the point-wise groups: μ, which only the continued TCM sees, is left out of the folds).

    prior_scales: candidate prior strengths (ParameterSet.prior_scale); with more than one, each
    outer fold picks its own by an inner leave-one-sequence-out on its training sequences only
    (nested cross-validation: the held-out sequence never chooses), needing >= 3 sequences.
    Returns {"per_sequence": {label: mm}, "mean_mm": sample-weighted mean, "samples": n,
    "prior_scale": {label: chosen scale}}."""
    robot = robot or ds.robot
    sid = ds.frame["sequence_id"].to_numpy()
    labels = ds.meta.get("sequence_labels") or []
    uniq = np.unique(sid)
    if len(uniq) < 2:
        raise CtrkinError("leave-one-sequence-out needs at least 2 sequences")
    if len(prior_scales) > 1 and (len(uniq) < 3 or not prior):
        raise CtrkinError("choosing the prior strength by nested leave-one-sequence-out needs the prior "
                          "and at least 3 sequences")
    joints, measured = _positions(ds)
    per, chosen, errs = {}, {}, []
    for k in uniq:
        train, test = np.nonzero(sid != k)[0], np.nonzero(sid == k)[0]
        scale = prior_scales[0]
        if len(prior_scales) > 1:
            scale = min(prior_scales, key=lambda c: _inner_loso(robot, groups, joints, measured, sid, train,
                                                                max_nfev, c))
        ps = ParameterSet(robot, tuple(groups), prior=prior, prior_scale=scale).point_wise()
        x, _ = _fit(ps, joints[train], measured[train], max_nfev)
        e = np.linalg.norm(ps.model(x).predict(joints[test])[:, :3] - measured[test], axis=1)
        name = str(labels[int(k)]) if int(k) < len(labels) else str(k)
        per[name], chosen[name] = float(np.nanmean(e)), scale
        errs.append(e)
    all_e = np.concatenate(errs)
    return {"per_sequence": per, "mean_mm": float(np.nanmean(all_e)), "samples": int(all_e.size),
            "groups": list(groups), "prior": prior, "prior_scale": chosen}


def _inner_loso(robot: Robot, groups: tuple[str, ...], joints: np.ndarray, measured: np.ndarray,
                sid: np.ndarray, rows: np.ndarray, max_nfev: int, scale: float) -> float:
    """Sample-weighted mean tip distance (mm) of a leave-one-sequence-out within `rows`."""
    ps = ParameterSet(robot, tuple(groups), prior_scale=scale).point_wise()
    errs = []
    for k in np.unique(sid[rows]):
        train, test = rows[sid[rows] != k], rows[sid[rows] == k]
        x, _ = _fit(ps, joints[train], measured[train], max_nfev)
        errs.append(np.linalg.norm(ps.model(x).predict(joints[test])[:, :3] - measured[test], axis=1))
    return float(np.nanmean(np.concatenate(errs)))
