"""Effect magnitudes of the virtual robot (frozen, validated, stored in every dataset's meta).

Every default is a value for a hand-made two-tube nitinol robot measured with an NDI Aurora 5-DOF
sensor, at the top of its published range where a source gives one (`CENTRAL` holds the central values
the defaults were before; docs/virtual_robot.md gives the source of each, and why the top). All
randomness is drawn from a seed, so a config plus a robot seed is one reproducible "piece of hardware".
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from ctrkin.errors import CtrkinError
from ctrkin.mechanics.settings import DEFAULT_SETTINGS

SHAPES = ("em_distortion_length_mm", "presliding_mm")   # fields that shape an effect but switch nothing


# the central published values of the effects whose default is the top of their range (the defaults
# before issue 20 moved them): `--set KEY=VALUE` of each gives the typical robot back
CENTRAL: dict[str, Any] = {
    "precurvature_error": 0.08,
    "stiffness_error": 0.08,
    "tube_friction": 0.2,
    "gear_backlash_deg": 1.0,
    "leadscrew_backlash_mm": 0.05,
    "registration_deg": 1.0,
    "em_distortion_mm": 1.0,
    "sensor_offset_mm": 4.0,
    "noise_mm": 0.25,
}


class VirtualConfigError(CtrkinError, ValueError):
    """A virtual robot effect magnitude is out of range, or not a setting at all."""


# the help of a command's `--set KEY=VALUE` (a VirtualConfig field of its configuration, ctrkin.cli)
SETTINGS_HELP = ("Override a virtual robot effect magnitude (repeatable; the keys are VirtualConfig's "
                 "fields, docs/virtual_robot.md), e.g. --set noise_mm=0.1.")


@dataclass(frozen=True)
class VirtualConfig:
    """Magnitudes of the imperfections (all ≥ 0; zero switches an effect off).

    Frozen and validated on construction (`VirtualConfigError` says which value and why); stored in
    the meta of every dataset the virtual robot records. The defaults are the top of each effect's
    published range (the largest honest error of a nominal model, issue 20); `CENTRAL` holds the
    central values. The tube effects are drawn once per robot seed and tube; the transmission's
    dead band between motor and tube base is what makes the robot's response depend on the
    direction of motion (hysteresis). docs/virtual_robot.md gives
    the source of each default.

    Attributes
    ----------
    precurvature_error : float
        Relative std of each tube's precurvature (shape-setting springback).
    stiffness_error : float
        Relative std of each tube's E·I (diameter tolerance, E of nitinol).
    residual_curvature : float
        Std (1/mm) of the curvature of the nominally straight parts.
    alpha_zero_error_deg : float
        Std (deg) of the offset between a rotation encoder's zero and the tube's precurvature plane
        (a tube clamped into its gear by hand).
    precurvature_variation : float
        Relative std of the precurvature's variation along each curved section (a smooth profile of
        zero mean, on top of precurvature_error).
    precurvature_plane_deg : float
        Std (deg) of the turn of the precurvature plane along each curved section (the shape-set
        curve leaves its plane: û = (κx, κy)).
    tube_friction : float
        Coulomb coefficient μ between neighbouring tubes of the true robot (contact forces from the
        bending moments they exchange, concentrated at curvature changes and tube ends;
        docs/mechanics.md: Friction and clearance).
    presliding_mm : float
        Elastic (presliding) slip at a contact between tubes before it slides (mm, > 0): the half
        width of its friction elements (SolverSettings.stick_mm; docs/mechanics.md: Friction and
        clearance). Metal contacts stick over 0.1–10 µm; 2e-3 mm and more keep the true robot's
        solves well conditioned on three tubes at μ ≈ 0.7 (docs/virtual_robot.md).
    clearance : float
        The share of the tubes' radial gap (from their diameters) the inner tube may tilt in where it
        leaves an outer tube's tip (1: all of it).
    gear_backlash_deg : float
        Full width (deg) of the gear backlash of each rotation stage.
    friction_deg : float
        Full width (deg) of the torsional-friction wind-up of a tube in its bearings.
    friction_deg_per_mm : float
        Extra wind-up width (deg) per mm of curved overlap of two or more tubes, a lumped stand-in
        for the friction between the tubes (default 0: tube_friction models it).
    leadscrew_backlash_mm : float
        Full width (mm) of the lead-screw backlash of each translation stage.
    registration_mm : float
        Std (mm, per axis) of the tracker's residual rigid registration error.
    registration_deg : float
        Std (deg) of its rotation.
    em_distortion_mm : float
        RMS (mm) over the robot's workspace of the part of a smooth warp of the tracker's space
        (field distortion by metal and motors) that no rigid registration removes.
    em_distortion_length_mm : float
        The warp's length scale (mm).
    sensor_offset_mm : float
        Distance (mm) of the sensor coil's centre beyond the tube tip, along the tip tangent (the
        sensor sits in a fixture on the tip; the nominal model predicts the tube tip).
    noise_mm : float
        Std (mm, per axis) of one reading's position noise.
    noise_deg : float
        Std (deg) of one reading's tangent noise.
    readings_per_sample : int
        Tracker readings averaged into one sample (the paper averaged five).
    glitch_rate : float
        Probability that a recorded sample carries a corrupted joint reading.
    glitch_deg : float
        Largest corruption (deg) of a rotation reading.
    glitch_mm : float
        Largest corruption (mm) of a translation reading.
    """

    precurvature_error: float = 0.20
    stiffness_error: float = 0.20
    residual_curvature: float = 1e-3
    alpha_zero_error_deg: float = 4.0
    precurvature_variation: float = 0.05
    precurvature_plane_deg: float = 3.0
    tube_friction: float = 0.69
    presliding_mm: float = DEFAULT_SETTINGS.stick_mm   # 2e-3 mm: the mechanics' own default
    clearance: float = 1.0
    gear_backlash_deg: float = 2.0
    friction_deg: float = 0.5
    friction_deg_per_mm: float = 0.0
    leadscrew_backlash_mm: float = 0.1
    registration_mm: float = 1.0
    registration_deg: float = 5.0
    em_distortion_mm: float = 1.64
    em_distortion_length_mm: float = 10.0
    sensor_offset_mm: float = 6.5
    noise_mm: float = 0.40
    noise_deg: float = 0.2
    readings_per_sample: int = 5
    glitch_rate: float = 2e-4
    glitch_deg: float = 90.0
    glitch_mm: float = 5.0

    def __post_init__(self) -> None:
        limits = {  # name: (upper bound, why)
            "precurvature_error": (0.5, "a relative std; 0.05 is 5 %"),
            "stiffness_error": (0.5, "a relative std; 0.08 is 8 %"),
            "residual_curvature": (0.01, "1/mm; 0.01 is a 100 mm radius, no longer 'straight'"),
            "alpha_zero_error_deg": (45.0, "deg"),
            "precurvature_variation": (0.5, "a relative std; 0.05 is 5 %"),
            "precurvature_plane_deg": (45.0, "deg"),
            "tube_friction": (1.0, "a friction coefficient; nitinol pairs are 0.1-0.7"),
            "presliding_mm": (0.05, "mm; metal contacts stick over 0.1-10 µm"),
            "clearance": (10.0, "a multiple of the tubes' radial gap; 1 is the whole gap"),
            "gear_backlash_deg": (30.0, "deg"),
            "friction_deg": (30.0, "deg"),
            "friction_deg_per_mm": (5.0, "deg per mm of curved overlap"),
            "leadscrew_backlash_mm": (2.0, "mm"),
            "registration_mm": (20.0, "mm"),
            "registration_deg": (20.0, "deg"),
            "em_distortion_mm": (20.0, "mm RMS over the workspace, after a rigid fit"),
            "em_distortion_length_mm": (10000.0, "mm"),
            "sensor_offset_mm": (50.0, "mm"),
            "noise_mm": (10.0, "mm"),
            "noise_deg": (10.0, "deg"),
            "glitch_rate": (0.5, "a probability per sample; glitches must stay rare"),
            "glitch_deg": (3600.0, "deg"),
            "glitch_mm": (100.0, "mm"),
        }
        for name, (upper, unit) in limits.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise VirtualConfigError(f"VirtualConfig.{name} must be a finite number, got {v!r}")
            if v < 0:
                raise VirtualConfigError(
                    f"VirtualConfig.{name} must be >= 0 (0 switches the effect off), got {v}")
            if v > upper:
                raise VirtualConfigError(
                    f"VirtualConfig.{name} = {v} is implausibly large ({unit}); use a value <= {upper}")
        if self.em_distortion_mm > 0 and not self.em_distortion_length_mm >= 1.0:
            raise VirtualConfigError(
                "VirtualConfig.em_distortion_length_mm must be >= 1 mm when em_distortion_mm > 0 "
                f"(the warp's length scale), got {self.em_distortion_length_mm}")
        if not self.presliding_mm > 0:
            raise VirtualConfigError(
                "VirtualConfig.presliding_mm must be > 0 mm (the contacts' elastic slip), "
                f"got {self.presliding_mm}")
        n = self.readings_per_sample
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 1000:
            raise VirtualConfigError(
                f"VirtualConfig.readings_per_sample must be an integer in 1..1000, got {n!r}")

    def to_dict(self) -> dict[str, Any]:
        """Every field by name (for the dataset meta and JSON)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> VirtualConfig:
        """The inverse of `to_dict`, validated.

        Raises
        ------
        VirtualConfigError
            On an unknown key (listing the known ones) or a value out of range.
        """
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise VirtualConfigError(f"unknown virtual robot setting(s) {sorted(unknown)}; "
                                     f"allowed: {sorted(known)}")
        return cls(**d)

    def central(self) -> VirtualConfig:
        """The effects whose default is the top of a published range at their central value instead
        (`CENTRAL`, the defaults before issue 20; the same as `--set` with each of them)."""
        return dataclasses.replace(self, **CENTRAL)

    def ideal(self) -> VirtualConfig:
        """All effects off: the virtual robot is then the nominal TCM with perfect sensing. The
        warp's length scale, a shape and no effect, keeps its value (so one field, em_distortion_mm,
        switches the warp back on)."""
        off: dict[str, Any] = {f.name: 0.0 for f in fields(self) if f.name not in SHAPES}
        off["readings_per_sample"] = 1
        return dataclasses.replace(self, **off)
