"""Issue 23 item 1: `ctrkin train` without --model trains the recommended model of its task (the
snap-aware FK, the follow IK) with the settings `reproduce --scale quick` trains it with; a model or a
setting given on the command line wins."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.evaluation.scales import SCALES
from ctrkin.evaluation.table import RECOMMENDED as REPORTED
from ctrkin.training.config import RECOMMENDED

ENV = {"CTRKIN_NO_PROGRESS": "1"}


@pytest.fixture(scope="module")
def data(sweeps, tmp_path_factory):
    folder = tmp_path_factory.mktemp("recommended") / "data"
    sweeps.save(folder)
    return folder


def _train(data, out, *words):
    r = CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(out), "--epochs", "1",
                                 "--threads", "1", *words], env=ENV)
    assert r.exit_code == 0, r.output
    # one epoch is its budget while the validation loss still improves: said, not silent (issue 22)
    assert "warning: training stopped at its budget (max_epochs, 1 epochs)" in r.output
    assert "stopped by max_epochs" in r.output and "fit: still improving" in r.output
    return json.loads((out / "config.json").read_text())["train"]


def test_the_recommended_settings_are_those_reproduce_trains_and_reports():
    quick = SCALES["quick"]
    for task, budget in (("fk", quick.branch), ("ik", quick.follow)):
        preset = RECOMMENDED[task]
        assert preset["model"] == REPORTED[task].name
        assert (preset["batch_size"], preset["lr"], preset["lr_schedule"], preset["base_epochs"],
                preset["patience"], preset.get("ib", 2)) == (budget.batch_size, budget.lr, budget.lr_schedule,
                                                             budget.epochs, budget.patience, budget.ib)


@pytest.mark.parametrize("task", ["fk", "ik"])
def test_train_without_a_model_trains_the_recommended_one(data, tmp_path, task):
    cfg = _train(data, tmp_path / task, "--task", task)
    preset = RECOMMENDED[task]
    if task == "fk":
        # the snap-aware FK or the paper's LSTM-MLP, as validation says (ctrkin.training.selection):
        # which one was kept is in its metrics, and its config is that model's with the budget asked for
        metrics = json.loads((tmp_path / task / "metrics.json").read_text())
        kept = metrics["model_selection"]["kept"]
        preset = {**preset, **metrics["model_selection"]["candidates"][kept]}
        assert kept == "paper" or (cfg["play_lags"], cfg["joint_field"]) == (True, True)
    assert {k: cfg[k] for k in preset} == preset


def test_the_command_line_wins(data, tmp_path):
    cfg = _train(data, tmp_path / "fk", "--task", "fk", "--batch-size", "64", "--structure", "L8|D8")
    assert cfg["model"] == "lstm_mlp_branch" and cfg["batch_size"] == 64 and cfg["lr"] == 2e-3
    assert cfg["options"]["structure"] == "L8|D8"
    paper = _train(data, tmp_path / "paper", "--task", "fk", "--model", "lstm_mlp", "--structure", "L8|D8")
    assert (paper["model"], paper["batch_size"], paper["lr"], paper["base_epochs"]) == \
        ("lstm_mlp", 32, 1e-3, 500)


def test_the_model_said_and_in_json_is_the_one_kept(data, tmp_path):
    out = tmp_path / "fk"
    r = CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(out), "--epochs", "1",
                                 "--threads", "1", "--task", "fk", "--json"], env=ENV)
    assert r.exit_code == 0, r.output
    kept = json.loads((out / "config.json").read_text())["train"]["model"]
    assert json.loads(r.stdout)["model"] == kept
    assert f"trained {kept}: 1 epochs" in r.stderr
