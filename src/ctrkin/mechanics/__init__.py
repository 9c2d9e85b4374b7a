"""Mechanics: the torsionally compliant model (TCM), point-wise solves and continuation."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

_WHERE = {
    "Trajectory": "ctrkin.mechanics.continuation", "follow": "ctrkin.mechanics.continuation",
    "Equilibrium": "ctrkin.mechanics.pointwise", "solve": "ctrkin.mechanics.pointwise",
    "solve_many": "ctrkin.mechanics.pointwise", "SolverSettings": "ctrkin.mechanics.settings",
}

__all__ = ["Equilibrium", "SolverSettings", "Trajectory", "follow", "solve", "solve_many"]

__getattr__, __dir__ = lazy_attributes(__name__, _WHERE)

if TYPE_CHECKING:
    from ctrkin.mechanics.continuation import Trajectory, follow
    from ctrkin.mechanics.pointwise import Equilibrium, solve, solve_many
    from ctrkin.mechanics.settings import SolverSettings
