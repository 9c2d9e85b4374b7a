"""The two small interfaces a rig is made of: an actuator (the motors of every joint) and a tracker.

Modelled on scikit-surgery's NDI tracker (`start_tracking`, `get_frame`, `close`): a simulated
device and a real one are interchangeable behind them, so `ctrkin collect --rig` runs the same
protocol code on the virtual robot, on recorded logs (replay) and on motors and a tracker.

Units at the boundary, as everywhere in ctrkin: joints q = (α1..αN deg, β1..βN mm), velocities in
deg/s and mm/s, positions in mm, quaternions (w, x, y, z) scalar first, time in seconds.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from ctrkin.errors import CtrkinError

# Tool status of one tracker reading (NDI's port status words, named as in its API guide)
OK = "enabled"
PARTIAL = "partially_out_of_volume"
OUT_OF_VOLUME = "out_of_volume"
MISSING = "missing"
DISABLED = "disabled"
STATUSES = (OK, PARTIAL, OUT_OF_VOLUME, MISSING, DISABLED)


class HardwareError(CtrkinError, RuntimeError):
    """A device did not do what it was asked (no answer, a fault, a timeout)."""


class RigStop(HardwareError):
    """A safety rule stopped the collection (tracker loss, out of volume, a joint limit); the motors
    have been stopped and what was recorded before is kept."""


@dataclass(frozen=True, eq=False)
class TrackerFrame:
    """One reading of every tool. time: s (the tracker's clock, or the host's when it has none);
    poses: (K, 7) per tool x, y, z (mm, tracker frame), qw, qx, qy, qz (NaN when not seen);
    status: K tool statuses (STATUSES); error: (K,) the tracker's RMS fit error (mm, NaN if none)."""

    time: float
    poses: np.ndarray
    status: tuple[str, ...]
    error: np.ndarray

    def ok(self, tool: int, accept: tuple[str, ...] = (OK,)) -> bool:
        """Tool `tool` (0-based) was seen with an accepted status and finite numbers."""
        return self.status[tool] in accept and bool(np.isfinite(self.poses[tool]).all())


class Actuator(ABC):
    """The motors of a robot's 2N joints, in the fixed joint order. Every method blocks until done."""

    n_joints: int

    @abstractmethod
    def home(self) -> np.ndarray:
        """Find the joints' zeros (homing) and go to the home configuration; returns the encoder
        joints (2N,) (deg, mm)."""

    @abstractmethod
    def move(self, q: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """Move all joints to q (2N,) together, each at most at velocity (2N,) (deg/s, mm/s), and
        wait until every drive reports the target reached; returns the encoder joints (2N,)."""

    @abstractmethod
    def read(self) -> np.ndarray:
        """The encoder joints now, (2N,) deg and mm."""

    @abstractmethod
    def stop(self) -> None:
        """Stop every motor now (quick stop); safe to call at any time, also twice."""

    def close(self) -> None:  # noqa: B027 (a hook: most devices have nothing to release)
        """Release the device (disable the drives, close the bus). The default does nothing."""

    def begin_run(self, index: int) -> None:  # noqa: B027 (a hook, see the docstring)
        """A protocol run `index` starts (its state must not depend on what came before). The
        default does nothing; the virtual robot rests its mechanics here."""


class Tracker(ABC):
    """A pose tracker with one or more tools (tip sensor, reference body)."""

    n_tools: int

    @abstractmethod
    def start(self) -> None:
        """Connect and start tracking."""

    @abstractmethod
    def read(self) -> TrackerFrame:
        """The next reading of every tool (blocks until the tracker has a new frame)."""

    @abstractmethod
    def stop(self) -> None:
        """Stop tracking and close the connection; safe to call twice."""

    def begin_run(self, index: int) -> None:  # noqa: B027 (a hook, see the docstring)
        """A protocol run `index` starts. The default does nothing; the virtual tracker keys its
        noise to the run here, so that a resumed collection draws the same noise."""
