"""The virtual robot (ctrkin.virtual.VirtualRobot) behind the rig interfaces: motors that drive its
mechanics and a tracker that reads its sensor one reading at a time, with its noise.

The actuator keeps the robot's state (equilibrium branch, backlash) between moves, as the motors of
a real rig do; `begin_run` rests it at the home joints (no history), as a protocol run starts.
With drives in the rig file, commanded joints are quantised to encoder counts and the encoders
report the counts. The tracker reports the sensor coil in the tracker frame: the virtual robot's
registration, sensor offset and per-reading noise (VirtualConfig), orientation as the quaternion
that turns z onto the sensor axis. Its noise is keyed to (seed, run, move since the run started,
reading since the move): a collection resumed after an interruption, which re-drives the run to
where it stopped, draws the same noise as one that never stopped.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ctrkin.geometry import quat_from_tangent, sensor_poses
from ctrkin.hardware.interfaces import OK, Actuator, HardwareError, Tracker, TrackerFrame
from ctrkin.hardware.rig import RigDescription
from ctrkin.virtual.robot import VirtualRobot, VirtualState

NOISE_STREAM = 0x7215


@dataclass(eq=False)
class _Shared:
    """What the virtual actuator and tracker share: the robot, its state and the noise key."""

    virtual: VirtualRobot
    seed: int
    state: VirtualState | None = None
    pose: np.ndarray | None = None       # (6,) true tip pose, robot base frame
    run: int = 0
    moves: int = 0
    reads: int = 0


class VirtualActuator(Actuator):
    """inner: real (or simulated) drives whose encoder readings move the virtual robot instead of
    the commanded joints (a dry run of a rig's drives with virtual mechanics); None: ideal motors."""

    def __init__(self, rig: RigDescription, shared: _Shared, inner: Actuator | None = None) -> None:
        self.rig, self.shared, self.inner = rig, shared, inner
        self.n_joints = rig.n_joints
        self.joints = np.array(rig.home, dtype=float)
        self._stopped = False

    def _quantise(self, q: np.ndarray) -> np.ndarray:
        out = np.array(q, dtype=float)
        for k, name in enumerate(self.rig.robot.joint_names()):
            d = self.rig.drive(name)
            if d is not None:
                out[k] = d.from_counts(d.to_counts(float(out[k])))
        return out

    def begin_run(self, index: int) -> None:
        """The run starts from rest where the motors are (the home joints for ideal motors)."""
        self.shared.run = index
        self._rest(None if self.inner is None else self.inner.read())

    def _rest(self, q: np.ndarray | None = None) -> None:
        s = self.shared
        self.joints = self._quantise(self.rig.home) if q is None else np.array(q, dtype=float)
        s.state = s.virtual.rest(self.joints)
        s.pose = s.state.equilibrium.tip_pose
        s.moves, s.reads = 0, 0
        self._stopped = False

    def home(self) -> np.ndarray:
        self._rest(None if self.inner is None else self.inner.home())
        return self.joints.copy()

    def move(self, q: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        s = self.shared
        if self._stopped:
            raise HardwareError("the virtual motors were stopped; home them again before moving")
        state = s.state if s.state is not None else s.virtual.rest(self.joints)
        target = (self._quantise(np.asarray(q, dtype=float)) if self.inner is None
                  else self.inner.move(q, velocity))
        motion, s.state = s.virtual.move(state, target[None, :])
        s.pose = motion.true_poses[0]
        s.moves += 1
        s.reads = 0
        self.joints = target
        return target.copy()

    def read(self) -> np.ndarray:
        return self.joints.copy()

    def stop(self) -> None:
        self._stopped = True
        if self.inner is not None:
            self.inner.stop()

    def close(self) -> None:
        if self.inner is not None:
            self.inner.close()


class VirtualTracker(Tracker):
    """One tool: the sensor coil on the virtual robot's tip (tracker frame, mm)."""

    n_tools = 1

    def __init__(self, shared: _Shared) -> None:
        self.shared = shared
        self.started = False

    def start(self) -> None:
        self.started = True

    def read(self) -> TrackerFrame:
        s = self.shared
        if not self.started:
            raise HardwareError("the virtual tracker is not started")
        if s.pose is None:
            raise HardwareError("the virtual robot has not been homed: no pose to read")
        tr = s.virtual.tracker
        rng = np.random.default_rng(np.random.SeedSequence([s.seed, NOISE_STREAM, s.run, s.moves, s.reads]))
        s.reads += 1
        p, tan = sensor_poses(s.pose[None, :], tr.registration, tr.offset)
        p = p[0] + tr.noise_mm * rng.standard_normal(3)
        t = tan[0] + np.radians(tr.noise_deg) * rng.standard_normal(3)
        q5 = quat_from_tangent(t / np.linalg.norm(t))         # (q0, qx, qy), qz = 0
        pose = np.array([[*p, q5[0], q5[1], q5[2], 0.0]])
        return TrackerFrame(time.monotonic(), pose, (OK,), np.zeros(1))

    def stop(self) -> None:
        self.started = False


def virtual_rig(rig: RigDescription, inner: Actuator | None = None
                ) -> tuple[VirtualActuator, VirtualTracker, VirtualRobot]:
    """The virtual actuator and tracker of a rig file whose kinds are "virtual" ([virtual]: seed
    of the noise, robot_seed of the hardware draw, settings: VirtualConfig overrides)."""
    from ctrkin.virtual.config import VirtualConfig

    v = dict(rig.virtual)
    unknown = set(v) - {"seed", "robot_seed", "settings"}
    if unknown:
        raise HardwareError(f"{rig.source}: [virtual] unknown key(s) {sorted(unknown)}; allowed: seed, "
                            "robot_seed, settings")
    config = VirtualConfig.from_dict(dict(v.get("settings", {})))
    virtual = VirtualRobot(rig.robot, config, seed=int(v.get("robot_seed", 0)))
    shared = _Shared(virtual, int(v.get("seed", 0)))
    return VirtualActuator(rig, shared, inner), VirtualTracker(shared), virtual
