"""A simulated CiA 402 profile-position drive: a real CANopen node (`canopen.LocalNode`, an SDO
server with ctrkin's object dictionary `data/cia402_pp.eds`) on any python-can bus, usually the
`virtual` one. The drive client (canopen_drive.py) talks to it exactly as to a Maxon EPOS4, which
is how the CANopen side is tested without hardware, and how a rig file is dry-run
(`[actuator] simulate = true`).

What it simulates (cia402.py has the state machine): the power states driven by the controlword;
profile position moves (0x607A target, 0x6081 profile velocity in rpm or counts/s) at constant
speed, target reached (statusword bit 10) when the time the move takes has passed (real time,
`speedup` times faster); homing (mode 6) on the current position (methods 35, 37) or on a
mechanical stop (any other method: the drive moves to the stop at 0x6099 speed); software
position limits (0x607D, a target outside them is a fault), quick stop, fault reset, and injected
faults (`inject_fault`). A move's position follows p(t) = p0 + sign · min(v (t − t0), |p1 − p0|).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import canopen

import ctrkin.hardware.cia402 as c

LIMIT_FAULT = 0x8612   # CiA 402 "reference limit": a target beyond the software position limits


class SimulatedDrive:
    """node_id: CANopen id; counts_per_turn: for rpm velocities; velocity_unit: "rpm" | "counts/s";
    stops: (low, high) mechanical stops in encoder counts of the motor before homing;
    start: the motor's position (counts) at power-up; speedup: simulated time runs this much faster."""

    def __init__(self, node_id: int, counts_per_turn: float = 4096.0, velocity_unit: str = "rpm",
                 stops: tuple[float, float] = (-1e9, 1e9), start: float = 0.0, speedup: float = 1.0,
                 eds: str | Path = c.EDS_FILE, clock: Callable[[], float] = time.monotonic) -> None:
        self.node = canopen.LocalNode(node_id, str(eds))
        self.counts_per_turn, self.velocity_unit = counts_per_turn, velocity_unit
        self.stops, self.speedup, self.clock = stops, speedup, clock
        self.lock = threading.RLock()   # the write callback reads the dictionary too
        self.word = c.STATE_WORDS["switch on disabled"]
        self.control = 0
        self.mode = c.PROFILE_POSITION
        self.mechanical = float(start)        # motor position (counts) when not moving
        self.encoder_zero = 0.0               # position actual = mechanical - encoder_zero
        self.motion: tuple[float, float, float, float] | None = None   # (t0, p0, p1, counts/s)
        self.ack = False
        self.homing_attained = False
        self.error_code = 0
        self.moves = 0
        self.node.add_write_callback(self._on_write)
        self.node.add_read_callback(self._on_read)

    # --- time and motion ------------------------------------------------------------------------
    def _now(self) -> float:
        return self.clock() * self.speedup

    def _mechanical_now(self) -> float:
        if self.motion is None:
            return self.mechanical
        t0, p0, p1, v = self.motion
        run = min(v * (self._now() - t0), abs(p1 - p0))
        return p0 + (run if p1 >= p0 else -run)

    def _settle(self) -> None:
        """A finished motion becomes the resting position."""
        if self.motion is not None and self._mechanical_now() == self.motion[2]:
            self.mechanical, self.motion = self.motion[2], None
            if self.mode == c.HOMING and not self.homing_attained:
                self.encoder_zero = self.mechanical - self._get(c.HOME_OFFSET)
                self.homing_attained = True

    def _start(self, target_mechanical: float, counts_per_s: float) -> None:
        p0 = self._mechanical_now()
        lo, hi = self.stops
        p1 = min(max(target_mechanical, lo), hi)
        self.motion = (self._now(), p0, p1, max(counts_per_s, 1e-9))
        self.mechanical = p0
        self.moves += 1

    def _velocity_counts(self, value: float) -> float:
        return value * self.counts_per_turn / 60.0 if self.velocity_unit == "rpm" else value

    # --- object dictionary ----------------------------------------------------------------------
    def _get(self, index: int, sub: int = 0) -> Any:
        obj: Any = self.node.object_dictionary[index]
        var = obj if isinstance(obj, canopen.objectdictionary.ODVariable) else obj[sub]
        return var.decode_raw(self.node.get_data(index, sub))

    def _on_read(self, index: int, subindex: int, od: Any) -> Any:
        with self.lock:
            self._settle()
            if index == c.STATUSWORD:
                word = self.word
                if self.motion is None and not (self.control & c.HALT):
                    word |= c.TARGET_REACHED
                if self.ack or (self.mode == c.HOMING and self.homing_attained):
                    word |= c.SETPOINT_ACK
                return word
            if index == c.POSITION_ACTUAL:
                return round(self._mechanical_now() - self.encoder_zero)
            if index == c.VELOCITY_ACTUAL:
                return 0 if self.motion is None else round(self.motion[3])
            if index == c.MODES_DISPLAY:
                return self.mode
            if index == c.ERROR_CODE:
                return self.error_code
        return None

    def _on_write(self, index: int, subindex: int, od: Any, data: bytes) -> None:
        value = od.decode_raw(data)
        with self.lock:
            self._settle()
            if index == c.MODES_OF_OPERATION:
                self.mode = int(value)
            elif index == c.CONTROLWORD:
                self._control(int(value))

    def _control(self, word: int) -> None:
        rising = word & ~self.control
        self.control = word
        st = c.state(self.word)
        if rising & c.FAULT_RESET and st == "fault":
            self.word, self.error_code = c.STATE_WORDS["switch on disabled"], 0
            return
        if st == "fault":
            return
        command = word & 0x8F
        if command & 0x02 == 0:                                    # disable voltage
            self._halt()
            self.word = c.STATE_WORDS["switch on disabled"]
        elif command & 0x06 == 0x02:                               # quick stop (bit 1 set, bit 2 clear)
            self._halt()
            active = st in ("operation enabled", "quick stop active")
            self.word = c.STATE_WORDS["quick stop active" if active else "switch on disabled"]
        elif command & 0x07 == 0x06 and st in ("switch on disabled", "switched on", "operation enabled",
                                                "ready to switch on"):
            self._halt()
            self.word = c.STATE_WORDS["ready to switch on"]
        elif command & 0x0F == 0x07 and st in ("ready to switch on", "switched on", "operation enabled"):
            self._halt()
            self.word = c.STATE_WORDS["switched on"]
        elif command & 0x0F == 0x0F and st in ("switched on", "operation enabled"):
            self.word = c.STATE_WORDS["operation enabled"]
            if rising & c.NEW_SETPOINT:
                self._setpoint()
            if not word & c.NEW_SETPOINT:
                self.ack = False

    def _halt(self) -> None:
        self.mechanical, self.motion = self._mechanical_now(), None

    def _setpoint(self) -> None:
        if self.mode == c.HOMING:
            self.homing_attained = False
            method = int(self._get(c.HOMING_METHOD))
            if method in (35, 37):                                 # on the current position
                self._halt()
                self.encoder_zero = self.mechanical - self._get(c.HOME_OFFSET)
                self.homing_attained = True
            else:                                                  # on a mechanical stop
                stop = self.stops[1] if method in (-3, 2, 18, 34) else self.stops[0]
                self._start(stop, self._velocity_counts(self._get(0x6099, 1)))
            return
        if self.mode != c.PROFILE_POSITION:
            return
        target = float(self._get(c.TARGET_POSITION))
        lo, hi = self._get(c.SOFTWARE_LIMITS, 1), self._get(c.SOFTWARE_LIMITS, 2)
        if not lo <= target <= hi:
            self._halt()
            self.word, self.error_code = c.STATE_WORDS["fault"], LIMIT_FAULT
            return
        self.ack = True
        self._start(target + self.encoder_zero, self._velocity_counts(self._get(c.PROFILE_VELOCITY)))

    def inject_fault(self, code: int = 0x7300) -> None:
        """Put the drive into the fault state with error code `code` (e.g. a sensor fault)."""
        with self.lock:
            self._halt()
            self.word, self.error_code = c.STATE_WORDS["fault"], code


class SimulatedBus:
    """Simulated drives as nodes of their own canopen.Network on a python-can bus (default the
    in-process `virtual` interface on `channel`); close() disconnects it."""

    def __init__(self, drives: list[SimulatedDrive], channel: str, interface: str = "virtual") -> None:
        self.drives = drives
        self.network = canopen.Network()
        self.network.connect(interface=interface, channel=channel)
        for d in drives:
            self.network.add_node(d.node)

    def close(self) -> None:
        self.network.disconnect()
