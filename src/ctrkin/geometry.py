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
    """The 5-DOF quaternion of tip tangents: the minimal rotation turning the base z axis onto them.

    Parameters
    ----------
    t : ndarray, shape (..., 3)
        Tip tangents (any length).

    Returns
    -------
    ndarray, shape (..., 3)
        Unit quaternions (q0, qx, qy), qz = 0: q ∝ (1 + e3·t, e3 × t) = (1 + tz, −ty, tx, 0). At
        t = −e3 (the tip pointing straight back) the axis is undefined; the x axis is taken.
    """
    t = np.asarray(t, dtype=float)
    t = t / np.linalg.norm(t, axis=-1, keepdims=True)
    q = np.stack([1.0 + t[..., 2], -t[..., 1], t[..., 0]], axis=-1)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    flipped = n[..., 0] < 1e-12
    q = np.where(flipped[..., None], np.array([0.0, 1.0, 0.0]), q / np.where(n < 1e-12, 1.0, n))
    return q


def tangent_from_quat(q: np.ndarray) -> np.ndarray:
    """Tip tangents of 5-DOF quaternions (the inverse of `quat_from_tangent`).

    Parameters
    ----------
    q : ndarray, shape (..., 3)
        Quaternions (q0, qx, qy) with qz = 0; normalised here.

    Returns
    -------
    ndarray, shape (..., 3)
        Unit tangents R e3.
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y = q[..., 0], q[..., 1], q[..., 2]
    # third column of the rotation matrix of (w, x, y, 0)
    return np.stack([2 * w * y, -2 * w * x, 1 - 2 * (x * x + y * y)], axis=-1)


def tip_pose(position: np.ndarray, tangent: np.ndarray) -> np.ndarray:
    """A tip pose from a position and a tangent.

    Parameters
    ----------
    position : ndarray, shape (..., 3)
        Tip positions (mm).
    tangent : ndarray, shape (..., 3)
        Tip tangents (any length).

    Returns
    -------
    ndarray, shape (..., 6)
        Poses (x, y, z, q0, qx, qy).
    """
    return np.concatenate([np.asarray(position, float), quat_from_tangent(tangent)], axis=-1)


def pose_rotation(q: np.ndarray) -> Rotation:
    """5-DOF quaternions as scipy rotations, for general rotation maths (composition, interpolation).

    Parameters
    ----------
    q : ndarray, shape (3,) or (K, 3)
        Quaternions (q0, qx, qy), qz = 0; scipy normalises them.

    Returns
    -------
    scipy.spatial.transform.Rotation
    """
    q = np.asarray(q, dtype=float)
    zero = np.zeros(q.shape[:-1])
    return Rotation.from_quat(np.stack([q[..., 1], q[..., 2], zero, q[..., 0]], axis=-1))  # (x, y, z, w)


# --- full quaternions (w, x, y, z) ------------------------------------------------------------------
def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices of full quaternions.

    Parameters
    ----------
    q : ndarray, shape (..., 4)
        Quaternions (w, x, y, z), scalar first; normalised here.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def tangent_from_quaternion(q: np.ndarray) -> np.ndarray:
    """Tip tangents of full quaternions: the third column of `quaternion_to_matrix`.

    Parameters
    ----------
    q : ndarray, shape (..., 4)
        Quaternions (w, x, y, z); normalised here.

    Returns
    -------
    ndarray, shape (..., 3)
        Unit tangents R e3 (the roll about the tangent, which a 5-DOF sensor cannot see, is dropped).
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=-1)


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternions of rotation matrices.

    Parameters
    ----------
    R : ndarray, shape (K, 3, 3)
        Rotation matrices.

    Returns
    -------
    ndarray, shape (K, 4)
        Quaternions (w, x, y, z) with w ≥ 0 (scipy's maths, in ctrkin's order and sign).
    """
    xyzw = Rotation.from_matrix(R).as_quat()
    q = np.column_stack([xyzw[:, 3], xyzw[:, :3]])
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def rotate_z(v: np.ndarray, deg: np.ndarray) -> np.ndarray:
    """Rotate vectors about the z axis.

    Parameters
    ----------
    v : ndarray, shape (T, 3)
        Vectors.
    deg : ndarray, shape (T,)
        Angles (deg), one per vector.

    Returns
    -------
    ndarray, shape (T, 3)
    """
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]], axis=1)


# --- errors between poses ---------------------------------------------------------------------------
def position_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Position error between poses.

    Parameters
    ----------
    a, b : ndarray, shape (..., ≥3)
        Poses or positions (mm); the first three entries are the position.

    Returns
    -------
    ndarray, shape (...)
        Euclidean distance (mm).
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.linalg.norm(a[..., :3] - b[..., :3], axis=-1)


def tangent_angle_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Orientation error between 5-DOF poses: the angle between their tip tangents.

    Parameters
    ----------
    a, b : ndarray, shape (..., 6)
        Poses (x, y, z, q0, qx, qy).

    Returns
    -------
    ndarray, shape (...)
        Angle (deg); q and −q, and any roll about the tangent, give zero.
    """
    ta = tangent_from_quat(np.asarray(a, float)[..., 3:6])
    tb = tangent_from_quat(np.asarray(b, float)[..., 3:6])
    cross = np.linalg.norm(np.cross(ta, tb), axis=-1)
    dot = np.sum(ta * tb, axis=-1)
    return np.degrees(np.arctan2(cross, dot))


def quaternion_angle(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """Rotation angle between full quaternions.

    Parameters
    ----------
    qa, qb : ndarray, shape (..., 4)
        Quaternions (w, x, y, z); normalised here.

    Returns
    -------
    ndarray, shape (...)
        Angle (deg); q and −q are the same rotation.
    """
    qa = np.asarray(qa, float)
    qb = np.asarray(qb, float)
    qa = qa / np.linalg.norm(qa, axis=-1, keepdims=True)
    qb = qb / np.linalg.norm(qb, axis=-1, keepdims=True)
    d = np.abs(np.sum(qa * qb, axis=-1))
    return np.degrees(2.0 * np.arccos(np.clip(d, 0.0, 1.0)))


def tip_azimuth(position: np.ndarray, outer_alpha_deg: np.ndarray | float) -> np.ndarray:
    """T(L): the azimuth of the tip about z, measured from the outer tube's base rotation.

    Parameters
    ----------
    position : ndarray, shape (T, 3) or (3,)
        Tip positions (mm).
    outer_alpha_deg : ndarray of shape (T,), or float
        The outer tube's rotation αN (deg, unwrapped).

    Returns
    -------
    ndarray, shape (T,), or float
        T(L) (deg), unwrapped along the trajectory so that it stays continuous (a snap is a step of
        more than 10°: the paper's rule).
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
    """A rigid transform p' = R p + t.

    The one rigid-transform type: the registration robot base → tracker (`Registration`, fitted by
    Kabsch), the virtual tracker's residual registration error (ctrkin.virtual.tracker) and the
    outer-tube frame of learned models (ctrkin.models.frame).

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        R.
    translation : ndarray, shape (3,)
        t (mm).
    rms_mm : float
        The residual of the fit (mm), where fitted; NaN otherwise.
    """

    rotation: np.ndarray
    translation: np.ndarray
    rms_mm: float = float("nan")

    @classmethod
    def identity(cls) -> RigidTransform:
        """The transform that moves nothing."""
        return cls(np.eye(3), np.zeros(3), 0.0)

    @classmethod
    def from_rotvec(cls, rotvec: np.ndarray, translation: np.ndarray) -> RigidTransform:
        """A transform from a rotation vector and a translation.

        Parameters
        ----------
        rotvec : ndarray, shape (3,)
            Rotation vector (rad): axis × angle.
        translation : ndarray, shape (3,)
            Translation (mm).
        """
        rotation = Rotation.from_rotvec(np.asarray(rotvec, float)).as_matrix()
        return cls(rotation, np.asarray(translation, float))

    @property
    def rotvec(self) -> np.ndarray:
        """(3,) rotation vector (rad) of the rotation."""
        return Rotation.from_matrix(self.rotation).as_rotvec()

    @classmethod
    def fit(cls, robot_points: np.ndarray, tracker_points: np.ndarray) -> RigidTransform:
        """The least-squares rigid transform between point pairs (Kabsch/Umeyama without scale).

        The closed form by SVD of the cross-covariance, the reflection fixed by det; scipy's
        Rotation.align_vectors gives the same rotation (tested to 1e-12) but not the same last
        bits, and a fitted frame feeds training.

        Parameters
        ----------
        robot_points : ndarray, shape (K, 3)
            Points in the source frame (mm); rows with a NaN (here or in `tracker_points`) are dropped.
        tracker_points : ndarray, shape (K, 3)
            The same points in the target frame (mm).

        Returns
        -------
        RigidTransform
            With `rms_mm` the residual of the fit.

        Raises
        ------
        CtrkinError
            With fewer than 3 finite pairs.
        """
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
        """Transform points: (T, 3) mm → (T, 3) mm, R p + t."""
        return np.asarray(p, float) @ self.rotation.T + self.translation

    def apply_vectors(self, v: np.ndarray) -> np.ndarray:
        """Rotate directions: (T, 3) → (T, 3), R v (no translation)."""
        return np.asarray(v, float) @ self.rotation.T

    def apply(self, poses: np.ndarray) -> np.ndarray:
        """Transform tip poses: (T, 6) → (T, 6), positions moved and tangents rotated (5-DOF)."""
        p = np.asarray(poses, float)
        pos = self.apply_points(p[:, :3])
        tan = self.apply_vectors(tangent_from_quat(p[:, 3:6]))
        return np.concatenate([pos, quat_from_tangent(tan)], axis=1)

    def to_dict(self) -> dict[str, object]:
        """For JSON: rotation (3 × 3 list), translation_mm, rms_mm."""
        return {
            "rotation": self.rotation.tolist(),
            "translation_mm": self.translation.tolist(),
            "rms_mm": self.rms_mm,
        }

    @classmethod
    def from_dict(cls, d: dict) -> RigidTransform:
        """The inverse of `to_dict` (KeyError or ValueError on a bad entry: callers name the file)."""
        return cls(np.array(d["rotation"], float), np.array(d["translation_mm"], float),
                   float(d.get("rms_mm", float("nan"))))


Registration = RigidTransform
"""The registration robot base -> tracker (p_tracker = R p_robot + t): a RigidTransform."""


def sensor_poses(poses: np.ndarray, transform: RigidTransform, offset_mm: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """A tracker's view of tip poses: where its sensor is and how it points.

    Parameters
    ----------
    poses : ndarray, shape (T, 6)
        Tip poses in the robot base frame.
    transform : RigidTransform
        The tracker's registration (robot base → tracker).
    offset_mm : float
        The sensor's centre beyond the tip along the tangent (mm).

    Returns
    -------
    centres : ndarray, shape (T, 3)
        Sensor centres in the tracker frame (mm).
    axes : ndarray, shape (T, 3)
        Unit sensor axes in the tracker frame.
    """
    tan = tangent_from_quat(poses[:, 3:6])
    p = transform.apply_points(poses[:, :3] + offset_mm * tan)
    return p, transform.apply_vectors(tan)


def sensor_view(poses: np.ndarray, transform: RigidTransform, offset_mm: float) -> np.ndarray:
    """The noise-free tracker view of tip poses: `sensor_poses` as 5-DOF poses, (T, 6) → (T, 6)."""
    p, axis = sensor_poses(poses, transform, offset_mm)
    return np.concatenate([p, quat_from_tangent(axis)], axis=1)


def wave_warp(points: np.ndarray, amplitude: np.ndarray, wave: np.ndarray, phase: np.ndarray,
              centre: np.ndarray) -> np.ndarray:
    """Displacement (T, 3) mm of a smooth warp of space made of M plane waves at points (T, 3) mm:
    d(p) = Σ_m amplitude_m sin(wave_m · (p − centre) + phase_m); amplitude (M, 3) mm, wave (M, 3)
    1/mm, phase (M,) rad, centre (3,) mm. The virtual tracker's field distortion (ctrkin.virtual.field)
    and the recorded tracker view of its datasets (ctrkin.data.tracker_view) share it."""
    arg = (np.asarray(points, dtype=float) - centre) @ np.asarray(wave).T + phase    # (T, M)
    return np.sin(arg) @ np.asarray(amplitude)
