"""The true tubes of one virtual robot: the nominal description with seeded manufacturing error.

Each tube's precurvature and bending stiffness E·I are scaled by (1 + e), e ~ N(0, σ²) (shape-setting
springback, diameter tolerance); its nominally straight part gets a small residual curvature in the
precurvature plane, κr ~ N(0, σr²) (as-drawn nitinol tubing is not perfectly straight). Only the
part in front of the plate (s ≥ 0) bends; inside the actuation unit the tube is held straight
(docs/mechanics.md: Model), so the residual curvature matters more the further a tube is extended.
"""

from __future__ import annotations

import numpy as np

from ctrkin.robots.robot import Robot
from ctrkin.robots.tube import Tube
from ctrkin.virtual.config import VirtualConfig

MIN_FACTOR = 0.5  # a scale factor is clipped to [0.5, 1.5]: a 10-sigma draw must stay a tube


def perturb_robot(nominal: Robot, config: VirtualConfig, rng: np.random.Generator
                  ) -> tuple[Robot, list[dict[str, float]]]:
    """The true robot and, per tube, the factors drawn (for the dataset meta).

    Stiffness error is applied through E (E·I scales with E), which keeps the tube's geometry exact.
    Returns (true robot, [{"precurvature_factor", "stiffness_factor", "residual_curvature"}] per
    tube, innermost first).
    """
    tubes = []
    drawn = []
    for t in nominal.tubes:
        kf = float(np.clip(1 + config.precurvature_error * rng.standard_normal(),
                           MIN_FACTOR, 2 - MIN_FACTOR))
        ef = float(np.clip(1 + config.stiffness_error * rng.standard_normal(),
                           MIN_FACTOR, 2 - MIN_FACTOR))
        kr = float(config.residual_curvature * rng.standard_normal())
        sections = [(s.length, s.curvature * kf if s.curvature != 0.0 else kr) for s in t.sections]
        tubes.append(Tube.from_sections(t.od, t.id, sections, youngs_modulus=t.youngs_modulus * ef,
                                        poisson_ratio=t.poisson_ratio))
        drawn.append({"precurvature_factor": kf, "stiffness_factor": ef, "residual_curvature": kr})
    true = Robot(tubes=tuple(tubes), transmission=nominal.transmission, name=f"{nominal.name}-true")
    return true, drawn
