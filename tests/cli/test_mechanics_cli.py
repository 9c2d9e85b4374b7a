"""`ctrkin solve` and `ctrkin sweep` through click's runner."""

from __future__ import annotations

import json

import pandas as pd
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
