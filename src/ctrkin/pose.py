"""Tip pose conventions shared by every stage (DESIGN.md: Conventions, fixed).

A tip pose is (x, y, z, q0, qx, qy) in mm and a unit quaternion with qz = 0: the minimal rotation that
turns the base z axis onto the tip tangent, as a 5-DOF electromagnetic sensor reports it (roll about
the tangent is unobservable).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctrkin.errors import CtrkinError

POSE_COLUMNS = ("x", "y", "z", "q0", "qx", "qy")


def quat_from_tangent(t: np.ndarray) -> np.ndarray:
    """t: (..., 3) tip tangents (any length) -> (..., 3) quaternions (q0, qx, qy), qz = 0.

    The minimal rotation e3 -> t is q ∝ (1 + e3·t, e3 × t) = (1 + tz, -ty, tx, 0).
    At t = -e3 (tip pointing straight back) the axis is undefined; we pick the x axis.
    """
    t = np.asarray(t, dtype=float)
    t = t / np.linalg.norm(t, axis=-1, keepdims=True)
    q = np.stack([1.0 + t[..., 2], -t[..., 1], t[..., 0]], axis=-1)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    flipped = n[..., 0] < 1e-12
    q = np.where(flipped[..., None], np.array([0.0, 1.0, 0.0]), q / np.where(n < 1e-12, 1.0, n))
    return q


def tangent_from_quat(q: np.ndarray) -> np.ndarray:
    """q: (..., 3) (q0, qx, qy) with qz = 0 (need not be exactly unit) -> (..., 3) unit tangents R e3."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y = q[..., 0], q[..., 1], q[..., 2]
    # third column of the rotation matrix of (w, x, y, 0)
    return np.stack([2 * w * y, -2 * w * x, 1 - 2 * (x * x + y * y)], axis=-1)


def tip_pose(position: np.ndarray, tangent: np.ndarray) -> np.ndarray:
    """position (..., 3) mm, tangent (..., 3) -> pose (..., 6) = (x, y, z, q0, qx, qy)."""
    return np.concatenate([np.asarray(position, float), quat_from_tangent(tangent)], axis=-1)


def position_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distance (mm) between the positions of poses (..., >=3)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.linalg.norm(a[..., :3] - b[..., :3], axis=-1)


def tangent_angle_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (deg) between the tip tangents of poses (..., 6) (the 5-DOF orientation error)."""
    ta = tangent_from_quat(np.asarray(a, float)[..., 3:6])
    tb = tangent_from_quat(np.asarray(b, float)[..., 3:6])
    cross = np.linalg.norm(np.cross(ta, tb), axis=-1)
    dot = np.sum(ta * tb, axis=-1)
    return np.degrees(np.arctan2(cross, dot))


def quaternion_angle(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """Rotation angle (deg) between unit quaternions (..., 4) (w, x, y, z); q and -q are the same."""
    qa = np.asarray(qa, float)
    qb = np.asarray(qb, float)
    qa = qa / np.linalg.norm(qa, axis=-1, keepdims=True)
    qb = qb / np.linalg.norm(qb, axis=-1, keepdims=True)
    d = np.abs(np.sum(qa * qb, axis=-1))
    return np.degrees(2.0 * np.arccos(np.clip(d, 0.0, 1.0)))


def tip_azimuth(position: np.ndarray, outer_alpha_deg: np.ndarray | float) -> np.ndarray:
    """T(L) (deg): azimuth of the tip about z measured from the outer tube's base rotation,
    unwrapped along the leading axis so that a trajectory stays continuous.

    position: (T, 3) or (3,) mm; outer_alpha_deg: (T,) or scalar (αN, deg, unwrapped).
    """
    p = np.atleast_2d(np.asarray(position, float))
    az = np.unwrap(np.arctan2(p[:, 1], p[:, 0]))
    out = np.degrees(az) - np.broadcast_to(np.asarray(outer_alpha_deg, float), az.shape)
    # express relative to the outer base angle, then unwrap again (the outer angle is unwrapped)
    out = np.degrees(np.unwrap(np.radians(out)))
    return out if np.ndim(position) > 1 else out[0]


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
