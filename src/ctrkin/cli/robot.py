"""`ctrkin robot`: robot description files.

    ctrkin robot template --out my_robot.toml      # the paper robot, every field with its unit
    ctrkin solve --robot my_robot.toml --q 0,0,-15,-5
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import click

from ctrkin.cli.common import output_file, overwrite_option, say
from ctrkin.cli.from_config import config_options, option_help
from ctrkin.robots.builtin import robot_template
from ctrkin.util.files import atomic_write_text


@dataclass(frozen=True)
class TemplateConfig:
    """Where `ctrkin robot template` writes (one option per field)."""

    out: str | None = field(default=None, metadata=option_help("TOML file to write (default: stdout).",
                                                               path="out"))


@click.group("robot", epilog="""\b
Examples:
  ctrkin robot template --out my_robot.toml""")
def robot_group() -> None:
    """Robot description files: a documented template."""


@robot_group.command("template", epilog="""\b
Examples:
  ctrkin robot template --out my_robot.toml
  ctrkin robot template > my_robot.toml""")
@config_options(TemplateConfig)
@overwrite_option()
def template_cmd(overwrite: bool, **settings: Any) -> None:
    """A robot TOML file to edit: the paper robot (paper Table I), every field commented with its unit;
    it loads back as the built-in `paper` robot."""
    out_file = TemplateConfig(**settings).out
    text = robot_template()
    if out_file is None:
        click.echo(text, nl=False)
        return
    output_file(out_file, "robot description", overwrite)
    atomic_write_text(out_file, text)
    say(f"wrote {out_file}: edit it, then pass it as --robot {out_file}")
