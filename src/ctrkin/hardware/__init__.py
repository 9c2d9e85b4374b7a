"""Hardware: the actuator and tracker interfaces of a rig, the rig description (TOML), and their
implementations: the virtual robot, CiA 402 drives over CANopen (Maxon EPOS4), NDI trackers
(Aurora, Polaris, Vega) and a replay device (docs/hardware.md)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["Actuator", "HardwareError", "RigDescription", "RigError", "RigStop", "Tracker",
           "TrackerFrame", "open_rig"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.hardware.interfaces import (
        Actuator,
        HardwareError,
        RigStop,
        Tracker,
        TrackerFrame,
    )
    from ctrkin.hardware.open import open_rig
    from ctrkin.hardware.rig import RigDescription, RigError

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
