"""Rig files: the examples parse, joint units convert through gears and leads, and every mistake is
refused with a message that names the file, the table and the key, and says what to change."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from ctrkin.errors import JointError
from ctrkin.hardware.rig import Drive, RigDescription, RigError, parse_rig
from tests.hardware.conftest import CANOPEN_RIG

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "rigs"


@pytest.mark.parametrize("name", ["paper.toml", "paper_dry_run.toml", "virtual.toml"])
def test_example_rig_files_parse(name):
    rig = RigDescription.from_toml(EXAMPLES / name)
    assert rig.robot.name == "paper" and rig.home.shape == (4,)
    rig.check(rig.home)
    assert (rig.velocity() <= rig.max_velocity()).all()


def test_paper_rig_is_the_papers_hardware():
    rig = RigDescription.from_toml(EXAMPLES / "paper.toml")
    assert rig.actuator.kind == "canopen" and len(rig.actuator.drives) == 4
    assert rig.tracker.device == "aurora" and rig.tracker.readings == 5
    assert rig.fingerprint() == RigDescription.from_toml(EXAMPLES / "paper.toml").fingerprint()


def test_counts_through_gear_and_lead():
    rot = Drive("alpha_1", counts_per_turn=64, gear_ratio=64.0, zero=10.0)
    assert rot.counts_per_unit == pytest.approx(64 * 64 / 360)
    assert rot.to_counts(100.0) == round(90.0 * 64 * 64 / 360)
    assert rot.from_counts(rot.to_counts(100.0)) == pytest.approx(100.0, abs=360 / 64 / 64)
    lin = Drive("beta_1", counts_per_turn=64, gear_ratio=16.0, lead_mm=0.5, direction=-1)
    assert lin.to_counts(-2.0) == round(2.0 * 64 * 16 / 0.5)                # direction -1
    assert lin.drive_velocity(1.0) == round(64 * 16 / 0.5 / 64 * 60)       # 1 mm/s = 1920 motor rpm
    assert Drive("beta_1", lead_mm=1.0, velocity_unit="counts/s").drive_velocity(0.5) == 2048


def _broken(change) -> str:
    d = copy.deepcopy(CANOPEN_RIG)
    change(d)
    with pytest.raises(RigError) as e:
        parse_rig(d, source="my_rig.toml")
    return str(e.value)


@pytest.mark.parametrize("change, words", [
    (lambda d: d["actuator"]["drives"][2].pop("lead_mm"), ["my_rig.toml", "beta_1", "lead_mm", "lead-screw"]),
    (lambda d: d["actuator"]["drives"][0].update(lead_mm=1.0), ["alpha_1", "remove lead_mm"]),
    (lambda d: d["actuator"]["drives"].pop(), ["beta_2", "needs a drive for every joint"]),
    (lambda d: d["actuator"]["drives"][1].update(node_id=1), ["node_id"]),
    (lambda d: d["actuator"]["drives"][1].update(node_id=200), ["1..127"]),
    (lambda d: d["actuator"]["drives"][0].update(velocity=100.0), ["above max_velocity 90"]),
    (lambda d: d["actuator"]["drives"][0].update(gear_ratio=0), ["gear_ratio", "> 0"]),
    (lambda d: d["actuator"]["drives"][0].update(joint="alpha_3"), ["alpha_3", "not a joint"]),
    (lambda d: d["actuator"]["drives"][0].update(speed=3), ["unknown key", "speed"]),
    (lambda d: d["actuator"]["drives"][2].update(min=0.0, max=-5.0), ["min", "below max"]),
    (lambda d: d.update(colour="red"), ["unknown key", "colour"]),
    (lambda d: d["tracker"].update(kind="ndi", device="polaris"), ["tools", ".rom"]),
    (lambda d: d["tracker"].update(kind="ndi", device="vega", tools=["a.rom"]), ["host"]),
    (lambda d: d["tracker"].update(accept=["fine"]), ["accept", "enabled"]),
    (lambda d: d["tracker"].update(reference_tool=1), ["same tool"]),
    (lambda d: d["actuator"].update(simulate=False), ["virtual tracker", "simulate = true"]),
    (lambda d: d["tracker"].update(kind="replay", log="r.csv"), ["replay"]),
    (lambda d: d.update(home=[0, 0, -95.0, 0]), ["home", "beta_1", "outside the rig's limits"]),
    (lambda d: d.update(home=[0, 0]), ["home", "4 numbers"]),
])
def test_mistakes_are_refused_with_what_to_change(change, words):
    message = _broken(change)
    for w in words:
        assert w in message, message


def test_check_refuses_joints_outside_drive_limits_or_the_robot(canopen_rig):
    canopen_rig.check(np.array([10.0, 0.0, -20.0, -3.0]))
    with pytest.raises(JointError, match="beta_2 = -45"):
        canopen_rig.check(np.array([0.0, 0.0, -50.0, -45.0]))
    with pytest.raises(JointError):                       # inside the drive limits, but β1 > β2
        canopen_rig.check(np.array([0.0, 0.0, -1.0, -3.0]))


def test_a_rig_file_with_a_robot_file_beside_it(tmp_path):
    (tmp_path / "bot.toml").write_text((Path(__file__).resolve().parents[2] / "examples" / "robots"
                                        / "comet_nylon_ndi.toml").read_text())
    (tmp_path / "rig.toml").write_text('robot = "bot.toml"\nhome = [0, 0, -250, -90]\n'
                                       '[actuator]\nkind = "virtual"\n[tracker]\nkind = "virtual"\n')
    rig = RigDescription.from_toml(tmp_path / "rig.toml")
    assert rig.robot.name == "comet-nylon-ndi" and rig.path("x.rom") == tmp_path / "x.rom"
    (tmp_path / "bad.toml").write_text("name = \n")
    with pytest.raises(RigError, match="not valid TOML"):
        RigDescription.from_toml(tmp_path / "bad.toml")
