"""`ctrkin reproduce` on a robot it was not written for, end to end at tiny scale: three tubes, a
robot file, --set. The protocols take their translations from the robot (the middle tube moves with
the outer one: docs/reproduction.md, Other robots), every model trains on 3-tube joints, the report
names the robot and the settings."""

from __future__ import annotations

import json
import math

import pytest
from click.testing import CliRunner

from ctrkin.acquisition.ranges import ProtocolRanges
from ctrkin.cli.main import cli
from ctrkin.evaluation.datasets import virtual_overrides
from ctrkin.inference import Kinematics
from ctrkin.robots.robot import Robot
from ctrkin.robots.tube import Tube
from ctrkin.virtual.config import CENTRAL, VirtualConfig


def three_tube_robot() -> Robot:
    """The paper's inner tube inside two paper-like outer tubes (middle and outer both curved, 14.5 mm
    at 1/24 mm⁻¹): L1 − L2 = 15.5 mm, so the paper's d = 20 mm is out of reach."""
    def tube(od: float, idd: float, straight: float, curved: float, radius: float) -> Tube:
        return Tube(od=od, id=idd, straight_length=straight, curved_length=curved, curvature=1 / radius,
                    youngs_modulus=58.0, poisson_ratio=0.33)

    return Robot(tubes=(tube(0.4, 0.2, 57.0, 15.0, 27.0), tube(0.56, 0.45, 42.0, 14.5, 24.0),
                        tube(0.8, 0.66, 30.0, 14.5, 24.0)), name="three-tube-test")


@pytest.mark.slow
def test_a_three_tube_robot_reproduces_end_to_end_with_set(tmp_path) -> None:
    robot = three_tube_robot()
    robot.to_toml(tmp_path / "three.toml")
    out = tmp_path / "repro"
    # the central values (docs/virtual_robot.md), where this robot snaps and every snap figure has
    # events to score; at the defaults (μ 0.69) its quick data holds no snap (bench_generalisation's
    # `three-tube` row, docs/reproduction.md)
    settings = {**CENTRAL, "noise_mm": 0.1}
    sets = [a for k, v in settings.items() for a in ("--set", f"{k}={v}")]
    res = CliRunner().invoke(cli, ["--quiet", "reproduce", "--scale", "tiny", "--robot",
                                   str(tmp_path / "three.toml"), *sets, "--workers", "1",
                                   "--out", str(out)])
    assert res.exit_code == 0, res.output + str(res.exception)
    results = json.loads((out / "results.json").read_text())
    assert results["robot"]["name"] == "three-tube-test" and len(results["robot"]["tubes"]) == 3
    expected = virtual_overrides(VirtualConfig(**settings))
    assert results["virtual_settings"] == expected and expected["noise_mm"] == 0.1
    meta = json.loads((out / "data" / "paper" / "meta.json").read_text())
    ranges = ProtocolRanges.of(robot)
    assert meta["protocol_params"]["levels_mm"] == list(ranges.levels((4.0, 20.0)))
    assert meta["virtual_robot"]["config"]["noise_mm"] == 0.1
    for key in ("fk.lstm_mlp.position_rmse_mm", "ik.lstm_mlp.tip_error_mm", "snapping.precision",
                "experiments.sweeps.position_rmse_mm", "experiments.ik_square.position_rmse_mm"):
        assert isinstance(results[key], float) and math.isfinite(results[key]), key
    for folder in (results["recommended.fk"], results["recommended.ik"]):
        assert Kinematics.load(out / folder).layout.n_tubes == 3
    report = (out / "report.md").read_text()
    assert ("Robot: three-tube-test, virtual robot seed 0 with "
            + ", ".join(f"{k} = {v}" for k, v in expected.items()) + ".") in report
    assert "Table I)" not in report
