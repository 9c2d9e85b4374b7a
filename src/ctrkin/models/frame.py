"""Learn tip poses in the outer tube's frame: rotation equivariance by construction.

Turning every tube by the same angle turns the whole robot about its insertion axis (no gravity in
the TCM; docs/design.md: Frames). A network that predicts tracker-frame poses from αN has to learn that
rotation from the outer angles in its data, and a by-sequence split holds some of those angles out
entirely. Here the FK target is the pose expressed in a frame that turns with the outer tube:

    p_local = Rz(−αN) · Rᵀ (p_tracker − t)           (tangent: Rz(−αN) · Rᵀ · tangent)

where (R, t) is the rigid registration robot -> tracker, fitted once on training rows against the
nominal TCM (point-wise solves; paper IV.A maps TCM and model coordinates the same way). The network
then learns a function of the relative joints, and the residual dependence on αN that a real robot
has (imperfections, registration error) from αN itself, which stays an input. Predictions are turned
back exactly, so the model's outputs are tracker-frame poses like any other FK model's.

With an outer lag (ctrkin.models.outer_lag) the outer tube points at αN − λ(β)·m_N, not at its motor's
αN. A model trained with `lagged_inputs` also sees that angle as its αN input (and α0 = α1 − it,
eq. 1): the relative rotation of the tubes, which decides where a fold lies, is then the tubes' own.
Without it the network learns the folds at the commanded α0 of its training rows, nearly all recorded
after a forward outer turn (m_N = +1), and places them λ early on a turn from rest (issue 8: the
full-scale snap magnitude, 10° → 0.6°).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ctrkin.errors import ModelError
from ctrkin.geometry import Registration, quat_from_tangent, rotate_z, tangent_from_quat
from ctrkin.models.field import PositionField
from ctrkin.models.outer_lag import lag_deg
from ctrkin.robots.robot import Robot


@dataclass(frozen=True, eq=False)
class OuterFrame:
    """registration: robot base -> tracker (p_tracker = R p_robot + t); lag: (a deg, b deg/mm) of the
    outer tube's transmission lag λ(β) = a + b·overlap(β) (ctrkin.models.outer_lag): the frame turns
    with the outer tube, at αN − λ(β)·m_N after the outer motor last turned in direction m_N."""

    registration: Registration
    lag: tuple[float, float] = (0.0, 0.0)
    lagged_inputs: bool = False
    field: PositionField | None = None     # the tracker-frame position field (ctrkin.models.field)

    @property
    def has_lag(self) -> bool:
        return self.lag != (0.0, 0.0)

    @property
    def lags_inputs(self) -> bool:
        """Whether the network's αN input is the frame's angle αN − λ(β)·m_N (module docstring)."""
        return self.lagged_inputs and self.has_lag

    def network_joints(self, joints: np.ndarray, angles: np.ndarray) -> np.ndarray:
        """(T, 2N) the joints the network sees: `joints` (T, 2N) with αN replaced by the frame's
        angles (T,) deg where the model learned so (lags_inputs), else `joints` itself."""
        if not self.lags_inputs:
            return joints
        out = np.array(joints, dtype=float)
        out[:, out.shape[1] // 2 - 1] = angles
        return out

    def outer_angle(self, robot: Robot, joints: np.ndarray, motion: np.ndarray | int) -> np.ndarray:
        """(T,) deg the angle the frame turns with: αN − λ(β)·m_N (αN itself without a lag).
        joints (T, 2N), motion (T,) or one m_N for every row."""
        J = np.atleast_2d(np.asarray(joints, float))
        a_n = J[:, robot.n_tubes - 1]
        if not self.has_lag:
            return a_n.copy()
        return a_n - lag_deg(robot, J, self.lag) * np.asarray(motion, float)

    @classmethod
    def fit(cls, robot: object, joints: np.ndarray, poses: np.ndarray, max_points: int = 400,
            seed: int = 0) -> OuterFrame:
        """Fit the registration on up to `max_points` rows: joints (M, 2N), measured poses (M, 6)."""
        from ctrkin.mechanics import solve

        if not isinstance(robot, Robot):
            raise ModelError("OuterFrame.fit needs the dataset's Robot")
        J, P = np.asarray(joints, float), np.asarray(poses, float)
        idx = np.random.default_rng(seed).choice(len(J), size=min(max_points, len(J)), replace=False)
        tips = np.array([solve(robot, q).tip_pose[:3] for q in J[idx]])
        return cls(Registration.fit(tips, P[idx, :3]))

    def to_local(self, poses: np.ndarray, alpha_outer_deg: np.ndarray) -> np.ndarray:
        """poses (T, 6) tracker frame, αN (T,) deg -> (T, 6) poses in the outer tube's frame."""
        p = np.ascontiguousarray(poses, dtype=np.float64)
        a = np.ascontiguousarray(np.broadcast_to(np.asarray(alpha_outer_deg, np.float64), (len(p),)))
        return world_poses_to_local(p, a, self.registration.rotation, self.registration.translation)

    def to_world(self, local: np.ndarray, alpha_outer_deg: np.ndarray) -> np.ndarray:
        """Inverse of to_local: (T, 6) local poses -> (T, 6) tracker-frame poses."""
        R, t = self.registration.rotation, self.registration.translation
        y = np.asarray(local, float)
        a = np.asarray(alpha_outer_deg, float)
        pos = rotate_z(y[:, :3], a) @ R.T + t
        tan = rotate_z(tangent_from_quat(y[:, 3:6]), a) @ R.T
        if self.field is not None:
            pos = pos + self.field(pos)
        return np.concatenate([pos, quat_from_tangent(tan)], axis=1)

    def to_world_one(self, y: np.ndarray, alpha_outer_deg: float) -> np.ndarray:
        """to_world of one (6,) pose in scalar arithmetic (the streaming path)."""
        out = np.empty(6)
        pose_to_world(np.asarray(y, np.float64), float(alpha_outer_deg), self.registration.rotation,
                      self.registration.translation, out)
        return out if self.field is None else self.field.apply_one(out)

    def to_dict(self) -> dict[str, object]:
        d: dict[str, object] = {"frame": "outer", **self.registration.to_dict(),
                                "outer_lag_deg": list(self.lag), "lagged_inputs": self.lagged_inputs}
        if self.field is not None:
            d["position_field"] = self.field.to_dict()
        return d

    @classmethod
    def from_dict(cls, d: dict) -> OuterFrame:
        try:
            a, b = (float(v) for v in d.get("outer_lag_deg", (0.0, 0.0)))   # older folders: no lag
            field = PositionField.from_dict(d["position_field"]) if d.get("position_field") else None
            return cls(Registration.from_dict(d), (a, b), bool(d.get("lagged_inputs", False)), field)
        except (KeyError, ValueError, TypeError) as e:
            raise ModelError(f"bad outer-frame entry: {e}") from None


@njit(cache=True)
def _tip_to_world(y: np.ndarray, alpha_outer_deg: float, R: np.ndarray, t: np.ndarray
                  ) -> tuple[float, float, float, float, float, float]:
    """One pose y (≥6,) in the outer tube's frame (quaternion need not be unit), αN deg -> tracker-frame
    position and unit tangent (6 floats)."""
    a = math.radians(alpha_outer_deg)
    c, s = math.cos(a), math.sin(a)
    w, qx, qy = y[3], y[4], y[5]
    nq = math.sqrt(w * w + qx * qx + qy * qy)
    if nq < 1e-12:
        nq = 1.0
    w, qx, qy = w / nq, qx / nq, qy / nq
    tl0, tl1, tl2 = 2 * w * qy, -2 * w * qx, 1 - 2 * (qx * qx + qy * qy)   # R(q) e3
    p0, p1, p2 = c * y[0] - s * y[1], s * y[0] + c * y[1], y[2]
    v0, v1, v2 = c * tl0 - s * tl1, s * tl0 + c * tl1, tl2
    return (R[0, 0] * p0 + R[0, 1] * p1 + R[0, 2] * p2 + t[0],
            R[1, 0] * p0 + R[1, 1] * p1 + R[1, 2] * p2 + t[1],
            R[2, 0] * p0 + R[2, 1] * p1 + R[2, 2] * p2 + t[2],
            R[0, 0] * v0 + R[0, 1] * v1 + R[0, 2] * v2,
            R[1, 0] * v0 + R[1, 1] * v1 + R[1, 2] * v2,
            R[2, 0] * v0 + R[2, 1] * v1 + R[2, 2] * v2)


@njit(cache=True)
def local_tips_to_world(y: np.ndarray, alpha_outer_deg: np.ndarray, R: np.ndarray, t: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
    """y (K, ≥6) poses in the outer tube's frame (quaternion need not be unit), αN (K,) deg ->
    positions (K, 3) and unit tangents (K, 3) in the tracker frame (R, t: the frame's registration;
    identity and αN = 0 for tracker-frame poses). Scalar loops: K is a handful of candidates."""
    k_count = y.shape[0]
    pos = np.empty((k_count, 3))
    tan = np.empty((k_count, 3))
    for k in range(k_count):
        pos[k, 0], pos[k, 1], pos[k, 2], tan[k, 0], tan[k, 1], tan[k, 2] = _tip_to_world(
            y[k], alpha_outer_deg[k], R, t)
    return pos, tan


@njit(cache=True)
def pose_to_world(y: np.ndarray, alpha_outer_deg: float, R: np.ndarray, t: np.ndarray, out: np.ndarray
                  ) -> None:
    """OuterFrame.to_world of one pose y (6,) -> out (6,): the tracker-frame position and the unit
    quaternion of the tangent (geometry.quat_from_tangent; the x axis at a tangent pointing straight back)."""
    out[0], out[1], out[2], t0, t1, t2 = _tip_to_world(y, alpha_outer_deg, R, t)
    nt = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    t0, t1, t2 = t0 / nt, t1 / nt, t2 / nt
    q0, q1, q2 = 1.0 + t2, -t1, t0
    nq = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
    if nq < 1e-12:
        out[3], out[4], out[5] = 0.0, 1.0, 0.0
    else:
        out[3], out[4], out[5] = q0 / nq, q1 / nq, q2 / nq


@njit(cache=True)
def world_poses_to_local(p: np.ndarray, alpha_outer_deg: np.ndarray, R: np.ndarray, t: np.ndarray
                         ) -> np.ndarray:
    """OuterFrame.to_local in scalar loops (the follow IK calls it every step): p (K, 6)
    tracker-frame poses, αN (K,) deg -> (K, 6) poses in the outer tube's frame (unit quaternion
    from the tangent as geometry.quat_from_tangent, the x axis at a tangent pointing straight back)."""
    k_count = p.shape[0]
    out = np.empty((k_count, 6))
    for k in range(k_count):
        a = math.radians(alpha_outer_deg[k])
        c, s = math.cos(a), math.sin(a)
        d0, d1, d2 = p[k, 0] - t[0], p[k, 1] - t[1], p[k, 2] - t[2]
        w, qx, qy = p[k, 3], p[k, 4], p[k, 5]
        nq = math.sqrt(w * w + qx * qx + qy * qy)
        w, qx, qy = w / nq, qx / nq, qy / nq
        v0, v1, v2 = 2 * w * qy, -2 * w * qx, 1 - 2 * (qx * qx + qy * qy)     # R(q) e3
        b = np.empty(6)
        for i in range(3):                                                   # Rᵀ (p − t), Rᵀ v
            b[i] = R[0, i] * d0 + R[1, i] * d1 + R[2, i] * d2
            b[3 + i] = R[0, i] * v0 + R[1, i] * v1 + R[2, i] * v2
        out[k, 0], out[k, 1], out[k, 2] = c * b[0] + s * b[1], -s * b[0] + c * b[1], b[2]   # Rz(−αN)
        l0, l1, l2 = c * b[3] + s * b[4], -s * b[3] + c * b[4], b[5]
        nt = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
        l0, l1, l2 = l0 / nt, l1 / nt, l2 / nt
        q0, q1, q2 = 1.0 + l2, -l1, l0
        nq = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
        if nq < 1e-12:
            out[k, 3], out[k, 4], out[k, 5] = 0.0, 1.0, 0.0
        else:
            out[k, 3], out[k, 4], out[k, 5] = q0 / nq, q1 / nq, q2 / nq
    return out
