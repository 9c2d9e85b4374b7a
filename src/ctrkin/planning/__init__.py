"""Planning: snap-safe joint trajectories through tip targets on the mechanics (docs/planning.md)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["Plan", "PlanConfig", "SnapOffer", "TargetReport", "plan_path", "stability_margin"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.planning.margin import stability_margin
    from ctrkin.planning.planner import Plan, PlanConfig, SnapOffer, TargetReport, plan_path

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
