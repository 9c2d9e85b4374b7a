"""Issue 23 item 5: FK `ctrkin predict --joints FILE` (a joints-only CSV -> tip predictions), and one
column naming for IK predictions: every IK family writes pred_alpha_* / pred_beta_* (absolute joints),
the follow IK too (it wrote pred_step_alpha_*, the name of its network's outputs)."""

from __future__ import annotations

import io

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.inference import Kinematics
from ctrkin.training import TrainConfig, train

ENV = {"CTRKIN_NO_PROGRESS": "1"}
JOINTS = ["alpha_1", "alpha_2", "beta_1", "beta_2"]
POSES = ["x", "y", "z", "q0", "qx", "qy"]


@pytest.fixture(scope="module")
def follow_dir(sweeps, tmp_path_factory):
    out = tmp_path_factory.mktemp("follow_cols") / "ik_follow"
    train(sweeps, TrainConfig(task="ik", model="follow_mlp", max_epochs=2, threads=1,
                              options={"structure": "|D16"}), out, progress=False)
    return out


def test_fk_predicts_the_tips_of_a_joints_file(model_dirs, sweeps, tmp_path):
    frame = sweeps.frame
    rows = frame[["sequence_id", "step", *JOINTS]].iloc[:30]
    rows.to_csv(tmp_path / "joints.csv", index=False)
    out = tmp_path / "tips.csv"
    r = CliRunner().invoke(cli, ["predict", str(model_dirs["fk"]), "--joints", str(tmp_path / "joints.csv"),
                                 "--out", str(out)], env=ENV)
    assert r.exit_code == 0, r.output
    table = pd.read_csv(out)
    assert list(table.columns) == ["sequence_id", "step", *(f"pred_{p}" for p in POSES)]
    ref = Kinematics.load(model_dirs["fk"]).forward(rows[JOINTS].to_numpy(), rows["sequence_id"].to_numpy())
    np.testing.assert_allclose(table[[f"pred_{p}" for p in POSES]].to_numpy(), ref, atol=1e-5)


def test_a_joints_only_file_is_one_sequence(model_dirs, sweeps, tmp_path):
    joints = sweeps.frame[JOINTS].iloc[:6]
    joints.to_csv(tmp_path / "j.csv", index=False)
    r = CliRunner().invoke(cli, ["predict", str(model_dirs["fk"]), "--joints", str(tmp_path / "j.csv")],
                           env=ENV)
    assert r.exit_code == 0, r.output
    table = pd.read_csv(io.StringIO(r.stdout))
    assert table["step"].tolist() == list(range(6)) and "sequence_id" not in table
    ref = Kinematics.load(model_dirs["fk"]).forward(joints.to_numpy())
    np.testing.assert_allclose(table[[f"pred_{p}" for p in POSES]].to_numpy(), ref, atol=1e-5)


def test_joints_files_are_checked(model_dirs, sweeps, tmp_path):
    joints = sweeps.frame[JOINTS].iloc[:6].copy()
    joints.drop(columns=["beta_2"]).to_csv(tmp_path / "no_b2.csv", index=False)
    fk = str(model_dirs["fk"])
    r = CliRunner().invoke(cli, ["predict", fk, "--joints", str(tmp_path / "no_b2.csv")])
    assert r.exit_code == 1 and "lacks joint column(s) ['beta_2']" in r.stderr
    joints.to_csv(tmp_path / "j.csv", index=False)
    r = CliRunner().invoke(cli, ["predict", str(model_dirs["ik"]), "--joints", str(tmp_path / "j.csv")])
    assert r.exit_code == 1 and "--joints needs an FK model" in r.stderr
    r = CliRunner().invoke(cli, ["predict", fk, "--joints", str(tmp_path / "j.csv"), "--data", str(tmp_path)])
    assert r.exit_code == 2 and "either --data" in r.output


def test_every_ik_family_writes_absolute_joint_columns(model_dirs, follow_dir, sweeps, tmp_path):
    sweeps.frame[["sequence_id", "step", *POSES]].iloc[:20].to_csv(tmp_path / "targets.csv", index=False)
    folders = {"ik": model_dirs["ik"], "follow": follow_dir, "refined": model_dirs["ik_refined"]}
    for name, folder in folders.items():
        out = tmp_path / f"{name}.csv"
        r = CliRunner().invoke(cli, ["predict", str(folder), "--poses", str(tmp_path / "targets.csv"),
                                     "--out", str(out)], env=ENV)
        assert r.exit_code == 0, (name, r.output)
        table = pd.read_csv(out)
        assert [c for c in table.columns if c.startswith("pred_")] == [f"pred_{j}" for j in JOINTS], name
        kin = Kinematics.load(folder)
        ref = kin.inverse(sweeps.poses()[:20], sweeps.frame["sequence_id"].to_numpy()[:20]).joints
        np.testing.assert_allclose(table[[f"pred_{j}" for j in JOINTS]].to_numpy(), ref, atol=1e-6)
