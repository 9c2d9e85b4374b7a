"""Control: a closed-loop tip controller on the learned FK, a plan driven with tracker feedback, and
their demonstration on the virtual robot (docs/planning.md: Control loop, Executing a plan with
feedback)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["Command", "ControlConfig", "Controller", "Executed", "FeedbackConfig", "LoopResult", "VirtualRig",
           "circle_path", "execute_plan", "run_virtual"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.control.controller import Command, ControlConfig, Controller
    from ctrkin.control.plan_feedback import Executed, FeedbackConfig, execute_plan
    from ctrkin.control.virtual_loop import LoopResult, VirtualRig, circle_path, run_virtual

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
