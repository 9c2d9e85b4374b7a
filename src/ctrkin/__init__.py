"""ctrkin: kinematics of concentric tube robots, with hysteresis and snapping.

    import ctrkin
    robot = ctrkin.paper_robot()
    eq = ctrkin.solve(robot, [0, 0, -15, -5])          # q = (α1, α2 deg, β1, β2 mm)
    traj = ctrkin.follow(robot, Q)                       # continuation, snaps flagged
    fk = ctrkin.Kinematics.load("models/fk")             # a trained model (torch)

Every name is imported on first use (PEP 562): `import ctrkin` costs no numba or torch import.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes
from ctrkin.version import __version__

__all__ = ["Equilibrium", "Kinematics", "Robot", "SolverSettings", "Trajectory", "Tube", "__version__",
           "follow", "load_robot", "paper_robot", "solve", "solve_many"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.inference import Kinematics
    from ctrkin.mechanics import Equilibrium, SolverSettings, Trajectory, follow, solve, solve_many
    from ctrkin.robots import Robot, Tube, load_robot, paper_robot

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
