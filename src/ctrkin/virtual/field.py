"""Distortion of an electromagnetic tracker's field: a smooth warp of the space it measures.

Metal and motors near the field generator bend the field, so the tracker reports a point displaced
by a smooth, static, position-dependent error (Franz et al. 2014, IEEE TMI, "Electromagnetic tracking
in medicine — a review of technology, validation, and applications"). A rigid registration removes
its mean and its rotation over the workspace, not the rest. Here the warp is a sum of M plane waves,

    d(p) = Σ_m a_m sin(k_m · (p − c) + φ_m),   |k_m| = 1 / ℓ,

with random amplitudes a_m (3,), directions k_m and phases φ_m, scaled so that its RMS over the
robot's workspace is the configured magnitude. A sensor's axis turns with the local deformation:
t ← normalise((I + ∂d/∂p) t).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

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
        """A warp of RMS rms_mm (mm) over the points `workspace` (K, 3) and length scale length_mm."""
        direction = rng.standard_normal((WAVES, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        amp = rng.standard_normal((WAVES, 3))
        phase = rng.uniform(0.0, 2.0 * np.pi, WAVES)
        centre = workspace.mean(axis=0)
        raw = cls(amp, direction / length_mm, phase, centre)
        rms = float(np.sqrt((raw.displacement(workspace) ** 2).sum(axis=1).mean()))
        return cls(amp * (rms_mm / rms if rms > 0 else 0.0), raw.wave, phase, centre)

    def displacement(self, p: np.ndarray) -> np.ndarray:
        """d(p) (T, 3) mm at points p (T, 3) mm."""
        arg = (p - self.centre) @ self.wave.T + self.phase     # (T, M)
        return np.sin(arg) @ self.amp

    def apply(self, p: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Warped points (T, 3) and unit axes (T, 3): p + d(p), normalise((I + ∂d/∂p) axis)."""
        arg = (p - self.centre) @ self.wave.T + self.phase
        # (∂d/∂p) t = Σ_m a_m cos(arg_m) (k_m · t)
        turned = axis + (np.cos(arg) * (axis @ self.wave.T)) @ self.amp
        return p + np.sin(arg) @ self.amp, turned / np.linalg.norm(turned, axis=1, keepdims=True)

    def to_dict(self) -> dict[str, Any]:
        return {"amplitude_mm": self.amp.tolist(), "wave_per_mm": self.wave.tolist(),
                "phase_rad": self.phase.tolist(), "centre_mm": self.centre.tolist()}
