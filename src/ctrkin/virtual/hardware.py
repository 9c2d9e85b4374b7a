"""The true tubes of one virtual robot: the nominal description with seeded manufacturing error, and
the contact between them.

Each tube's precurvature and bending stiffness E·I are scaled by (1 + e), e ~ N(0, σ²) (shape-setting
springback, diameter tolerance); its nominally straight part gets a small residual curvature in the
precurvature plane, κr ~ N(0, σr²) (as-drawn nitinol tubing is not perfectly straight). Only the
part in front of the plate (s ≥ 0) bends; inside the actuation unit the tube is held straight
(docs/mechanics.md: Model), so the residual curvature matters more the further a tube is extended.

Along each curved section the precurvature also varies and leaves its plane: the section is cut
into CURVED_PIECES pieces of constant precurvature û = κ (1 + ε(ξ)) (cos φ(ξ), sin φ(ξ)), with a
smooth relative profile ε(ξ) = σv (c1 √3 ξ + c2 √5 P2(ξ)) / √2 and a turn of the plane
φ(ξ) = σp c3 √3 ξ (ξ ∈ [−1, 1] along the section, c ~ N(0, 1): RMS σv and σp over the section, zero
mean, so they add to, and are not confused with, the scale error and the encoder zero offset).
The true robot has Coulomb friction μ between its tubes and the clearance of its diameters
(Robot.friction, Robot.clearance).
"""

from __future__ import annotations

import math

import numpy as np

from ctrkin.robots.robot import Robot
from ctrkin.robots.tube import Tube
from ctrkin.virtual.config import VirtualConfig

MIN_FACTOR = 0.5  # a scale factor is clipped to [0.5, 1.5]: a 10-sigma draw must stay a tube
CURVED_PIECES = 4  # pieces of constant precurvature per curved section (the arc-varying profile)


def _pieces(length: float, kappa: float, c: np.ndarray, variation: float, plane_deg: float
            ) -> list[tuple[float, float, float]]:
    """A curved section of `length` mm and curvature `kappa` cut into CURVED_PIECES pieces
    (length, κx, κy) along the smooth profile of c (3,) standard normals (module docstring)."""
    xi = (np.arange(CURVED_PIECES) + 0.5) / CURVED_PIECES * 2.0 - 1.0    # piece midpoints
    p2 = 0.5 * (3.0 * xi * xi - 1.0)                                    # Legendre P2
    eps = variation * (c[0] * math.sqrt(3.0) * xi + c[1] * math.sqrt(5.0) * p2) / math.sqrt(2.0)
    phi = np.radians(plane_deg) * c[2] * math.sqrt(3.0) * xi
    k = kappa * np.clip(1.0 + eps, MIN_FACTOR, 2 - MIN_FACTOR)
    return [(length / CURVED_PIECES, float(kv * math.cos(p)), float(kv * math.sin(p)))
            for kv, p in zip(k, phi, strict=True)]


def perturb_robot(nominal: Robot, config: VirtualConfig, rng: np.random.Generator,
                  shape_rng: np.random.Generator | None = None) -> tuple[Robot, list[dict[str, object]]]:
    """The true robot and, per tube, what was drawn (for the dataset meta).

    Stiffness error is applied through E (E·I scales with E), which keeps the tube's geometry exact.
    rng draws the scale factors and residual curvature (three draws a tube); shape_rng (default: a
    fixed stream) the arc profile (three draws a curved section), kept apart so that a seed's
    other draws do not move when the profile is switched on or off.
    Returns (true robot, [{"precurvature_factor", "stiffness_factor", "residual_curvature",
    "profile"}] per tube, innermost first).
    """
    shape_rng = shape_rng if shape_rng is not None else np.random.default_rng(0)
    tubes = []
    drawn: list[dict[str, object]] = []
    shaped = config.precurvature_variation > 0 or config.precurvature_plane_deg > 0
    for t in nominal.tubes:
        kf = float(np.clip(1 + config.precurvature_error * rng.standard_normal(),
                           MIN_FACTOR, 2 - MIN_FACTOR))
        ef = float(np.clip(1 + config.stiffness_error * rng.standard_normal(),
                           MIN_FACTOR, 2 - MIN_FACTOR))
        kr = float(config.residual_curvature * rng.standard_normal())
        sections: list[tuple[float, float, float]] = []
        profile = []
        for s in t.sections:
            if not s.curved:
                sections.append((s.length, kr, 0.0))
                continue
            c = shape_rng.standard_normal(3)
            profile.append(c.tolist())
            if shaped:
                sections += _pieces(s.length, s.curvature * kf, c, config.precurvature_variation,
                                    config.precurvature_plane_deg)
            else:
                sections.append((s.length, s.curvature * kf, s.curvature_y * kf))
        tubes.append(Tube.from_sections(t.od, t.id, sections, youngs_modulus=t.youngs_modulus * ef,
                                        poisson_ratio=t.poisson_ratio))
        drawn.append({"precurvature_factor": kf, "stiffness_factor": ef, "residual_curvature": kr,
                      "profile": profile})
    true = Robot(tubes=tuple(tubes), transmission=nominal.transmission, name=f"{nominal.name}-true",
                 friction=config.tube_friction, clearance=config.clearance)
    return true, drawn
