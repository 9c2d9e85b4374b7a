"""The documented robot TOML template (`ctrkin robot template`) and robot identity by tubes, not name."""

from __future__ import annotations

import dataclasses
import tomllib

from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.robots import Robot, load_robot, paper_robot
from ctrkin.robots.builtin import robot_template


def test_the_template_loads_back_as_the_paper_robot(tmp_path) -> None:
    r = CliRunner().invoke(cli, ["robot", "template", "--out", str(tmp_path / "r.toml")])
    assert r.exit_code == 0, r.output
    assert load_robot(str(tmp_path / "r.toml")) == paper_robot()
    assert CliRunner().invoke(cli, ["robot", "template"]).stdout == robot_template()
    again = CliRunner().invoke(cli, ["robot", "template", "--out", str(tmp_path / "r.toml")])
    assert again.exit_code == 1 and "--overwrite" in again.stderr


def test_every_field_of_the_template_is_commented_with_its_unit() -> None:
    text = robot_template()
    lines: dict[str, str] = {}
    for line in text.splitlines():        # the first tube's lines carry the comments
        if "=" in line and not line.startswith("#"):
            lines.setdefault(line.split("=")[0].strip(), line)
    for field, unit in (("od", "mm"), ("id", "mm"), ("straight_length", "mm"), ("curved_length", "mm"),
                        ("curvature", "1/mm"), ("youngs_modulus", "GPa"), ("poisson_ratio", "-")):
        assert f"# {unit}" in lines[field], field
    documented = set(tomllib.loads(text)["tubes"][0]) | {"sections"}
    assert {f.name for f in dataclasses.fields(paper_robot().tubes[0])} <= documented
    assert "transmission_length" in text and "sections" in text


def test_a_renamed_robot_is_the_same_hardware_a_changed_tube_is_not() -> None:
    robot = paper_robot()
    renamed = dataclasses.replace(robot, name="my-bench-robot")
    assert renamed.mechanical_fingerprint() == robot.mechanical_fingerprint()
    assert renamed.fingerprint() != robot.fingerprint()          # the stored integrity hash keeps the name
    tube = dataclasses.replace(robot.tubes[0], curvature=1 / 26.0)
    changed = Robot(tubes=(tube, robot.tubes[1]), name="paper")
    assert changed.mechanical_fingerprint() != robot.mechanical_fingerprint()
    rigid = dataclasses.replace(robot, transmission="rigid")
    assert rigid.mechanical_fingerprint() != robot.mechanical_fingerprint()
