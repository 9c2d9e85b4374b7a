"""`ctrkin evaluate` labels what a predictor knew of each row, agrees with `ctrkin train` on the same
rows, runs leave-one-sequence-out for calibrated robots and learned models, warns about joints the
held-out rows move that training never moved, and draws its figures. Small data written here."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ctrkin.acquisition import protocols
from ctrkin.acquisition.plan import Plan, Run, Segment
from ctrkin.acquisition.recorder import record
from ctrkin.cli.main import cli
from ctrkin.data import Dataset
from ctrkin.data.splits import Split, joint_coverage
from ctrkin.evaluation.real import HELD_OUT, IN_SAMPLE_CAL, IN_SAMPLE_REG, TEST, TRAIN, VAL, evaluate, loso
from ctrkin.robots import paper_robot
from ctrkin.virtual import VirtualConfig, VirtualRobot


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    """Four sequences of the paper protocol (two runs, outer tube at 0° and 180°), 25 samples each in
    30° steps, and a fifth turning the inner tube in 90° steps (larger than any step training saw);
    test = sequences 1 and 4, validation = 3, training = 0 and 2 (outer tube at 0°)."""
    robot = paper_robot()
    paper = protocols.paper(robot, scale="quick", levels=(4.0, 20.0), step_deg=30.0, outer_step_deg=180.0)
    coarse = Run((Segment(protocols.inner_turn(2, 0.0, 0.0, 12.0, step_deg=90.0)),))
    plan = Plan("test", (*paper.runs, coarse), paper.levels)
    ds = record(plan, VirtualRobot(robot, VirtualConfig(glitch_rate=0.0), seed=0), seed=0, workers=1,
                progress=False)
    sid = ds.frame["sequence_id"].to_numpy()
    ds.split = Split(np.nonzero(np.isin(sid, [0, 2]))[0], np.nonzero(sid == 3)[0],
                     np.nonzero(np.isin(sid, [1, 4]))[0], kind="sequence", seed=0,
                     fractions=(0.5, 0.25, 0.25), n_rows=len(sid))
    folder = tmp_path_factory.mktemp("eval") / "data"
    ds.save(folder)
    return folder


@pytest.fixture(scope="module")
def model(data: Path) -> Path:
    out = data.parent / "fk"
    r = CliRunner().invoke(cli, ["train", "--task", "fk", "--model", "lstm_mlp",
                                 "--data", str(data), "--out", str(out),
                                 "--epochs", "3", "--threads", "1", "--angles", "sincos"])
    assert r.exit_code == 0, r.output
    return out


def test_a_learned_models_parts_are_its_split_and_agree_with_train(data, model):
    ds = Dataset.load(data)
    res = evaluate(ds, str(model))
    assert list(res["per_part"]) == [TRAIN, VAL, TEST]
    assert [res["per_part"][p]["samples"] for p in (TRAIN, VAL, TEST)] == [50, 25, 34]
    trained = json.loads((model / "metrics.json").read_text())
    # the same rows, the same inputs (steps clipped to the trained range in both): equal up to the
    # float32 rounding of the network's input
    for part, key in ((TEST, "test"), (VAL, "val")):
        got, want = res["per_part"][part], trained[key]["vs_measured"]
        assert got["position_mean_mm"] == pytest.approx(want["position_mm_mae"], rel=1e-6)
        assert got["position_rmse_mm"] == pytest.approx(want["position_mm_rmse"], rel=1e-6)
    assert res["per_sequence"]["1"]["parts"] == [TEST]
    # the held-out sequence turns the outer tube to 180°, which training never did
    assert any("alpha_2 never moved in training (always 0 deg)" in w for w in res["warnings"])


def test_calibrated_robot_is_in_sample_on_its_own_data_and_held_out_elsewhere(data, tmp_path):
    cal = tmp_path / "cal.toml"
    r = CliRunner().invoke(cli, ["calibrate", "--data", str(data), "--out", str(cal), "--fit",
                                 "registration,precurvature", "--max-evaluations", "4"])
    assert r.exit_code == 0, r.output
    ds = Dataset.load(data)
    assert list(evaluate(ds, str(cal))["per_part"]) == [IN_SAMPLE_CAL]
    assert list(evaluate(ds, "tcm")["per_part"]) == [IN_SAMPLE_REG]
    other = Dataset(frame=ds.frame.assign(x=ds.frame["x"] + 0.5), robot=ds.robot, meta={})
    other.save(tmp_path / "other")
    assert list(evaluate(Dataset.load(tmp_path / "other"), str(cal))["per_part"]) == [HELD_OUT]


def test_loso_for_a_calibration_and_for_a_learned_model(data, model, tmp_path):
    ds = Dataset.load(data)
    tcm = loso(ds, "tcm", tmp_path)
    assert set(tcm["per_sequence"]) == {"0", "1", "2", "3", "4"} and "registration" in tcm["how"]
    assert all(np.isfinite(v) and v > 0 for v in tcm["per_sequence"].values())
    learned = loso(ds, str(model), tmp_path, max_epochs=2)
    assert set(learned["per_sequence"]) == {"0", "1", "2", "3", "4"} and "retrained" in learned["how"]
    assert (tmp_path / "loso_3" / "weights.pt").is_file()
    sizes = np.array([25, 25, 25, 25, 9])
    assert learned["mean_mm"] == pytest.approx(np.average(list(learned["per_sequence"].values()),
                                                          weights=sizes))


def test_evaluate_cli_names_folders_and_draws_labelled_figures(data, model, tmp_path):
    out = tmp_path / "eval"
    r = CliRunner().invoke(cli, ["evaluate", "--data", str(data), "--predictor", str(model), "--predictor",
                                 "tcm", "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert "held out (test)" in r.output and "all rows (mixes the parts above)" in r.output
    assert "in-sample (registration fitted here)" in r.output
    assert "alpha_2 never moved in training" in r.output
    for sub in ("fk", "tcm"):
        assert sorted(p.name for p in (out / sub).iterdir()) == [
            "error_by_sequence.png", "error_vs_joints.png", "results.json", "tips.png"]


def test_joint_coverage_names_the_joint_and_its_ranges():
    train = np.array([[0.0, 5.0, -10.0, 0.0], [30.0, 5.0, -10.0, 0.0]])
    held = np.array([[10.0, 5.0, -12.0, 0.0], [20.0, 5.0, -8.0, 0.0]])
    out = joint_coverage(train, held, ["alpha_1", "alpha_2", "beta_1", "beta_2"])
    assert out == ["beta_1 never moved in training (always -10 mm) but the held-out rows take it over "
                   "[-12, -8] mm: its effect is unknown to the model there"]
    assert joint_coverage(train, train, ["alpha_1", "alpha_2", "beta_1", "beta_2"]) == []


def test_dataset_split_val_rows_is_the_benchmarks_split(data, tmp_path):
    ds = Dataset.load(data)
    copy = tmp_path / "copy"
    ds.split = None
    ds.save(copy)
    r = CliRunner().invoke(cli, ["dataset", "split", str(copy), "--test", "1", "--val-rows", "0.2"])
    assert r.exit_code == 0, r.output
    split = Dataset.load(copy).split
    sid = ds.frame["sequence_id"].to_numpy()
    assert set(sid[split.test]) == {1} and len(split.val) == round(0.2 * (109 - 25))
    assert set(sid[split.val]) <= {0, 2, 3, 4} and len(set(sid[split.val])) > 1    # rows from several files
    r = CliRunner().invoke(cli, ["dataset", "split", str(copy), "--val-rows", "0.2"])
    assert r.exit_code == 2 and "--val-rows needs --test" in r.output
