"""Robot description: tubes, robots, built-in robots and their TOML files."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["Robot", "Section", "Tube", "load_robot", "paper_robot", "timclab_robot"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.robots.builtin import load_robot, paper_robot, timclab_robot
    from ctrkin.robots.robot import Robot
    from ctrkin.robots.tube import Section, Tube

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
