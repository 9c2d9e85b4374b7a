"""Mechanics: the torsionally compliant model (TCM), point-wise solves and continuation."""

from ctrkin.mechanics.continuation import Trajectory, follow
from ctrkin.mechanics.pointwise import Equilibrium, solve, solve_many
from ctrkin.mechanics.settings import SolverSettings

__all__ = ["Equilibrium", "SolverSettings", "Trajectory", "follow", "solve", "solve_many"]
