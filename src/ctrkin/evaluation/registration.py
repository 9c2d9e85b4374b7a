"""Rigid registration between the robot base frame and the tracker frame (paper IV.A: "the
transformation matrix was used to map the coordinates between the TCM and the learning-based model").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctrkin.errors import CtrkinError
from ctrkin.pose import quat_from_tangent, tangent_from_quat


@dataclass(frozen=True, eq=False)
class Registration:
    """p_tracker = R p_robot + t. rotation (3, 3), translation (3,) mm; rms_mm: fit residual."""

    rotation: np.ndarray
    translation: np.ndarray
    rms_mm: float = float("nan")

    @classmethod
    def identity(cls) -> Registration:
        return cls(np.eye(3), np.zeros(3), 0.0)

    @classmethod
    def fit(cls, robot_points: np.ndarray, tracker_points: np.ndarray) -> Registration:
        """Least-squares rigid transform (Kabsch/Umeyama without scale) from (K, 3) point pairs."""
        a = np.asarray(robot_points, float)
        b = np.asarray(tracker_points, float)
        ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
        a, b = a[ok], b[ok]
        if len(a) < 3:
            raise CtrkinError("registration needs at least 3 finite point pairs")
        ca, cb = a.mean(axis=0), b.mean(axis=0)
        u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
        d = np.sign(np.linalg.det(vt.T @ u.T))
        rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
        t = cb - rot @ ca
        rms = float(np.sqrt(np.mean(np.sum((a @ rot.T + t - b) ** 2, axis=1))))
        return cls(rot, t, rms)

    def apply(self, poses: np.ndarray) -> np.ndarray:
        """(T, 6) poses in the robot frame -> tracker frame (tangents rotated, 5-DOF quaternion)."""
        p = np.asarray(poses, float)
        pos = p[:, :3] @ self.rotation.T + self.translation
        tan = tangent_from_quat(p[:, 3:6]) @ self.rotation.T
        return np.concatenate([pos, quat_from_tangent(tan)], axis=1)

    def to_dict(self) -> dict[str, object]:
        return {
            "rotation": self.rotation.tolist(),
            "translation_mm": self.translation.tolist(),
            "rms_mm": self.rms_mm,
        }
