"""Mechanics: the torsionally compliant model (TCM), point-wise solves and continuation."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["Equilibrium", "SolverSettings", "Trajectory", "follow", "solve", "solve_many"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.mechanics.continuation import Trajectory, follow
    from ctrkin.mechanics.pointwise import Equilibrium, solve, solve_many
    from ctrkin.mechanics.settings import SolverSettings

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
