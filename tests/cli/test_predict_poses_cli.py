"""`ctrkin predict IK_MODEL --poses FILE`: IK for a file of target poses, with the per-target flags,
and clear errors for missing columns and NaNs."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.data import Dataset

ENV = {"CTRKIN_NO_PROGRESS": "1"}
POSES = ["x", "y", "z", "q0", "qx", "qy"]


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("ik_poses")
    runner = CliRunner()
    r = runner.invoke(cli, ["collect", "--protocol", "arbitrary", "--workers", "1",
                            "--out", str(root / "data")], env=ENV)
    assert r.exit_code == 0, r.output
    for task, model in (("ik", "lstm_mlp"), ("fk", "lstm_mlp")):
        r = runner.invoke(cli, ["train", "--task", task, "--model", model, "--data", str(root / "data"),
                                "--out", str(root / task), "--epochs", "1", "--structure", "L8|D8",
                                "--threads", "1", "--split", "random"], env=ENV)
        assert r.exit_code == 0, r.output
    frame = Dataset.load(root / "data").frame
    frame[["sequence_id", "step", *POSES]].iloc[:40].to_csv(root / "targets.csv", index=False)
    return root


def test_ik_on_a_poses_file_gives_joints_and_flags(models, tmp_path) -> None:
    out = tmp_path / "joints.csv"
    r = CliRunner().invoke(cli, ["predict", str(models / "ik"), "--poses", str(models / "targets.csv"),
                                 "--out", str(out)], env=ENV)
    assert r.exit_code == 0, r.output
    table = pd.read_csv(out)
    assert list(table.columns) == ["sequence_id", "step", "pred_alpha_1", "pred_alpha_2", "pred_beta_1",
                                   "pred_beta_2", "in_workspace", "reason", "projected", "jump"]
    assert len(table) == 40 and np.isfinite(table.filter(like="pred_").to_numpy()).all()
    assert table["in_workspace"].dtype == bool and table["jump"].dtype == bool
    assert "wrote 40 predictions" in r.output


def test_poses_without_index_columns_are_one_sequence_on_stdout(models, tmp_path) -> None:
    poses = pd.read_csv(models / "targets.csv")[POSES].iloc[:5]
    poses.to_parquet(tmp_path / "t.parquet")
    r = CliRunner().invoke(cli, ["predict", str(models / "ik"), "--poses", str(tmp_path / "t.parquet")],
                           env=ENV)
    assert r.exit_code == 0, r.output
    table = pd.read_csv(io.StringIO(r.stdout))
    assert table["step"].tolist() == [0, 1, 2, 3, 4] and "sequence_id" not in table


def test_missing_columns_and_nans_are_named(models, tmp_path) -> None:
    poses = pd.read_csv(models / "targets.csv")
    poses.drop(columns=["qy"]).to_csv(tmp_path / "no_qy.csv", index=False)
    r = CliRunner().invoke(cli, ["predict", str(models / "ik"), "--poses", str(tmp_path / "no_qy.csv")])
    assert r.exit_code == 1 and "lacks pose column(s) ['qy']" in r.stderr
    poses.loc[3, "z"] = np.nan
    poses.to_csv(tmp_path / "nan.csv", index=False)
    r = CliRunner().invoke(cli, ["predict", str(models / "ik"), "--poses", str(tmp_path / "nan.csv")])
    assert r.exit_code == 1 and "first at data row 4 (columns ['z'])" in r.stderr


def test_poses_need_an_ik_model_and_one_input(models) -> None:
    targets = str(models / "targets.csv")
    r = CliRunner().invoke(cli, ["predict", str(models / "fk"), "--poses", targets])
    assert r.exit_code == 1 and "--poses needs an IK model" in r.stderr
    r = CliRunner().invoke(cli, ["predict", str(models / "ik"), "--poses", targets,
                                 "--data", str(models / "data")])
    assert r.exit_code == 2 and "either --data" in r.output
    r = CliRunner().invoke(cli, ["predict", str(models / "ik"), "--poses", targets,
                                 "--start-joints", "0,0,-20,-5"])
    assert r.exit_code == 1 and "follow IK" in r.stderr       # start joints need a follow IK model
