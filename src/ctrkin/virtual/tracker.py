"""Electromagnetic 5-DOF tracker: registration error, per-reading noise, averaging of readings.

The recorded pose is the tracker's, expressed in the robot base frame through a registration that is
never perfect: a fixed rigid error (R_e, t_e) remains, drawn once per robot seed. The sensor coil sits
in a fixture on the tip, its centre `offset` mm beyond the tube tip along the tip tangent. Each sample is the
mean of n readings (the paper averaged five, Sec. II.B); a reading adds isotropic position noise and
turns the tangent by a small random angle. The 5-DOF sensor measures no roll, so the orientation is
rebuilt from the averaged tangent with qz = 0 (geometry.quat_from_tangent). A distorted field
(virtual.field) warps the registered sensor pose before the noise: a static error of the tracker
that the noise-free view (`registered`) includes, as it includes the registration error.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ctrkin.geometry import RigidTransform, quat_from_tangent, sensor_poses
from ctrkin.virtual.field import FieldWarp


@dataclass(frozen=True, eq=False)
class Tracker:
    """registration: the residual registration error, measured = R_e p + t_e (rotation (3, 3),
    translation (3,) mm). offset: mm of the sensor centre beyond the tube tip along the tangent.
    noise_mm: position std per axis of one reading; noise_deg: tangent std of one reading (deg);
    readings: readings averaged per sample; warp: the field distortion (None: an undistorted field)."""

    registration: RigidTransform
    offset: float
    noise_mm: float
    noise_deg: float
    readings: int
    warp: FieldWarp | None = None

    @classmethod
    def draw(cls, rng: np.random.Generator, registration_mm: float, registration_deg: float,
             offset_mm: float, noise_mm: float, noise_deg: float, readings: int) -> Tracker:
        """A tracker whose registration error is drawn: rotation about a random axis by an angle
        ~ N(0, registration_deg²), translation ~ N(0, registration_mm²) per axis."""
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        angle = np.radians(registration_deg) * rng.standard_normal()
        error = RigidTransform.from_rotvec(axis * angle, registration_mm * rng.standard_normal(3))
        return cls(error, float(offset_mm), float(noise_mm), float(noise_deg), int(readings))

    @property
    def rotation(self) -> np.ndarray:
        return self.registration.rotation

    @property
    def translation(self) -> np.ndarray:
        return self.registration.translation

    def _sensor(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sensor centre (T, 3) and axis (T, 3) seen through the registration and the warp."""
        p, axis = sensor_poses(poses, self.registration, self.offset)
        return (p, axis) if self.warp is None else self.warp.apply(p, axis)

    def registered(self, poses: np.ndarray) -> np.ndarray:
        """Noise-free tracker view of true poses (T, 6) in the robot base frame -> (T, 6)."""
        p, axis = self._sensor(np.atleast_2d(np.asarray(poses, dtype=float)))
        return np.concatenate([p, quat_from_tangent(axis)], axis=1)

    def measure(self, poses: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Measured poses (T, 6): registered, each the mean of `readings` noisy readings."""
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        t_count, k = poses.shape[0], self.readings
        p, tan = self._sensor(poses)
        p_read = p[:, None, :] + self.noise_mm * rng.standard_normal((t_count, k, 3))
        # a small rotation of the tangent: add an isotropic perturbation and re-normalise; its
        # component orthogonal to the tangent has std noise_deg (in rad) per direction
        tan_read = tan[:, None, :] + np.radians(self.noise_deg) * rng.standard_normal((t_count, k, 3))
        tan_read /= np.linalg.norm(tan_read, axis=-1, keepdims=True)
        tan_mean = tan_read.mean(axis=1)
        return np.concatenate([p_read.mean(axis=1), quat_from_tangent(tan_mean)], axis=1)

    def to_dict(self) -> dict[str, Any]:
        rv = self.registration.rotvec
        return {"registration_rotation": self.rotation.tolist(),
                "registration_rotation_deg": float(np.degrees(np.linalg.norm(rv))),
                "registration_translation_mm": self.translation.tolist(),
                "sensor_offset_mm": self.offset,
                "noise_mm": self.noise_mm, "noise_deg": self.noise_deg, "readings": self.readings,
                "field_warp": None if self.warp is None else self.warp.to_dict()}
