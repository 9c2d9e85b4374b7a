"""One pre-curved tube: geometry, material and piecewise-constant precurvature.

Units at this boundary (fixed convention): mm, 1/mm, GPa. A tube's precurvature lies in its own
material frame as û = (κ, 0, 0); the tube is described from its base (at the carriage) to its tip.
A section may also give the precurvature a component out of that plane, û = (κx, κy, 0) (a tube
whose shape-set curve is not quite planar, e.g. the virtual robot's true tubes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ctrkin.errors import RobotDescriptionError

# Physical bounds (far outside any concentric tube robot, inside what the numerics handle: stiffness
# od⁴ stays finite and non-zero, and a solve stays below SolverSettings.max_rk4_steps).
OD_RANGE_MM = (1e-3, 100.0)
MAX_LENGTH_MM = 10_000.0        # 10 m, per tube and per section
MAX_CURVATURE_PER_MM = 10.0     # a 0.1 mm bending radius
# precurvature strain |κ|·od/2 at the outer wall (|κ| = √(κx² + κy²) of a section): superelastic
# nitinol recovers about 8-10 %, so a tube set beyond 20 % cannot exist (and coils that tight make
# every solve spend its work bound)
MAX_STRAIN = 0.2
YOUNGS_RANGE_GPA = (1e-3, 1e3)
# precurvature sections per tube: a measured profile at 0.1 mm over a 1 m tube; every section is a
# stretch of the solver's grid, so this also bounds the work of one integration pass
MAX_SECTIONS = 10_000


@dataclass(frozen=True)
class Section:
    """A stretch of tube with constant precurvature.

    Attributes
    ----------
    length : float
        Length (mm).
    curvature : float
        Precurvature κx (1/mm), 0 on a straight stretch, in the tube's precurvature plane: it lies
        in the tube's material frame as û = (κx, κy, 0).
    curvature_y : float
        Precurvature κy (1/mm) out of that plane (default 0: a planar tube).
    """

    length: float
    curvature: float
    curvature_y: float = 0.0

    @property
    def curved(self) -> bool:
        return self.curvature != 0.0 or self.curvature_y != 0.0

    def as_list(self) -> list[float]:
        """[length, κx] or, out of plane, [length, κx, κy] (the robot file's form)."""
        return [self.length, self.curvature] + ([self.curvature_y] if self.curvature_y else [])


def _require_finite(owner: str, name: str, value: float) -> None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    try:
        ok = ok and math.isfinite(value)
    except OverflowError:       # an int beyond float range
        ok = False
    if not ok:
        raise RobotDescriptionError(f"{owner}.{name} must be a finite number, got {value!r}")


def _section(k: int, s: object) -> Section:
    """A Section from a Section, a (length mm, curvature 1/mm) pair or a (length, κx, κy) triple,
    else a clear error."""
    if isinstance(s, Section):
        return s
    if not isinstance(s, (tuple, list)) or len(s) not in (2, 3):
        raise RobotDescriptionError(
            f"Tube.sections[{k}] must be a pair [length mm, curvature 1/mm] or a triple [length mm, "
            f"curvature 1/mm, out-of-plane curvature 1/mm], got {s!r}")
    for name, v in zip(("length", "curvature", "curvature_y"), s, strict=False):
        _require_finite("Tube", f"sections[{k}].{name}", v)
    return Section(float(s[0]), float(s[1]), float(s[2]) if len(s) == 3 else 0.0)


def _check_count(sections: object) -> None:
    try:
        count = len(sections)  # type: ignore[arg-type]
    except TypeError:
        raise RobotDescriptionError(
            f"Tube.sections must be a list of [length mm, curvature 1/mm] pairs, got {sections!r}") from None
    if count > MAX_SECTIONS:
        raise RobotDescriptionError(f"Tube.sections has {count} sections, more than {MAX_SECTIONS} "
                                    "(merge neighbouring sections of equal curvature)")


@dataclass(frozen=True)
class Tube:
    """A nitinol tube: a straight part at the base, then a curved part (the common case).

    Validated on construction: a value outside physical bounds raises `RobotDescriptionError` with
    what to change.

    Parameters
    ----------
    od, id : float
        Outer and inner diameter (mm), 0 ≤ id < od.
    straight_length, curved_length : float
        Lengths of the straight and the curved part (mm).
    curvature : float
        Precurvature of the curved part (1/mm: 1 / radius of curvature).
    youngs_modulus : float
        E (GPa); superelastic nitinol is ~58 GPa.
    poisson_ratio : float
        ν, in [0, 0.5): sets the bending-to-torsion stiffness ratio EI/GJ = 1 + ν.
    sections : tuple of Section, optional
        General piecewise-constant precurvature from base to tip instead (see `from_sections`);
        always filled in, so the mechanics reads only `sections`.

    Examples
    --------
    >>> from ctrkin import Tube
    >>> inner = Tube(od=0.4, id=0.2, straight_length=57.0, curved_length=15.0, curvature=1 / 27)
    >>> round(inner.length, 1), len(inner.sections)
    (72.0, 2)
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
        if not OD_RANGE_MM[0] <= self.od <= OD_RANGE_MM[1]:
            raise RobotDescriptionError(
                f"Tube.od must be between {OD_RANGE_MM[0]} and {OD_RANGE_MM[1]} mm, got {self.od}")
        if not 0 <= self.id < self.od:
            raise RobotDescriptionError(
                f"Tube.id must satisfy 0 <= id < od (= {self.od} mm), got {self.id}")
        if self.straight_length < 0 or self.curved_length < 0:
            raise RobotDescriptionError(
                "Tube.straight_length and Tube.curved_length must be >= 0 mm, got "
                f"{self.straight_length} and {self.curved_length}")
        for name in ("straight_length", "curved_length"):
            if getattr(self, name) > MAX_LENGTH_MM:
                raise RobotDescriptionError(
                    f"Tube.{name} must be <= {MAX_LENGTH_MM:g} mm, got {getattr(self, name)}")
        if not 0 <= self.curvature <= MAX_CURVATURE_PER_MM:
            raise RobotDescriptionError(
                f"Tube.curvature must be between 0 and {MAX_CURVATURE_PER_MM:g} 1/mm (1/radius), "
                f"got {self.curvature}")
        if not YOUNGS_RANGE_GPA[0] <= self.youngs_modulus <= YOUNGS_RANGE_GPA[1]:
            raise RobotDescriptionError(
                f"Tube.youngs_modulus must be between {YOUNGS_RANGE_GPA[0]:g} and "
                f"{YOUNGS_RANGE_GPA[1]:g} GPa, got {self.youngs_modulus}")
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
            _check_count(self.sections)
            secs = tuple(_section(k, s) for k, s in enumerate(self.sections))
            for k, s in enumerate(secs):
                _require_finite(owner, f"sections[{k}].length", s.length)
                _require_finite(owner, f"sections[{k}].curvature", s.curvature)
                _require_finite(owner, f"sections[{k}].curvature_y", s.curvature_y)
                if not 0 <= s.length <= MAX_LENGTH_MM:
                    raise RobotDescriptionError(
                        f"Tube.sections[{k}].length must be between 0 and {MAX_LENGTH_MM:g} mm, "
                        f"got {s.length}")
                for name in ("curvature", "curvature_y"):
                    if abs(getattr(s, name)) > MAX_CURVATURE_PER_MM:
                        raise RobotDescriptionError(
                            f"Tube.sections[{k}].{name} must be within ±{MAX_CURVATURE_PER_MM:g} "
                            f"1/mm, got {getattr(s, name)}")
            object.__setattr__(self, "sections", secs)
            total = sum(s.length for s in secs)
            if abs(total - (self.straight_length + self.curved_length)) > 1e-9 * max(1.0, total):
                raise RobotDescriptionError(
                    f"Tube.sections add up to {total} mm but straight_length + curved_length = "
                    f"{self.straight_length + self.curved_length} mm; use Tube.from_sections")
        if self.length <= 0:
            raise RobotDescriptionError("Tube must have a positive total length "
                                        "(straight_length + curved_length > 0)")
        kappa = max(math.hypot(s.curvature, s.curvature_y) for s in self.sections)   # |û| = √(κx² + κy²)
        if kappa * self.od / 2 > MAX_STRAIN * (1 + 1e-9):      # at the bound itself, round-off passes
            raise RobotDescriptionError(
                f"Tube precurvature {kappa:g} 1/mm on an outer diameter of {self.od:g} mm strains its wall "
                f"by {kappa * self.od / 2:.0%}; a nitinol tube recovers about 8-10 % and none holds more "
                f"than {MAX_STRAIN:.0%} (curvature <= {2 * MAX_STRAIN / self.od:.3g} 1/mm for this "
                "diameter): check the units (1/mm) and the diameter (mm)")

    @classmethod
    def from_sections(cls, od: float, id: float,
                      sections: list[tuple[float, float]] | list[tuple[float, float, float]],
                      youngs_modulus: float = 58.0, poisson_ratio: float = 0.33) -> Tube:
        """A tube with general piecewise-constant precurvature.

        Parameters
        ----------
        od, id : float
            Outer and inner diameter (mm).
        sections : list of (float, float) or (float, float, float)
            (length mm, curvature 1/mm) pairs from base to tip, or (length, κx, κy) triples for
            precurvature out of the tube's plane.
        youngs_modulus : float
            E (GPa).
        poisson_ratio : float
            ν.

        Returns
        -------
        Tube
            With straight_length the leading straight stretch, curved_length the rest and curvature
            the first non-zero |κx|.
        """
        if not isinstance(sections, (list, tuple)):
            raise RobotDescriptionError(
                f"Tube.sections must be a list of [length mm, curvature 1/mm] pairs, got {sections!r}")
        _check_count(sections)
        secs = tuple(_section(k, s) for k, s in enumerate(sections))
        straight = 0.0
        for s in secs:
            if s.curved:
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
        """The tube as a robot TOML file's `[[tube]]` table (sections only where not the default)."""
        d: dict[str, object] = {
            "od": self.od, "id": self.id, "straight_length": self.straight_length,
            "curved_length": self.curved_length, "curvature": self.curvature,
            "youngs_modulus": self.youngs_modulus, "poisson_ratio": self.poisson_ratio,
        }
        default = Tube(self.od, self.id, self.straight_length, self.curved_length,
                       self.curvature, self.youngs_modulus, self.poisson_ratio)
        if default.sections != self.sections:
            d["sections"] = [s.as_list() for s in self.sections]
        return d
