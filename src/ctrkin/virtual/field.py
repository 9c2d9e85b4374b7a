"""Distortion of an electromagnetic tracker's field: a smooth warp of the space it measures.

Metal and motors near the field generator bend the field, so the tracker reports a point displaced
by a smooth, static, position-dependent error (Franz et al. 2014, IEEE TMI, "Electromagnetic tracking
in medicine — a review of technology, validation, and applications"). A rigid registration removes
its mean and its rotation over the workspace, not the rest. Here the warp is a sum of M plane waves,

    d(p) = Σ_m a_m sin(k_m · (p − c) + φ_m),   |k_m| = 1 / ℓ,

with random amplitudes a_m (3,), directions k_m and phases φ_m, scaled so that the part of it no
rigid transform removes — the RMS over the robot's workspace of what is left after the best rigid
fit of the warped points to the true ones — is the configured magnitude. That is the part the
published figures measure: Hummel et al. (2005, Med. Phys. 32, "Design and application of an
assessment protocol for electromagnetic tracking systems") report the Aurora's error of a 50 mm
distance (insensitive to any rigid offset) as 0.96 ± 0.68 mm in their set-up, and up to 4.2 mm with
a steel rod 20 mm from the sensor. Only positions are warped: the same study found the sensor's
rotation error 0.51°, which the tracker's noise and registration error already cover (the warp's
own Jacobian is no model of it). With the default length scale ℓ = 10 mm (a wavelength of 63 mm,
about Hummel's 50 mm test distance) a 1 mm non-rigid part comes with 2.3–3.0 mm RMS and 3.3–4.7 mm
largest absolute displacement over the paper robot's workspace (robot seeds 0–3), within the
published absolute errors; a longer ℓ would need a larger absolute warp for the same non-rigid part.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ctrkin.geometry import RigidTransform, wave_warp

WAVES = 6


@dataclass(frozen=True, eq=False)
class FieldWarp:
    """amp (M, 3) mm, wave (M, 3) 1/mm, phase (M,) rad, centre (3,) mm (tracker frame)."""

    amp: np.ndarray
    wave: np.ndarray
    phase: np.ndarray
    centre: np.ndarray

    @classmethod
    def draw(cls, rng: np.random.Generator, rms_mm: float, length_mm: float,
             workspace: np.ndarray) -> FieldWarp:
        """A warp whose non-rigid part (`non_rigid_rms`) over the points `workspace` (K, 3) is rms_mm
        (mm), of length scale length_mm (mm)."""
        direction = rng.standard_normal((WAVES, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        warp = cls(rng.standard_normal((WAVES, 3)), direction / length_mm,
                   rng.uniform(0.0, 2.0 * np.pi, WAVES), workspace.mean(axis=0))
        for _ in range(3):   # the rigid fit makes the residual nearly, not exactly, linear in the scale
            rms = warp.non_rigid_rms(workspace)
            if rms <= 0.0:
                break
            warp = cls(warp.amp * (rms_mm / rms), warp.wave, warp.phase, warp.centre)
        return warp

    def non_rigid_rms(self, points: np.ndarray) -> float:
        """RMS (mm) over points (K, 3) of the warp left after the best rigid fit of the warped
        points to the true ones (what a rigid registration cannot remove)."""
        fit = RigidTransform.fit(points + self.displacement(points), points)
        return float(fit.rms_mm)

    def displacement(self, p: np.ndarray) -> np.ndarray:
        """d(p) (T, 3) mm at points p (T, 3) mm."""
        return wave_warp(p, self.amp, self.wave, self.phase, self.centre)

    def apply(self, p: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Warped points (T, 3) p + d(p) and the sensor axes (T, 3), unchanged (module docstring)."""
        return p + self.displacement(p), axis

    def to_dict(self) -> dict[str, Any]:
        return {"amplitude_mm": self.amp.tolist(), "wave_per_mm": self.wave.tolist(),
                "phase_rad": self.phase.tolist(), "centre_mm": self.centre.tolist()}
