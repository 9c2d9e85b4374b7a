"""Maxon EPOS4, or any CiA 402 drive, over CANopen: the `canopen` stack on a python-can bus.

Every joint is one drive (node). The actuator talks to each by SDO, which a 1 Mbit/s bus answers
in well under a millisecond, fast enough for the paper's point-to-point protocol (a move, then
tracker readings): enable (fault reset, Shutdown, Switch on, Enable operation), homing (mode 6,
the rig file's method and offset, then the home configuration), profile position moves (0x607A
target, 0x6081 velocity; new set-point handshake on controlword bit 4 / statusword bit 12; all
drives start before any is waited for, so the joints move together), encoders from 0x6064, and a
quick stop. Joint units from counts through the rig file's gear ratio, lead and encoder counts
(rig.py). `canopen` and `python-can` are the `hardware` extra; they are imported on connect.

With `[actuator] simulate = true` the drives are ctrkin's simulated CiA 402 nodes
(cia402_sim.py) on python-can's in-process virtual bus: a dry run of a rig file.
"""

from __future__ import annotations

import itertools
import threading
import time
from typing import Any

import numpy as np

import ctrkin.hardware.cia402 as c
from ctrkin.hardware.interfaces import Actuator, HardwareError
from ctrkin.hardware.rig import Drive, RigDescription

POLL_S = 0.002
_channels = itertools.count()


def _import_canopen() -> Any:
    try:
        import canopen
    except ImportError:
        raise HardwareError("CANopen drives need the canopen and python-can packages: pip install "
                            "'ctrkin[hardware]'") from None
    return canopen


class CANopenActuator(Actuator):
    """rig: the rig description (its [actuator] table and drives). simulation: simulated drives
    to start on the bus first (a dry run; cia402_sim.SimulatedBus), or None for real hardware."""

    def __init__(self, rig: RigDescription, simulation: Any = None) -> None:
        self.rig, self.spec = rig, rig.actuator
        self.n_joints = rig.n_joints
        names = rig.robot.joint_names()
        self.drives: list[Drive] = [d for name in names for d in self.spec.drives if d.joint == name]
        self.simulation = simulation
        canopen = _import_canopen()
        self.network = canopen.Network()
        if simulation is not None:
            self.network.connect(interface="virtual", channel=simulation.channel)
        else:
            self.network.connect(interface=self.spec.interface, channel=self.spec.channel,
                                 bitrate=self.spec.bitrate)
        eds = str(rig.path(self.spec.eds)) if self.spec.eds else str(c.EDS_FILE)
        self.nodes = [self.network.add_node(d.node_id, eds) for d in self.drives]
        self._stopped = False
        # one SDO transaction on the bus at a time: stop() comes from another thread while a move
        # polls its drives, and two requests to one node in flight take each other's responses
        self._sdo = threading.Lock()
        self.enable()

    # --- SDO helpers ----------------------------------------------------------------------------
    def _write(self, k: int, index: int, value: int, sub: int = 0) -> None:
        node = self.nodes[k]
        try:
            var = node.sdo[index] if not sub else node.sdo[index][sub]
            with self._sdo:
                var.raw = int(value)
        except Exception as e:       # canopen raises SdoAbortedError, SdoCommunicationError, ...
            raise HardwareError(f"drive {self.drives[k].joint} (node {self.drives[k].node_id}): writing "
                                f"0x{index:04X}:{sub} = {value} failed: {e}") from None

    def _read(self, k: int, index: int, sub: int = 0) -> int:
        node = self.nodes[k]
        try:
            var = node.sdo[index] if not sub else node.sdo[index][sub]
            with self._sdo:
                return int(var.raw)
        except Exception as e:
            raise HardwareError(f"drive {self.drives[k].joint} (node {self.drives[k].node_id}): reading "
                                f"0x{index:04X}:{sub} failed: {e}") from None

    def _wait(self, k: int, test: Any, what: str, timeout: float | None = None) -> int:
        deadline = time.monotonic() + (timeout or self.spec.timeout_s)
        while True:
            if self._stopped:
                raise HardwareError(f"drive {self.drives[k].joint}: stopped while {what}")
            word = self._read(k, c.STATUSWORD)
            if word & c.FAULT_BIT:
                self.stop()
                code = self._read(k, c.ERROR_CODE)
                raise HardwareError(f"drive {self.drives[k].joint} (node {self.drives[k].node_id}) "
                                    f"reports a fault (error code 0x{code:04X}) while {what}; motors "
                                    "stopped. Fix the cause, then run again (the fault is reset on start)")
            if test(word):
                return word
            if time.monotonic() > deadline:
                self.stop()
                raise HardwareError(f"drive {self.drives[k].joint} (node {self.drives[k].node_id}): "
                                    f"timed out after {timeout or self.spec.timeout_s:g} s while {what} "
                                    f"(statusword 0x{word:04X}, {c.state(word)}); motors stopped")
            time.sleep(POLL_S)

    def _state(self, k: int, name: str, command: int) -> None:
        self._write(k, c.CONTROLWORD, command)
        mask, value = c.STATE_MASKS[name]
        self._wait(k, lambda w: w & mask == value, f"switching to {name!r}", timeout=5.0)

    # --- the interface --------------------------------------------------------------------------
    def enable(self) -> None:
        """Fault reset, then Shutdown → Switch on → Enable operation on every drive, in profile
        position mode."""
        self._stopped = False
        for k in range(len(self.drives)):
            if c.state(self._read(k, c.STATUSWORD)) == "fault":
                self._write(k, c.CONTROLWORD, 0)
                self._write(k, c.CONTROLWORD, c.FAULT_RESET)
            self._state(k, "switch on disabled", c.DISABLE_VOLTAGE)     # from quick stop, too
            self._write(k, c.MODES_OF_OPERATION, c.PROFILE_POSITION)
            self._state(k, "ready to switch on", c.SHUTDOWN)
            self._state(k, "switched on", c.SWITCH_ON)
            self._state(k, "operation enabled", c.ENABLE_OPERATION)

    def _limits(self) -> None:
        for k, d in enumerate(self.drives):
            if np.isfinite(d.min) and np.isfinite(d.max):
                a, b = sorted((d.to_counts(d.min), d.to_counts(d.max)))
                self._write(k, c.SOFTWARE_LIMITS, a, sub=1)
                self._write(k, c.SOFTWARE_LIMITS, b, sub=2)

    def home(self) -> np.ndarray:
        if self._stopped:
            self.enable()
        for k, d in enumerate(self.drives):
            self._write(k, c.MODES_OF_OPERATION, c.HOMING)
            self._write(k, c.HOMING_METHOD, d.homing_method)
            self._write(k, c.HOME_OFFSET, d.home_offset_counts)
            self._write(k, c.CONTROLWORD, c.ENABLE_OPERATION)
            self._write(k, c.CONTROLWORD, c.ENABLE_OPERATION | c.NEW_SETPOINT)
        for k in range(len(self.drives)):
            self._wait(k, lambda w: w & c.SETPOINT_ACK and w & c.TARGET_REACHED, "homing")
            if self._read(k, c.STATUSWORD) & c.HOMING_ERROR:
                raise HardwareError(f"drive {self.drives[k].joint}: homing error; check the homing method")
            self._write(k, c.CONTROLWORD, c.ENABLE_OPERATION)
            self._write(k, c.MODES_OF_OPERATION, c.PROFILE_POSITION)
        self._limits()
        return self.move(self.rig.home, self.rig.velocity())

    def move(self, q: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        if self._stopped:
            raise HardwareError("the drives were stopped; home them again before moving")
        qa = np.asarray(q, dtype=float)
        v = np.minimum(np.abs(np.asarray(velocity, dtype=float)), self.rig.max_velocity())
        for k, d in enumerate(self.drives):
            self._write(k, c.TARGET_POSITION, d.to_counts(float(qa[k])))
            self._write(k, c.PROFILE_VELOCITY, d.drive_velocity(float(v[k])))
            self._write(k, c.CONTROLWORD, c.ENABLE_OPERATION)
            self._write(k, c.CONTROLWORD, c.ENABLE_OPERATION | c.NEW_SETPOINT | c.CHANGE_IMMEDIATELY)
        for k in range(len(self.drives)):
            self._wait(k, lambda w: w & c.SETPOINT_ACK, "taking the new set-point", timeout=5.0)
            self._write(k, c.CONTROLWORD, c.ENABLE_OPERATION)
        for k in range(len(self.drives)):
            self._wait(k, lambda w: w & c.TARGET_REACHED, f"moving to {qa[k]:g}")
        if self.spec.settle_s:
            time.sleep(self.spec.settle_s)
        return self.read()

    def read(self) -> np.ndarray:
        return np.array([d.from_counts(self._read(k, c.POSITION_ACTUAL)) for k, d in enumerate(self.drives)])

    def stop(self) -> None:
        self._stopped = True
        for k in range(len(self.drives)):
            try:
                self._write(k, c.CONTROLWORD, c.QUICK_STOP)
            except HardwareError:
                continue          # stop the others whatever one of them answers

    def close(self) -> None:
        try:
            for k in range(len(self.drives)):
                try:
                    self._write(k, c.CONTROLWORD, c.DISABLE_VOLTAGE)
                except HardwareError:
                    continue
        finally:
            self.network.disconnect()
            if self.simulation is not None:
                self.simulation.close()


class Simulation:
    """The simulated drives of a dry run, on a fresh virtual bus channel."""

    def __init__(self, rig: RigDescription) -> None:
        from ctrkin.hardware.cia402_sim import SimulatedBus, SimulatedDrive

        self.channel = f"ctrkin-sim-{next(_channels)}-{id(self):x}"
        names = rig.robot.joint_names()
        drives = []
        for name in names:
            d = rig.drive(name)
            if d is None:
                raise HardwareError(f"simulated rig: no drive for {name}")
            start = d.to_counts(float(rig.home[names.index(name)]))
            drives.append(SimulatedDrive(d.node_id, d.counts_per_turn, d.velocity_unit, start=start,
                                         speedup=rig.actuator.simulation_speedup))
        self.bus = SimulatedBus(drives, self.channel)

    def close(self) -> None:
        self.bus.close()
