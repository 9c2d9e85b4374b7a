"""ctrkin: kinematics of concentric tube robots, with hysteresis and snapping.

    import ctrkin
    robot = ctrkin.paper_robot()
    eq = ctrkin.solve(robot, [0, 0, -15, -5])          # q = (α1, α2 deg, β1, β2 mm)
    traj = ctrkin.follow(robot, Q)                       # continuation, snaps flagged
"""

__version__ = "0.1.0"

from ctrkin.mechanics import Equilibrium, SolverSettings, Trajectory, follow, solve, solve_many
from ctrkin.robots import Robot, Tube, load_robot, paper_robot

__all__ = ["Equilibrium", "Robot", "SolverSettings", "Trajectory", "Tube", "__version__", "follow",
           "load_robot", "paper_robot", "solve", "solve_many"]


def __getattr__(name: str):  # torch is imported only when a learned model is asked for
    if name == "Kinematics":
        from ctrkin.inference import Kinematics

        return Kinematics
    raise AttributeError(f"module 'ctrkin' has no attribute {name!r}")
