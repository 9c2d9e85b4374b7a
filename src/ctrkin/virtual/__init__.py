"""Virtual robot: the TCM of perturbed tubes behind backlash, friction, an EM tracker and encoders."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["Motion", "Recording", "Tracker", "VirtualConfig", "VirtualConfigError", "VirtualRobot",
           "VirtualState"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.virtual.config import VirtualConfig, VirtualConfigError
    from ctrkin.virtual.robot import Motion, Recording, VirtualRobot, VirtualState
    from ctrkin.virtual.tracker import Tracker

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
