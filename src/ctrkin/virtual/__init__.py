"""Virtual robot: the TCM of perturbed tubes behind backlash, friction, an EM tracker and encoders."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

_WHERE = {
    "VirtualConfig": "ctrkin.virtual.config", "VirtualConfigError": "ctrkin.virtual.config",
    "Motion": "ctrkin.virtual.robot", "Recording": "ctrkin.virtual.robot",
    "VirtualRobot": "ctrkin.virtual.robot", "VirtualState": "ctrkin.virtual.robot",
    "Tracker": "ctrkin.virtual.tracker",
}

__all__ = ["Motion", "Recording", "Tracker", "VirtualConfig", "VirtualConfigError", "VirtualRobot",
           "VirtualState"]

__getattr__, __dir__ = lazy_attributes(__name__, _WHERE)

if TYPE_CHECKING:
    from ctrkin.virtual.config import VirtualConfig, VirtualConfigError
    from ctrkin.virtual.robot import Motion, Recording, VirtualRobot, VirtualState
    from ctrkin.virtual.tracker import Tracker
