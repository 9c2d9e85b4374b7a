"""`--json` of sweep, collect, train, evaluate and calibrate: one JSON object on stdout, nothing else
there (messages go to stderr), with the command's summary figures and the paths it wrote."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli

ENV = {"CTRKIN_NO_PROGRESS": "1"}


def run_json(args: list[str]) -> dict:
    r = CliRunner().invoke(cli, args, env=ENV)
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)          # the whole of stdout is one JSON object
    assert isinstance(out, dict)
    return out


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("json")
    out = run_json(["collect", "--protocol", "arbitrary", "--workers", "1", "--out", str(root / "data"),
                    "--json"])
    assert out["samples"] == 361 and out["out"] == str(root / "data")
    assert out["protocol"] == "arbitrary" and out["sequences"] >= 1
    return root


def test_collect_json_of_a_sweep_has_its_hysteresis(tmp_path) -> None:
    out = run_json(["collect", "--protocol", "sweeps", "--levels", "8", "--workers", "1",
                    "--out", str(tmp_path / "s"), "--json"])
    assert out["samples"] > 0 and (tmp_path / "s" / "data.parquet").is_file()
    assert [h["relative_translation_mm"] for h in out["hysteresis"]] == [8.0]
    assert out["hysteresis"][0]["hysteresis_max_mm"] >= out["hysteresis"][0]["hysteresis_mean_mm"] > 0


def test_sweep_json(tmp_path) -> None:
    out = run_json(["sweep", "--translations", "8,20", "--step", "15", "--out", str(tmp_path / "sw"),
                    "--json"])
    assert [lv["relative_translation_mm"] for lv in out["levels"]] == [8.0, 20.0]
    assert all(lv["steps"] == 49 for lv in out["levels"])           # 0 → 360 → 0 in 15° steps
    assert Path(out["files"]["table"]).is_file() and Path(out["files"]["plot"]).is_file()
    assert all(lv["snaps"] == len(lv["snap_alpha_1_deg"]) for lv in out["levels"])


def test_train_json(data, tmp_path) -> None:
    out = run_json(["train", "--task", "fk", "--model", "lstm_mlp",
                    "--data", str(data / "data"), "--out", str(tmp_path / "fk"),
                    "--epochs", "1", "--structure", "L8|D8", "--threads", "1", "--split", "random", "--json"])
    assert out["out"] == str(tmp_path / "fk") and out["task"] == "fk"
    assert out["training"]["epochs"] == 1
    assert out["test"]["vs_measured"]["position_mm_rmse"] > 0


def test_evaluate_json_and_overwrite_replaces_the_folder(data, tmp_path) -> None:
    folder = tmp_path / "eval"
    out = run_json(["evaluate", "--data", str(data / "data"), "--predictor", "tcm", "--predictor", "tcm",
                    "--out", str(folder), "--json"])
    assert [p["predictor"] for p in out["predictors"]] == ["tcm", "tcm"]
    assert out["predictors"][1]["out"] == f"{folder}/tcm-2"        # named after the predictor (issue 22)
    assert out["predictors"][0]["overall"]["samples"] == 361
    assert (folder / "tcm-2" / "results.json").is_file()
    # one predictor now: the sub-folders of the earlier run go, the folder holds this run only
    out = run_json(["evaluate", "--data", str(data / "data"), "--predictor", "tcm", "--out", str(folder),
                    "--overwrite", "--json"])
    assert not (folder / "tcm-1").exists() and not (folder / "tcm-2").exists()
    assert (folder / "results.json").is_file()
    assert sorted(p.name for p in folder.parent.iterdir()) == ["eval"]      # no temporary folder left


def test_evaluate_json_without_out_prints_no_table(data) -> None:
    r = CliRunner().invoke(cli, ["evaluate", "--data", str(data / "data"), "--predictor", "tcm", "--json"],
                           env=ENV)
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert out["predictors"][0]["out"] is None
    assert "mean mm" in r.stderr              # the table, which is the result without --json


def test_calibrate_json(data, tmp_path) -> None:
    out = run_json(["calibrate", "--data", str(data / "data"), "--fit", "registration,precurvature",
                    "--max-evaluations", "3", "--out", str(tmp_path / "cal.toml"), "--json"])
    assert out["out"] == str(tmp_path / "cal.toml") and (tmp_path / "cal.toml").is_file()
    assert out["samples"] == 361 and out["calibrated_mean_mm"] > 0
    assert {p["name"] for p in out["parameters"]} and all("value" in p for p in out["parameters"])
