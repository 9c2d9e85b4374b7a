"""Issue 23 item 2: `ctrkin export` exports what `predict` runs or refuses with the reason, and its
summary lists every input and output of the graph (a snap-aware FK's `state` included)."""

from __future__ import annotations

import onnx
import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.errors import ModelError
from ctrkin.inference import Kinematics, export_onnx
from ctrkin.training import TrainConfig, train


def test_the_plain_fk_exports_with_every_input_and_output_listed(model_dirs, tmp_path):
    out = tmp_path / "fk.onnx"
    r = CliRunner().invoke(cli, ["export", str(model_dirs["fk"]), "--out", str(out)])
    assert r.exit_code == 0, r.output
    graph = onnx.load(str(out)).graph
    for v in [*graph.input, *graph.output]:
        assert f"{v.name} (" in r.output
    assert "warning" not in r.output


def test_a_fold_gated_fk_is_refused_unless_the_downgrade_is_asked_for(model_dirs, tmp_path):
    folder = str(model_dirs["fk_branch"])
    assert Kinematics.load(folder).fold_gate is not None          # predict's default gate is the fold gate
    r = CliRunner().invoke(cli, ["export", folder, "--out", str(tmp_path / "b.onnx")])
    assert r.exit_code == 1 and "fold gate" in r.stderr and "--allow-downgrade" in r.stderr
    assert not (tmp_path / "b.onnx").exists()
    r = CliRunner().invoke(cli, ["export", folder, "--out", str(tmp_path / "b.onnx"), "--allow-downgrade"])
    assert r.exit_code == 0, r.output
    assert "state (batch)" in r.output and "state_out (batch)" in r.output and "window (batch," in r.output
    assert "warning: exported the network alone" in r.output


def test_the_refined_and_follow_iks_are_refused_with_the_reason(model_dirs, sweeps, tmp_path):
    r = CliRunner().invoke(cli, ["export", str(model_dirs["ik_refined"]), "--out", str(tmp_path / "r.onnx")])
    assert r.exit_code == 1 and "refinement" in r.stderr and "--allow-downgrade" in r.stderr
    r = CliRunner().invoke(cli, ["export", str(model_dirs["ik_refined"]), "--out", str(tmp_path / "r.onnx"),
                                 "--allow-downgrade"])
    assert r.exit_code == 0 and "direct IK network alone" in r.output
    follow = tmp_path / "follow"
    train(sweeps, TrainConfig(task="ik", model="follow_mlp", max_epochs=1, threads=1,
                              options={"structure": "|D8"}), follow, progress=False)
    r = CliRunner().invoke(cli, ["export", str(follow), "--out", str(tmp_path / "f.onnx"),
                                 "--allow-downgrade"])
    assert r.exit_code == 1 and "cannot be exported" in r.stderr and "Kinematics.step" in r.stderr
    with pytest.raises(ModelError, match="fold gate"):
        export_onnx(Kinematics.load(model_dirs["fk_branch"]), tmp_path / "lib.onnx")
