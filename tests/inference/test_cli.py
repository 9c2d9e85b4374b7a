"""`ctrkin train`, `ctrkin export`, `ctrkin predict` end to end on a tiny dataset."""

from __future__ import annotations

import json

import numpy as np
import onnxruntime as ort
import pandas as pd
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.inference import Kinematics


def test_train_export_predict(sweeps, tmp_path):
    data = sweeps.save(tmp_path / "data")
    runner = CliRunner()
    out = tmp_path / "ik"
    r = runner.invoke(cli, ["train", "--task", "ik", "--model", "lstm_mlp",
                            "--data", str(data), "--out", str(out), "--epochs", "1",
                            "--structure", "L8|D8", "--threads", "1"], env={"CTRKIN_NO_PROGRESS": "1"})
    assert r.exit_code == 0, r.output
    assert json.loads((out / "config.json").read_text())["train"]["options"] == {"structure": "L8|D8"}
    r = runner.invoke(cli, ["export", str(out), "--out", str(tmp_path / "ik.onnx")])
    assert r.exit_code == 0, r.output
    assert ort.InferenceSession(str(tmp_path / "ik.onnx")).get_inputs()[0].shape[1:] == [2, 12]
    r = runner.invoke(cli, ["predict", str(out), "--data", str(data), "--out", str(tmp_path / "p.csv")])
    assert r.exit_code == 0, r.output
    table = pd.read_csv(tmp_path / "p.csv")
    assert len(table) == len(sweeps.frame)
    assert {"pred_alpha_1", "pred_beta_2", "in_workspace", "reason"} <= set(table.columns)
    ref = Kinematics.load(out).predict(sweeps).joints
    np.testing.assert_allclose(table[["pred_alpha_1", "pred_alpha_2", "pred_beta_1", "pred_beta_2"]], ref,
                               rtol=1e-9, atol=1e-9)


def test_train_lists_models():
    r = CliRunner().invoke(cli, ["train", "--list-models"])
    assert r.exit_code == 0
    assert "lstm_mlp_no_delta" in r.output and "S3=L128,L128|D64" in r.output


def test_train_snap_aware_model_with_cosine_schedule(sweeps, tmp_path):
    data = sweeps.save(tmp_path / "data")
    out = tmp_path / "fk_branch"
    r = CliRunner().invoke(cli, ["train", "--task", "fk", "--model", "lstm_mlp_branch", "--data", str(data),
                                 "--out", str(out), "--epochs", "1", "--structure", "L8|D8", "--threads", "1",
                                 "--lr-schedule", "cosine"], env={"CTRKIN_NO_PROGRESS": "1"})
    assert r.exit_code == 0, r.output
    train_cfg = json.loads((out / "config.json").read_text())["train"]
    assert train_cfg["lr_schedule"] == "cosine" and train_cfg["target_frame"] == "outer"
    assert Kinematics.load(out).predict(sweeps).shape == (len(sweeps.frame), 6)
