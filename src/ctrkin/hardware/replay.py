"""The replay device: a recorded readings log (readings_log.py) played back as an actuator and a
tracker, so that a collection, its safety rules and its averaging can be rerun without hardware on
exactly what a rig once measured (`[actuator] kind = "replay"`, `[tracker] kind = "replay"`).

The actuator walks through the log's samples: a move to the joints the next logged sample was
commanded at returns that sample's encoder readings and makes its readings the tracker's next
frames; a move the log did not record (a transition between sequences, the approach from home)
returns the commanded joints. The tracker hands out the current sample's readings in order, and
then reports every tool "missing": the log holds nothing more for that configuration.
"""

from __future__ import annotations

import time

import numpy as np

from ctrkin.hardware.interfaces import MISSING, Actuator, HardwareError, Tracker, TrackerFrame
from ctrkin.hardware.readings_log import LoggedSample, ReadingsLog
from ctrkin.hardware.rig import RigDescription

MATCH_TOL = 1e-6   # deg / mm: a move matches a logged command


class _Cursor:
    def __init__(self, samples: list[LoggedSample], n_tools: int) -> None:
        self.samples, self.n_tools = samples, n_tools
        self.next = 0
        self.current: LoggedSample | None = None
        self.reading = 0


class ReplayActuator(Actuator):
    def __init__(self, rig: RigDescription, cursor: _Cursor) -> None:
        self.rig, self.cursor = rig, cursor
        self.n_joints = rig.n_joints
        self.joints = np.array(rig.home, dtype=float)

    def home(self) -> np.ndarray:
        self.joints = np.array(self.rig.home, dtype=float)
        self.cursor.current = None
        return self.joints.copy()

    def move(self, q: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        c = self.cursor
        qa = np.asarray(q, dtype=float)
        if c.next < len(c.samples) and np.abs(c.samples[c.next].command - qa).max() <= MATCH_TOL:
            c.current, c.reading = c.samples[c.next], 0
            c.next += 1
            self.joints = c.current.encoder.copy()
        else:
            c.current = None
            self.joints = qa.copy()
        return self.joints.copy()

    def read(self) -> np.ndarray:
        return self.joints.copy()

    def stop(self) -> None:
        pass


class ReplayTracker(Tracker):
    def __init__(self, cursor: _Cursor) -> None:
        self.cursor = cursor
        self.n_tools = cursor.n_tools

    def start(self) -> None:
        pass

    def read(self) -> TrackerFrame:
        c = self.cursor
        if c.current is None or c.reading >= len(c.current.frames):
            return TrackerFrame(time.time(), np.full((self.n_tools, 7), np.nan),
                                (MISSING,) * self.n_tools, np.full(self.n_tools, np.nan))
        frame = c.current.frames[c.reading]
        c.reading += 1
        return frame

    def stop(self) -> None:
        pass


def replay_rig(rig: RigDescription) -> tuple[ReplayActuator, ReplayTracker]:
    """The replay actuator and tracker of a rig file ([actuator] log, the same file for both)."""
    name = rig.actuator.log or rig.tracker.log
    if name is None or (rig.tracker.log and rig.actuator.log and rig.tracker.log != rig.actuator.log):
        raise HardwareError(f"{rig.source}: the replay actuator and tracker play one log; give the same "
                            "log = \"readings.csv\" in [actuator] and [tracker]")
    path = rig.path(name)
    if not path.is_file():
        raise HardwareError(f"{rig.source}: replay log {path} does not exist")
    with path.open() as f:
        first = f.readline().strip().split(",")
    n_tools = sum(1 for c in first if c.endswith("_status"))
    samples = ReadingsLog(path, rig.robot.joint_names(), n_tools).read()
    if not samples:
        raise HardwareError(f"{path}: the log holds no readings")
    cursor = _Cursor(samples, n_tools)
    return ReplayActuator(rig, cursor), ReplayTracker(cursor)
