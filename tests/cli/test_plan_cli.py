"""`ctrkin plan` through click's runner: the plan CSV, its summary and figure, refusals."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
from click.testing import CliRunner

from ctrkin import paper_robot, solve
from ctrkin.cli.main import cli


def _targets(tmp_path, alphas=(160.0, 180.0, 200.0, 220.0, 240.0, 260.0)) -> str:
    robot = paper_robot()
    tips = np.array([solve(robot, [a, 0.0, -20.0, 0.0]).tip_position for a in alphas])
    path = tmp_path / "targets.csv"
    pd.DataFrame(tips, columns=["x", "y", "z"]).to_csv(path, index=False)
    return str(path)


def test_plan_writes_table_summary_and_figure(tmp_path) -> None:
    out = tmp_path / "plan"
    res = CliRunner().invoke(cli, ["plan", "--targets", _targets(tmp_path), "--start-joints",
                                   "150,0,-20,0", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert summary["reached"] == 6 and summary["planned_snaps"] == 0
    assert summary["naive_snaps"] >= 1
    table = pd.read_csv(out / "plan.csv")
    assert list(table.columns[:5]) == ["step", "alpha_1", "alpha_2", "beta_1", "beta_2"]
    assert {"tip_x", "tip_y", "tip_z", "margin", "target", "route", "snap"} <= set(table.columns)
    assert sorted(table.loc[table["target"] >= 0, "target"]) == [0, 1, 2, 3, 4, 5]
    assert not table["snap"].any() and table["margin"].min() >= 0.25
    assert (out / "plan.png").stat().st_size > 10_000
    saved = json.loads((out / "plan.json").read_text(), parse_constant=lambda c: 1 / 0)  # no NaN, inf
    assert saved["per_target"][0]["reached"] and saved["config"]["beta_limits_mm"] == [None, 0.0]
    again = CliRunner().invoke(cli, ["plan", "--targets", _targets(tmp_path), "--start-joints",
                                     "150,0,-20,0", "--out", str(out), "--no-naive"])
    assert again.exit_code == 1 and "overwrite" in again.output       # an existing plan is kept


def test_plan_refuses_bad_targets_and_joints(tmp_path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    res = CliRunner().invoke(cli, ["plan", "--targets", str(bad), "--start-joints", "0,0,-20,0",
                                   "--out", str(tmp_path / "p1")])
    assert res.exit_code == 1 and "x, y, z" in res.output
    res = CliRunner().invoke(cli, ["plan", "--targets", _targets(tmp_path), "--start-joints", "0,0,5,0",
                                   "--out", str(tmp_path / "p2")])
    assert res.exit_code == 1 and "beta_1 <= beta_2" in res.output
    assert not (tmp_path / "p1").exists() or not any((tmp_path / "p1").iterdir())


def test_plan_with_a_learned_snap_model(tmp_path, model_dirs) -> None:
    """--model streams the snap-aware FK along the plan: its state, margin and predicted snaps per step
    in plan.csv, the summary in plan.json (the tests' small model: a jump above 0.3 mm is a snap, see
    tests/planning/test_learned_planner.py); a model without a branch state is refused."""
    out = tmp_path / "plan"
    res = CliRunner().invoke(cli, ["plan", "--targets", _targets(tmp_path, (160.0, 200.0, 240.0)),
                                   "--start-joints", "150,0,-20,0", "--model", str(model_dirs["fk_branch"]),
                                   "--learned-jump-mm", "0.3", "--out", str(out), "--no-naive", "--json"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert summary["learned_snaps"] == 0 and summary["learned_min_margin_deg"] >= 5.0
    table = pd.read_csv(out / "plan.csv")
    assert {"learned_state", "learned_margin_deg", "learned_snap", "learned_jump_mm"} <= set(table.columns)
    assert table["learned_margin_deg"].min() >= 5.0 and not table["learned_snap"].any()
    assert set(table["learned_state"]) <= {0, 1}
    assert (out / "plan.png").stat().st_size > 10_000
    res = CliRunner().invoke(cli, ["plan", "--targets", _targets(tmp_path), "--start-joints", "150,0,-20,0",
                                   "--model", str(model_dirs["fk"]), "--out", str(tmp_path / "p2")])
    assert res.exit_code == 1 and "branch state" in res.output
