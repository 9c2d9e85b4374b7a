"""Virtual robot: the TCM of perturbed tubes behind backlash, friction, an EM tracker and encoders."""

from ctrkin.virtual.config import VirtualConfig, VirtualConfigError
from ctrkin.virtual.robot import Motion, Recording, VirtualRobot, VirtualState
from ctrkin.virtual.tracker import Tracker

__all__ = ["Motion", "Recording", "Tracker", "VirtualConfig", "VirtualConfigError", "VirtualRobot",
           "VirtualState"]
