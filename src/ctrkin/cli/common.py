"""Options and parsing shared by the sub-commands."""

from __future__ import annotations

import click

from ctrkin.robots import Robot, load_robot

robot_option = click.option(
    "--robot", "robot_spec", default="paper", show_default=True,
    help="Built-in robot name (paper, timclab) or path to a robot TOML file.")


def get_robot(spec: str) -> Robot:
    return load_robot(spec)


def parse_floats(text: str, what: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(" ", "").split(",") if v != ""]
    except ValueError:
        raise click.BadParameter(f"{what} must be comma-separated numbers, got {text!r}") from None
