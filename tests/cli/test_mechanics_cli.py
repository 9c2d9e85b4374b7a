"""`ctrkin solve` and `ctrkin sweep` through click's runner."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli


def test_solve_json() -> None:
    res = CliRunner().invoke(cli, ["solve", "--q", "0,0,-15,-5", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["converged"] and out["stable"] and len(out["tip_pose"]) == 6


def test_solve_rejects_invalid_joints() -> None:
    res = CliRunner().invoke(cli, ["solve", "--q", "0,0,5,-5"])
    assert res.exit_code == 1 and res.stdout == ""
    assert res.stderr.startswith("Error: ") and "beta_1 <= beta_2" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_solve_rejects_garbage() -> None:
    res = CliRunner().invoke(cli, ["solve", "--q", "0,zero,-15,-5"])
    assert res.exit_code == 2 and "comma-separated" in res.output


def test_sweep_writes_csv_and_png(tmp_path) -> None:
    out = tmp_path / "sw"
    res = CliRunner().invoke(cli, ["sweep", "--translations", "4,20", "--step", "5", "--out", str(out)])
    assert res.exit_code == 0, res.output
    table = pd.read_csv(out / "sweep.csv")
    assert set(table["relative_translation"]) == {4.0, 20.0}
    snaps = table.groupby("relative_translation")["snap"].sum()
    assert snaps[4.0] == 0 and snaps[20.0] == 2
    assert (out / "sweep.png").stat().st_size > 10_000


def test_solve_prints_t_of_l_and_json_gives_the_backbone() -> None:
    from ctrkin.mechanics import solve
    from ctrkin.pose import tip_azimuth
    from ctrkin.robots import paper_robot

    eq = solve(paper_robot(), [180.0, 30.0, -20.0, 0.0])
    expected = (float(tip_azimuth(eq.tip_position, 30.0)) + 180.0) % 360.0 - 180.0
    res = CliRunner().invoke(cli, ["solve", "--q", "180,30,-20,0"])
    assert res.exit_code == 0, res.output
    assert f"(deg): {expected:.3f}" in res.output
    res = CliRunner().invoke(cli, ["solve", "--q", "180,30,-20,0", "--json", "--backbone"])
    out = json.loads(res.output)
    assert out["T_L_deg"] == pytest.approx(expected) and -180.0 < out["T_L_deg"] <= 180.0
    b = out["backbone"]
    assert len(b["s_mm"]) == len(b["points_mm"]) == len(b["twist_deg"]) > 2
    assert all(len(row) == 2 for row in b["twist_deg"]) and np.all(np.diff(b["s_mm"]) > 0)
    assert b["points_mm"][-1] == pytest.approx(out["tip_position_mm"], abs=1e-9)
    plain = CliRunner().invoke(cli, ["solve", "--q", "0,0,-15,-5", "--json"]).output
    assert "backbone" not in json.loads(plain)
    table = CliRunner().invoke(cli, ["solve", "--q", "180,30,-20,0", "--backbone"]).output
    assert "s_mm,x_mm,y_mm,z_mm,psi_1_deg,psi_2_deg" in table
