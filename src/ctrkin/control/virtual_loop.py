"""The controller closed around the virtual robot (issue 24, goal 3; docs/planning.md: Control loop):
each cycle the virtual tracker measures the true robot (noise, registration, sensor offset: the
recorded measurement, ctrkin.virtual.tracker), the controller answers with joints, the virtual robot
moves there (backlash, friction, the true tubes' mechanics, a snap where its branch ends).

    res = run_virtual(Controller(fk), VirtualRobot(paper_robot(), seed=0), *circle_path(...), start)
    res.rmse_mm(settle=500), res.snaps.sum(), res.stopped_at

The virtual robot is quasi-static (it reaches each command before the next frame), so one cycle is
one motion step; the loop rate figure is the controller's own time per cycle, measured around
`cycle` (the simulation is not part of a real loop).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ctrkin.control.controller import Controller
from ctrkin.geometry import tip_pose
from ctrkin.virtual.robot import VirtualRobot


@dataclass(frozen=True, eq=False)
class LoopResult:
    """T cycles. joints (T, 2N) commands; true_tips (T, 3) mm, the true tip as the tracker would see
    it without noise; measured (T, 3) mm (NaN where the frame was dropped); targets (T, 3);
    snaps (T,) bool, the true robot crossed a fold; cycle_s (T,) the controller's time per cycle;
    stopped_at: the first cycle the controller stopped in (None: it never did)."""

    joints: np.ndarray
    true_tips: np.ndarray
    measured: np.ndarray
    targets: np.ndarray
    snaps: np.ndarray
    cycle_s: np.ndarray
    stopped_at: int | None

    def errors_mm(self) -> np.ndarray:
        """(T,) distance of the true tip from its target (mm)."""
        return np.asarray(np.linalg.norm(self.true_tips - self.targets, axis=1))

    def rmse_mm(self, settle: int) -> float:
        """RMS tracking error after the first `settle` cycles (the steady state), mm."""
        e = self.errors_mm()[settle:]
        return float(np.sqrt(np.mean(e * e)))

    def rate_hz(self) -> float:
        """Cycles per second the controller sustains: 1 / its median time per cycle."""
        return float(1.0 / np.median(self.cycle_s))


def circle_path(center: np.ndarray, radius_mm: float, period_s: float, cycles: int, rate_hz: float,
                normal: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A circle through `center` (3,) mm (it starts there, so the loop starts on its path) of radius
    radius_mm in the plane normal to `normal` (default z), once per period_s: targets (T, 3) mm and
    velocities (T, 3) mm/s at `rate_hz`."""
    n = np.array([0.0, 0.0, 1.0]) if normal is None else np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    w = 2.0 * np.pi / period_s
    t = np.arange(cycles) / rate_hz
    c, s = np.cos(w * t)[:, None], np.sin(w * t)[:, None]
    pts = np.asarray(center, float) + radius_mm * ((c - 1.0) * u + s * v)
    vel = radius_mm * w * (-s * u + c * v)
    return pts, vel


def run_virtual(controller: Controller, robot: VirtualRobot, targets: np.ndarray,
                velocities: np.ndarray | None, start: np.ndarray, seed: int = 0,
                drop_from: int | None = None) -> LoopResult:
    """Close the loop for len(targets) cycles from the robot at rest at motor joints `start` (2N,);
    tracker noise drawn from `seed`; from cycle `drop_from` on the tracker gives no frame (a dropout)."""
    rng = np.random.default_rng(seed)
    state = robot.rest(start)
    controller.reset(start)
    eq = state.equilibrium
    pose = tip_pose(eq.tip_position[None, :], eq.tip_tangent[None, :])[0]
    T, n2 = len(targets), len(start)
    joints, true_tips = np.empty((T, n2)), np.empty((T, 3))
    measured = np.full((T, 3), np.nan)
    snaps, cycle_s = np.zeros(T, bool), np.empty(T)
    stopped_at = None
    clock = time.perf_counter
    for t in range(T):
        seen = robot.tracker.registered(pose[None, :])[0]
        frame = None
        if drop_from is None or t < drop_from:
            frame = robot.tracker.measure(pose[None, :], rng)[0]
            measured[t] = frame[:3]
        t0 = clock()
        cmd = controller.cycle(frame, targets[t], None if velocities is None else velocities[t])
        cycle_s[t] = clock() - t0
        if cmd.stopped and stopped_at is None:
            stopped_at = t
        joints[t] = cmd.joints
        motion, state = robot.move(state, cmd.joints[None, :])
        snaps[t] = bool(motion.snaps[0])
        pose = motion.true_poses[0]
        true_tips[t] = seen[:3]
    return LoopResult(joints, true_tips, measured, np.asarray(targets, float), snaps, cycle_s, stopped_at)



class VirtualRig:
    """The virtual robot as a rig for control.plan_feedback: its motors (backlash, friction, the true
    tubes' mechanics) and its tracker (5 noisy readings averaged, noise drawn from `seed`), at rest
    at motor joints start (2N,). Beside what a rig gives it keeps what only a simulator knows, for
    judging: true_poses (T, 6) robot base frame, one per joint command; snaps (T,) bool, a fold of
    the true robot crossed."""

    def __init__(self, robot: VirtualRobot, start: np.ndarray, seed: int = 0) -> None:
        self.robot = robot
        self.state = robot.rest(start)
        self.rng = np.random.default_rng(seed)
        self.pose = self.state.equilibrium.tip_pose
        self._poses: list[np.ndarray] = []
        self._snaps: list[np.ndarray] = []

    def move(self, q: np.ndarray) -> None:
        motion, self.state = self.robot.move(self.state, np.atleast_2d(q))
        self.pose = motion.true_poses[-1]
        self._poses.append(motion.true_poses)
        self._snaps.append(motion.snaps)

    def measure(self) -> np.ndarray:
        return np.asarray(self.robot.tracker.measure(self.pose[None, :], self.rng)[0, :3])

    @property
    def true_poses(self) -> np.ndarray:
        return np.concatenate(self._poses) if self._poses else np.empty((0, 6))

    @property
    def snaps(self) -> np.ndarray:
        return np.concatenate(self._snaps) if self._snaps else np.empty(0, bool)

    def seen(self, poses: np.ndarray) -> np.ndarray:
        """(T, 3) mm: true poses (T, 6) as the tracker sees them without noise (the reference of the
        feedback: its frame, its sensor point, its field)."""
        return np.asarray(self.robot.tracker.registered(poses)[:, :3])
