"""Robot description: tubes, robots, built-in robots and their TOML files."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

_WHERE = {
    "load_robot": "ctrkin.robots.builtin", "paper_robot": "ctrkin.robots.builtin",
    "timclab_robot": "ctrkin.robots.builtin", "Robot": "ctrkin.robots.robot",
    "Section": "ctrkin.robots.tube", "Tube": "ctrkin.robots.tube",
}

__all__ = ["Robot", "Section", "Tube", "load_robot", "paper_robot", "timclab_robot"]

__getattr__, __dir__ = lazy_attributes(__name__, _WHERE)

if TYPE_CHECKING:
    from ctrkin.robots.builtin import load_robot, paper_robot, timclab_robot
    from ctrkin.robots.robot import Robot
    from ctrkin.robots.tube import Section, Tube
