"""The calibration parameter vector: names, units, nominal values, bounds, and how a vector becomes a
CalibratedTCM.

Groups (`--fit`): registration (rotation vector rad, translation mm: 6), precurvature (per tube, a
scale of the nominal curvature), stiffness_ratio (per tube EI/GJ = 1 + ν, bounded by ν ∈ [0, 0.49]),
alpha_offset and beta_offset (all tubes but the outermost: a common rotation or translation of all
tubes is the registration's), transmission_length (per tube, mm), marker (tip-marker distance, mm),
friction (μ between the tubes: fitted on the continued TCM, calibration/friction.py, after the
other groups; in the default groups when the nominal robot has friction, `default_groups`).
Not fitted unless asked (`--fit ...,bending_stiffness`): bending_stiffness, per tube but the
outermost a scale of E (so of E·I and G·J together; the unloaded TCM depends on the tubes'
stiffnesses only through their ratios, so the outermost tube's E is the reference), for tubes of
one robot whose E differs (nylon tubes drawn from different stock).

Prior (`prior=True`, the default): each physical parameter has a Gaussian prior about its nominal
value with the standard deviation in PRIOR_SIGMA, chosen from what a lab knows before calibrating
(curvature of a shape-set tube ±15 %, ν ±0.2, offsets ±10° and ±5 mm, transmission ±100 mm, marker
±10 mm; `prior_scale` multiplies them all). It keeps parameters that the data hardly constrain
(the outer tube's, when only the inner tube moved) near their nominal values instead of letting
them drift to fit noise. The registration has no prior. The strength can be chosen without the
test data by nested leave-one-sequence-out (fit.leave_one_sequence_out, prior_scales).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ctrkin.calibration.model import CalibratedTCM
from ctrkin.errors import CtrkinError
from ctrkin.geometry import Registration
from ctrkin.robots.robot import Robot
from ctrkin.robots.tube import Section

PRIOR_SIGMA = {"curvature_scale": 0.15, "stiffness_ratio": 0.2, "alpha_offset": 10.0, "beta_offset": 5.0,
               "transmission_length": 100.0, "marker_mm": 10.0, "bending_scale": 0.3}
GROUPS = ("registration", "precurvature", "stiffness_ratio", "alpha_offset", "beta_offset",
          "transmission_length", "marker")
FRICTION = "friction"        # μ: not a point-wise parameter (calibration/friction.py)
OPTIONAL_GROUPS = ("bending_stiffness", FRICTION)   # fitted only when named (--fit; μ: default_groups)
ALL_GROUPS = GROUPS + OPTIONAL_GROUPS
PHYSICAL = GROUPS[1:]
BENDING_SCALE_BOUNDS = (0.3, 3.0)
MAX_FRICTION = 1.0


def default_groups(robot: Robot) -> tuple[str, ...]:
    """GROUPS, and μ when the nominal robot has friction between its tubes."""
    return (*GROUPS, FRICTION) if robot.friction > 0 else GROUPS


@dataclass(frozen=True)
class ParameterSet:
    """Which groups are fitted for `robot` (nominal), with bounds; vector layout in `names`."""

    robot: Robot
    groups: tuple[str, ...] = GROUPS
    max_precurvature_change: float = 0.5      # κ within nominal · (1 ± this)
    max_offset_deg: float = 45.0
    max_offset_mm: float = 20.0
    max_transmission_mm: float = 500.0
    max_marker_mm: float = 20.0
    prior: bool = True
    prior_scale: float = 1.0                  # multiplies every prior σ (> 1: a weaker prior)

    def __post_init__(self) -> None:
        if not self.prior_scale > 0:
            raise CtrkinError(f"prior_scale must be > 0, got {self.prior_scale}")
        bad = [g for g in self.groups if g not in ALL_GROUPS]
        if bad:
            raise CtrkinError(f"unknown calibration group(s) {bad}; choose from {list(ALL_GROUPS)}")

    def layout(self) -> list[tuple[str, str, float, float, float]]:
        """(name, unit, nominal, lower, upper) per fitted parameter."""
        n = self.robot.n_tubes
        out: list[tuple[str, str, float, float, float]] = []
        if "registration" in self.groups:
            out += [(f"reg_rot_{a}", "rad", 0.0, -np.pi, np.pi) for a in "xyz"]
            out += [(f"reg_t_{a}", "mm", 0.0, -np.inf, np.inf) for a in "xyz"]
        for i, t in enumerate(self.robot.tubes):
            if "precurvature" in self.groups and t.curvature > 0:
                c = self.max_precurvature_change
                out.append((f"curvature_scale_{i + 1}", "-", 1.0, 1.0 - c, 1.0 + c))
        for i, t in enumerate(self.robot.tubes):
            if "stiffness_ratio" in self.groups:
                out.append((f"stiffness_ratio_{i + 1}", "-", 1.0 + t.poisson_ratio, 1.0, 1.49))
        for i in range(n - 1):
            if "bending_stiffness" in self.groups:
                out.append((f"bending_scale_{i + 1}", "-", 1.0, *BENDING_SCALE_BOUNDS))
        for i in range(n - 1):
            if "alpha_offset" in self.groups:
                out.append((f"alpha_offset_{i + 1}", "deg", 0.0, -self.max_offset_deg, self.max_offset_deg))
        for i in range(n - 1):
            if "beta_offset" in self.groups:
                out.append((f"beta_offset_{i + 1}", "mm", 0.0, -self.max_offset_mm, self.max_offset_mm))
        if "transmission_length" in self.groups and self.robot.transmission == "compliant":
            tl = self.robot.transmission_length or (0.0,) * n
            out += [(f"transmission_length_{i + 1}", "mm", float(tl[i]), 0.0, self.max_transmission_mm)
                    for i in range(n)]
        if "marker" in self.groups:
            out.append(("marker_mm", "mm", 0.0, -self.max_marker_mm, self.max_marker_mm))
        if FRICTION in self.groups:
            out.append(("friction_mu", "-", self.robot.friction, 0.0, MAX_FRICTION))
        return out

    def point_wise(self) -> ParameterSet:
        """The same set without μ: the parameters a point-wise solve depends on."""
        return dataclasses.replace(self, groups=tuple(g for g in self.groups if g != FRICTION))

    @property
    def names(self) -> list[str]:
        return [r[0] for r in self.layout()]

    def nominal(self, registration: Registration | None = None) -> np.ndarray:
        x = np.array([r[2] for r in self.layout()])
        if registration is not None and "registration" in self.groups:
            x[:3] = registration.rotvec
            x[3:6] = registration.translation
        return x

    def prior_sigma(self) -> np.ndarray:
        """(P,) prior standard deviation of each parameter in its unit (inf: no prior)."""
        out = []
        for name in self.names:
            key = name if name == "marker_mm" else name.rsplit("_", 1)[0]
            out.append(PRIOR_SIGMA.get(key, np.inf) * self.prior_scale if self.prior else np.inf)
        return np.array(out)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lay = self.layout()
        return np.array([r[3] for r in lay]), np.array([r[4] for r in lay])

    def model(self, x: np.ndarray, registration: Registration | None = None) -> CalibratedTCM:
        """The predictor for parameter vector x; registration: used when it is not fitted."""
        v = dict(zip(self.names, np.asarray(x, float), strict=True))
        n = self.robot.n_tubes
        tubes = []
        for i, t in enumerate(self.robot.tubes):
            scale = v.get(f"curvature_scale_{i + 1}", 1.0)
            ratio = v.get(f"stiffness_ratio_{i + 1}", 1.0 + t.poisson_ratio)
            secs = tuple(Section(s.length, s.curvature * scale, s.curvature_y * scale) for s in t.sections)
            tubes.append(dataclasses.replace(t, curvature=t.curvature * scale, sections=secs,
                                             poisson_ratio=float(np.clip(ratio - 1.0, 0.0, 0.499)),
                                             youngs_modulus=t.youngs_modulus * v.get(f"bending_scale_{i + 1}",
                                                                                     1.0)))
        tl = tuple(v.get(f"transmission_length_{i + 1}", (self.robot.transmission_length or (0.0,) * n)[i])
                   for i in range(n))
        robot = dataclasses.replace(self.robot, tubes=tuple(tubes),
                                    transmission_length=tl if any(tl) else (),
                                    friction=float(v.get("friction_mu", self.robot.friction)))
        offsets = np.zeros(2 * n)
        for i in range(n - 1):
            offsets[i] = v.get(f"alpha_offset_{i + 1}", 0.0)
            offsets[n + i] = v.get(f"beta_offset_{i + 1}", 0.0)
        if "registration" in self.groups:
            rotvec = [v["reg_rot_x"], v["reg_rot_y"], v["reg_rot_z"]]
            reg = Registration.from_rotvec(np.array(rotvec),
                                           np.array([v["reg_t_x"], v["reg_t_y"], v["reg_t_z"]]))
        else:
            reg = registration or Registration.identity()
        return CalibratedTCM(robot, offsets, float(v.get("marker_mm", 0.0)), reg)
