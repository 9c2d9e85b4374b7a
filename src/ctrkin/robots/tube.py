"""One pre-curved tube: geometry, material and piecewise-constant precurvature.

Units at this boundary (fixed convention): mm, 1/mm, GPa. A tube's precurvature lies in its own
material frame as û = (κ, 0, 0); the tube is described from its base (at the carriage) to its tip.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ctrkin.errors import RobotDescriptionError


@dataclass(frozen=True)
class Section:
    """A stretch of tube with constant precurvature. length: mm, curvature: 1/mm."""

    length: float
    curvature: float


def _require_finite(owner: str, name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        raise RobotDescriptionError(f"{owner}.{name} must be a finite number, got {value!r}")


@dataclass(frozen=True)
class Tube:
    """A nitinol tube: straight part at the base, then a curved part (the common case).

    od, id: outer and inner diameter (mm); straight_length, curved_length: mm; curvature: 1/mm
    (1 / radius of curvature); youngs_modulus: GPa; poisson_ratio: dimensionless.
    `sections` may instead give general piecewise-constant precurvature from base to tip
    (see `Tube.from_sections`); it is always filled in, so the mechanics reads only `sections`.
    """

    od: float
    id: float
    straight_length: float
    curved_length: float
    curvature: float
    youngs_modulus: float = 58.0
    poisson_ratio: float = 0.33
    sections: tuple[Section, ...] = field(default=())

    def __post_init__(self) -> None:
        owner = "Tube"
        for name in ("od", "id", "straight_length", "curved_length", "curvature",
                     "youngs_modulus", "poisson_ratio"):
            _require_finite(owner, name, getattr(self, name))
        if self.od <= 0:
            raise RobotDescriptionError(f"Tube.od must be > 0 mm, got {self.od}")
        if not 0 <= self.id < self.od:
            raise RobotDescriptionError(
                f"Tube.id must satisfy 0 <= id < od (= {self.od} mm), got {self.id}")
        if self.straight_length < 0 or self.curved_length < 0:
            raise RobotDescriptionError(
                "Tube.straight_length and Tube.curved_length must be >= 0 mm, got "
                f"{self.straight_length} and {self.curved_length}")
        if self.curvature < 0:
            raise RobotDescriptionError(
                f"Tube.curvature must be >= 0 1/mm (1/radius), got {self.curvature}")
        if self.youngs_modulus <= 0:
            raise RobotDescriptionError(
                f"Tube.youngs_modulus must be > 0 GPa, got {self.youngs_modulus}")
        if not 0 <= self.poisson_ratio < 0.5:
            raise RobotDescriptionError(
                f"Tube.poisson_ratio must satisfy 0 <= nu < 0.5, got {self.poisson_ratio} (sets the "
                "bending-to-torsion stiffness ratio EI/GJ = 1 + nu; a code using G = E/4 means nu = 1, "
                "which no isotropic material has: use the material's nu, or let ctrkin calibrate fit it)")
        if not self.sections:
            secs = tuple(s for s in (Section(float(self.straight_length), 0.0),
                                     Section(float(self.curved_length), float(self.curvature)))
                         if s.length > 0)
            object.__setattr__(self, "sections", secs)
        else:
            secs = tuple(s if isinstance(s, Section) else Section(*s) for s in self.sections)
            for k, s in enumerate(secs):
                _require_finite(owner, f"sections[{k}].length", s.length)
                _require_finite(owner, f"sections[{k}].curvature", s.curvature)
                if s.length < 0:
                    raise RobotDescriptionError(
                        f"Tube.sections[{k}].length must be >= 0 mm, got {s.length}")
            object.__setattr__(self, "sections", secs)
            total = sum(s.length for s in secs)
            if abs(total - (self.straight_length + self.curved_length)) > 1e-9 * max(1.0, total):
                raise RobotDescriptionError(
                    f"Tube.sections add up to {total} mm but straight_length + curved_length = "
                    f"{self.straight_length + self.curved_length} mm; use Tube.from_sections")
        if self.length <= 0:
            raise RobotDescriptionError("Tube must have a positive total length "
                                        "(straight_length + curved_length > 0)")

    @classmethod
    def from_sections(cls, od: float, id: float, sections: list[tuple[float, float]],
                      youngs_modulus: float = 58.0, poisson_ratio: float = 0.33) -> Tube:
        """A tube with general piecewise-constant precurvature.

        sections: [(length mm, curvature 1/mm), ...] from base to tip. straight_length is set to
        the leading straight stretch, curved_length to the rest, curvature to the first non-zero one.
        """
        secs = tuple(Section(float(length), float(kappa)) for length, kappa in sections)
        straight = 0.0
        for s in secs:
            if s.curvature != 0.0:
                break
            straight += s.length
        total = sum(s.length for s in secs)
        first_curved = next((s.curvature for s in secs if s.curvature != 0.0), 0.0)
        return cls(od=od, id=id, straight_length=straight, curved_length=total - straight,
                   curvature=abs(first_curved), youngs_modulus=youngs_modulus,
                   poisson_ratio=poisson_ratio, sections=secs)

    @property
    def length(self) -> float:
        """Total length L (mm)."""
        return float(self.straight_length + self.curved_length)

    @property
    def second_moment(self) -> float:
        """I = π (od⁴ − id⁴) / 64 (mm⁴)."""
        return math.pi * (self.od**4 - self.id**4) / 64.0

    @property
    def bending_stiffness(self) -> float:
        """k = E I (N·mm²), E converted from GPa to N/mm²."""
        return self.youngs_modulus * 1e3 * self.second_moment

    @property
    def torsional_stiffness(self) -> float:
        """GJ with J = 2 I and G = E / (2 (1 + ν)) (N·mm²)."""
        return self.bending_stiffness / (1.0 + self.poisson_ratio)

    def to_dict(self) -> dict[str, object]:
        d: dict[str, object] = {
            "od": self.od, "id": self.id, "straight_length": self.straight_length,
            "curved_length": self.curved_length, "curvature": self.curvature,
            "youngs_modulus": self.youngs_modulus, "poisson_ratio": self.poisson_ratio,
        }
        default = Tube(self.od, self.id, self.straight_length, self.curved_length,
                       self.curvature, self.youngs_modulus, self.poisson_ratio)
        if default.sections != self.sections:
            d["sections"] = [[s.length, s.curvature] for s in self.sections]
        return d
