"""Geometry: the tip-pose convention, quaternion and tangent conversions, and rigid transforms.

Every stage uses these (docs/design.md: Conventions, fixed); nothing else re-derives them. A tip pose is
(x, y, z, q0, qx, qy) in mm and a unit quaternion with qz = 0: the minimal rotation that turns the
base z axis onto the tip tangent, as a 5-DOF electromagnetic sensor reports it (roll about the
tangent is unobservable). Full quaternions are (w, x, y, z), scalar first. General rotation maths
(rotation vectors, composition, interpolation) is scipy.spatial.transform.Rotation's; the kernels
here are the few closed forms the pose convention needs, written once.

Numba and torch kernels that must stay scalar or on tensors (ctrkin.models.frame,
ctrkin.inference.onnx_export) restate `quat_from_tangent` and `tangent_from_quat` inline; tests
check them against the functions here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ctrkin.errors import CtrkinError

POSITION_COLUMNS = ("x", "y", "z")
QUATERNION_COLUMNS = ("q0", "qx", "qy")
POSE_COLUMNS = POSITION_COLUMNS + QUATERNION_COLUMNS   # the pose (and dataset column) names, once
POSE_UNITS = ("mm", "mm", "mm", "", "", "")


# --- the 5-DOF pose convention ----------------------------------------------------------------------
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


def pose_rotation(q: np.ndarray) -> Rotation:
    """q: (3,) or (K, 3) 5-DOF quaternions (q0, qx, qy) -> scipy Rotation(s) (qz = 0; normalised by
    scipy), for the general rotation maths (composition, angle-axis interpolation)."""
    q = np.asarray(q, dtype=float)
    zero = np.zeros(q.shape[:-1])
    return Rotation.from_quat(np.stack([q[..., 1], q[..., 2], zero, q[..., 0]], axis=-1))  # (x, y, z, w)


# --- full quaternions (w, x, y, z) ------------------------------------------------------------------
def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """q: (..., 4) quaternions (w, x, y, z), normalised here -> (..., 3, 3) rotation matrices."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def tangent_from_quaternion(q: np.ndarray) -> np.ndarray:
    """q: (..., 4) quaternions (w, x, y, z), normalised here -> (..., 3) tip tangents R e3 (the third
    column of quaternion_to_matrix; the roll about the tangent is dropped)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=-1)


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """R: (K, 3, 3) rotations -> (K, 4) unit quaternions (w, x, y, z) with w >= 0 (scipy's rotation
    maths; its (x, y, z, w) order and sign turned into ours)."""
    xyzw = Rotation.from_matrix(R).as_quat()
    q = np.column_stack([xyzw[:, 3], xyzw[:, :3]])
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def rotate_z(v: np.ndarray, deg: np.ndarray) -> np.ndarray:
    """Rotate vectors v (T, 3) about z by deg (T,) degrees."""
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]], axis=1)


# --- errors between poses ---------------------------------------------------------------------------
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


# --- rigid transforms -------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class RigidTransform:
    """p' = R p + t: rotation (3, 3), translation (3,) mm; rms_mm: the fit residual where fitted.

    The one rigid-transform type: the registration robot base -> tracker (Registration, fitted by
    Kabsch), the virtual tracker's residual registration error (ctrkin.virtual.tracker) and the
    outer-tube frame of learned models (ctrkin.models.frame)."""

    rotation: np.ndarray
    translation: np.ndarray
    rms_mm: float = float("nan")

    @classmethod
    def identity(cls) -> RigidTransform:
        return cls(np.eye(3), np.zeros(3), 0.0)

    @classmethod
    def from_rotvec(cls, rotvec: np.ndarray, translation: np.ndarray) -> RigidTransform:
        """rotvec: (3,) rotation vector (rad, axis × angle); translation (3,) mm."""
        rotation = Rotation.from_rotvec(np.asarray(rotvec, float)).as_matrix()
        return cls(rotation, np.asarray(translation, float))

    @property
    def rotvec(self) -> np.ndarray:
        """(3,) rotation vector (rad) of the rotation."""
        return Rotation.from_matrix(self.rotation).as_rotvec()

    @classmethod
    def fit(cls, robot_points: np.ndarray, tracker_points: np.ndarray) -> RigidTransform:
        """Least-squares rigid transform (Kabsch/Umeyama without scale) from (K, 3) point pairs
        (rows with a NaN dropped). The closed form by SVD of the cross-covariance, with the
        reflection fixed by det; scipy's Rotation.align_vectors gives the same rotation (tested to
        1e-12) but not the same last bits, and a fitted frame feeds training."""
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

    def apply_points(self, p: np.ndarray) -> np.ndarray:
        """(T, 3) points -> (T, 3) R p + t."""
        return np.asarray(p, float) @ self.rotation.T + self.translation

    def apply_vectors(self, v: np.ndarray) -> np.ndarray:
        """(T, 3) directions -> (T, 3) R v (no translation)."""
        return np.asarray(v, float) @ self.rotation.T

    def apply(self, poses: np.ndarray) -> np.ndarray:
        """(T, 6) poses -> transformed (T, 6) poses (tangents rotated, 5-DOF quaternion)."""
        p = np.asarray(poses, float)
        pos = self.apply_points(p[:, :3])
        tan = self.apply_vectors(tangent_from_quat(p[:, 3:6]))
        return np.concatenate([pos, quat_from_tangent(tan)], axis=1)

    def to_dict(self) -> dict[str, object]:
        return {
            "rotation": self.rotation.tolist(),
            "translation_mm": self.translation.tolist(),
            "rms_mm": self.rms_mm,
        }

    @classmethod
    def from_dict(cls, d: dict) -> RigidTransform:
        """Inverse of to_dict (KeyError, ValueError on a bad entry: callers name the file)."""
        return cls(np.array(d["rotation"], float), np.array(d["translation_mm"], float),
                   float(d.get("rms_mm", float("nan"))))


Registration = RigidTransform
"""The registration robot base -> tracker (p_tracker = R p_robot + t): a RigidTransform."""


def sensor_poses(poses: np.ndarray, transform: RigidTransform, offset_mm: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """A tracker's view of tip poses: poses (T, 6) in the robot base frame -> sensor centres (T, 3)
    mm, `offset_mm` beyond the tip along its tangent, and unit sensor axes (T, 3), both through
    `transform` (the tracker's registration)."""
    tan = tangent_from_quat(poses[:, 3:6])
    p = transform.apply_points(poses[:, :3] + offset_mm * tan)
    return p, transform.apply_vectors(tan)


def sensor_view(poses: np.ndarray, transform: RigidTransform, offset_mm: float) -> np.ndarray:
    """The noise-free tracker view of tip poses (T, 6): sensor_poses as (T, 6) 5-DOF poses."""
    p, axis = sensor_poses(poses, transform, offset_mm)
    return np.concatenate([p, quat_from_tangent(axis)], axis=1)
