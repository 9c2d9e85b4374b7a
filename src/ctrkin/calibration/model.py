"""The calibrated TCM as a predictor: robot (precurvature, stiffness ratio, transmission length),
joint offsets, tip-marker offset and tracker registration.

    q_model = project(q_log + offsets)                         (mechanical stops, Robot.project_joints)
    p_marker = p_tip + d · t_tip                               (marker d mm beyond the tip, along it)
    p_tracker = R p_marker + t                                 (registration)

A calibrated robot file (`ctrkin calibrate --out`) is a normal robot file: its `[calibration]` table
(offsets, marker offset, registration, uncertainties, errors) is read here and ignored elsewhere.
`predict` solves point-wise (no history: no friction load); `predict_continued` follows each
sequence by continuation, carrying the branch and, with Robot.friction > 0, the friction state;
`stream()` follows one step at a time (the same numbers as predict_continued, the state carried in
a `TCMStream`).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from ctrkin.errors import CtrkinError
from ctrkin.geometry import Registration, quat_from_tangent
from ctrkin.mechanics.continuation import follow
from ctrkin.mechanics.pointwise import Equilibrium, prepare, solve_prepared
from ctrkin.mechanics.settings import DEFAULT_SETTINGS
from ctrkin.robots.robot import Robot


@dataclass(eq=False)
class CalibratedTCM:
    """robot: the (calibrated) robot; joint_offsets (2N,) deg/mm added to logged joints; marker_mm:
    marker distance beyond the tip along the tangent; registration: robot base -> tracker."""

    robot: Robot
    joint_offsets: np.ndarray = field(default_factory=lambda: np.zeros(0))
    marker_mm: float = 0.0
    registration: Registration = field(default_factory=Registration.identity)

    def __post_init__(self) -> None:
        if self.joint_offsets.size == 0:
            self.joint_offsets = np.zeros(self.robot.n_joints)

    def model_joints(self, joints: np.ndarray) -> np.ndarray:
        """(T, 2N) logged joints -> (T, 2N) joints the TCM sees (offsets, then the mechanical stops)."""
        return self.robot.project_joints(np.atleast_2d(joints) + self.joint_offsets)

    def robot_frame(self, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Point-wise TCM (no history, cold start): marker positions (T, 3) mm and unit tangents
        (T, 3) in the robot base frame; NaN where no equilibrium converged."""
        pos, tan, _ = self.solve(joints)
        return pos, tan

    def solve(self, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[Equilibrium | None]]:
        """robot_frame and the equilibria behind it ((T,) list, None where none converged), whose
        prepared problem and shooting solution the calibration's Jacobian (sensitivity.py) reuses."""
        Q = self.model_joints(joints)
        pos = np.full((len(Q), 3), np.nan)
        tan = np.full((len(Q), 3), np.nan)
        eqs: list[Equilibrium | None] = [None] * len(Q)
        for i, q in enumerate(Q):
            eq = solve_prepared(prepare(self.robot, q, DEFAULT_SETTINGS, checked=True), None,
                                DEFAULT_SETTINGS)
            if eq.converged:
                pos[i] = eq.tip_position + self.marker_mm * eq.tip_tangent
                tan[i] = eq.tip_tangent
                eqs[i] = eq
        return pos, tan, eqs

    def predict(self, joints: np.ndarray) -> np.ndarray:
        """(T, 2N) logged joints (deg, mm) -> (T, 6) tip poses (x, y, z mm, q0, qx, qy) in the
        tracker frame."""
        return self.tracker_poses(*self.robot_frame(joints))

    def predict_continued(self, joints: np.ndarray, bounds: list[tuple[int, int]]) -> np.ndarray:
        """(T, 2N) logged joints, sequences `bounds` [(start, stop), ...] -> (T, 6) tracker-frame
        poses of the calibrated robot followed along each sequence from a point-wise solve at its
        first row (mechanics.follow: branch and friction state carried; NaN where a step did not
        converge)."""
        Q = self.model_joints(joints)
        pos = np.full((len(Q), 3), np.nan)
        tan = np.full((len(Q), 3), np.nan)
        for a, b in bounds:
            tr = follow(self.robot, Q[a:b])
            ok = tr.converged       # the tips from the trajectory's arrays: no Equilibrium is made
            tip, tangent = tr.tip_positions[ok], tr.tip_tangents[ok]
            pos[a:b][ok] = tip + self.marker_mm * tangent
            tan[a:b][ok] = tangent
        return self.tracker_poses(pos, tan)

    def tracker_poses(self, pos: np.ndarray, tan: np.ndarray) -> np.ndarray:
        """Marker positions (T, 3) and tip tangents (T, 3) in the robot base frame -> (T, 6)
        tracker-frame poses (the registration applied); NaN rows stay NaN."""
        safe = np.where(np.isfinite(tan), tan, [0.0, 0.0, 1.0])
        poses = self.registration.apply(np.column_stack([pos, quat_from_tangent(safe)]))
        poses[~np.isfinite(pos).all(axis=1)] = np.nan
        return poses

    def stream(self) -> TCMStream:
        """A streaming follower of this model, at rest (TCMStream)."""
        return TCMStream(self)

    def to_dict(self) -> dict[str, Any]:
        return {"joint_offsets": self.joint_offsets.tolist(), "marker_mm": self.marker_mm,
                "registration": {"rotation": self.registration.rotation.tolist(),
                                 "translation_mm": self.registration.translation.tolist()}}

    def to_toml(self, name: str, **calibration: Any) -> str:
        """A calibrated robot file's text (a robot file with a [calibration] table, as `ctrkin
        calibrate --out` writes: `from_file` reads it back); calibration: more entries of the table
        (provenance); None values are left out (TOML has no null)."""
        d: dict[str, Any] = {**self.robot.to_dict(), "name": name,
                             "calibration": {**self.to_dict(), **calibration}}
        return tomli_w.dumps(drop_none(d))

    @classmethod
    def from_file(cls, path: str | Path) -> CalibratedTCM:
        """A robot file, with its [calibration] table if it has one (else nominal, identity)."""
        robot = Robot.from_toml(path)
        cal = tomllib.loads(Path(path).read_text()).get("calibration", {})
        try:
            reg = cal.get("registration")
            registration = (Registration(np.array(reg["rotation"], float),
                                         np.array(reg["translation_mm"], float))
                            if reg else Registration.identity())
            offsets = np.array(cal.get("joint_offsets", np.zeros(robot.n_joints)), float)
            marker = float(cal.get("marker_mm", 0.0))
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise CtrkinError(f"{path}: [calibration] table is malformed: {e}") from None
        if offsets.shape != (robot.n_joints,):
            raise CtrkinError(f"{path}: [calibration] joint_offsets needs {robot.n_joints} values")
        return cls(robot, offsets, marker, registration)

    @property
    def has_registration(self) -> bool:
        return not (np.allclose(self.registration.rotation, np.eye(3))
                    and np.allclose(self.registration.translation, 0))


class TCMStream:
    """A CalibratedTCM followed one step at a time: its last equilibrium (branch and friction state)
    is carried from step to step, so that a run of steps gives predict_continued's poses of that run
    (equal to its rounding: a streamed step is follow() of one row from the last equilibrium).
    A step where no equilibrium converges returns the last pose and keeps the last equilibrium
    (NaN before any converged); `reset()` starts again from a point-wise solve."""

    def __init__(self, model: CalibratedTCM) -> None:
        self.model = model
        self._eq: Equilibrium | None = None
        self._pose = np.full(6, np.nan)

    def reset(self) -> None:
        self._eq, self._pose = None, np.full(6, np.nan)

    def step(self, joints: np.ndarray) -> np.ndarray:
        """Logged joints (2N,) (deg, mm) -> the (6,) tracker-frame pose after moving to them."""
        m = self.model
        q = m.model_joints(np.asarray(joints, float))
        tr = follow(m.robot, q, start=self._eq)
        if tr.converged[0]:
            self._eq = tr.equilibrium(0)
            tan = tr.tip_tangents[:1]
            self._pose = m.tracker_poses(tr.tip_positions[:1] + m.marker_mm * tan, tan)[0]
        return self._pose.copy()


def drop_none(d: Any) -> Any:
    """TOML has no null: None entries dropped (recursively)."""
    if isinstance(d, dict):
        return {k: drop_none(v) for k, v in d.items() if v is not None}
    if isinstance(d, list):
        return [drop_none(v) for v in d if v is not None]
    return d
