"""Robot description: tubes, robots, built-in robots and their TOML files."""

from ctrkin.robots.builtin import load_robot, paper_robot, timclab_robot
from ctrkin.robots.robot import Robot
from ctrkin.robots.tube import Section, Tube

__all__ = ["Robot", "Section", "Tube", "load_robot", "paper_robot", "timclab_robot"]
