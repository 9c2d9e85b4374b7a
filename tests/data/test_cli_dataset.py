"""`ctrkin dataset import | info | split` through click's CliRunner."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.data import Dataset
from tests.data.conftest import readings


@pytest.fixture
def log_csv(tmp_path, sweep):
    q, poses = sweep
    log = readings(q, poses, n_readings=5, noise_mm=0.02, seed=1)
    log.loc[5 * 30: 5 * 30 + 4, "alpha_1"] += 90.0  # one encoder glitch
    log = log.rename(columns={"alpha_1": "rot_in", "beta_1": "lin_in"})
    log["rot_in"] = np.radians(log["rot_in"])
    log[["lin_in", "beta_2", "x", "y", "z"]] /= 1000.0
    log["alpha_2"] = np.radians(log["alpha_2"])
    path = tmp_path / "log.csv"
    log.to_csv(path, index=False, float_format="%.17g")
    return path


def _import(runner, log_csv, out, *extra):
    return runner.invoke(cli, ["dataset", "import", str(log_csv), "--robot", "paper", "--out", str(out),
                               "--map", "rot_in=alpha_1,lin_in=beta_1", "--units", "rad,m", *extra])


def test_import_info_split(tmp_path, log_csv, sweep):
    runner = CliRunner()
    out = tmp_path / "ds"
    res = _import(runner, log_csv, out)
    assert res.exit_code == 0, res.output
    assert "joint_glitches" in res.output and "144" in res.output
    ds = Dataset.load(out)
    assert len(ds.frame) == len(sweep[0]) - 1
    np.testing.assert_allclose(ds.frame["beta_1"], -12.0)

    res = runner.invoke(cli, ["dataset", "info", str(out)])
    assert res.exit_code == 0, res.output
    for text in ("paper", "import", "samples", "144", "alpha_1", "deg", "position_std_mm", "snaps"):
        assert text in res.output
    res = runner.invoke(cli, ["dataset", "info", str(out), "--json"])
    summary = json.loads(res.output)
    assert summary["samples"] == 144 and summary["cleaning"]["joint_glitches"] == 1
    assert summary["ranges"]["beta_1"] == {"min": -12.0, "max": -12.0, "mean": -12.0, "unit": "mm"}
    assert summary["split"] is None

    res = runner.invoke(cli, ["dataset", "split", str(out), "--kind", "random", "--seed", "5"])
    assert res.exit_code == 0, res.output
    assert "train 101, val 22, test 21" in res.output
    split = Dataset.load(out).split
    assert split is not None and (split.kind, split.seed) == ("random", 5)
    summary = json.loads(runner.invoke(cli, ["dataset", "info", str(out), "--json"]).output)
    assert summary["split"]["train"] == 101


def test_import_refuses_to_overwrite_without_overwrite(tmp_path, log_csv):
    runner = CliRunner()
    out = tmp_path / "ds"
    assert _import(runner, log_csv, out).exit_code == 0
    res = _import(runner, log_csv, out)
    assert res.exit_code == 1 and "exists; pass --overwrite" in res.output
    res = _import(runner, log_csv, out, "--overwrite", "--keep-outliers")
    assert res.exit_code == 0, res.output
    assert Dataset.load(out).frame["outlier"].sum() == 1
    res = _import(runner, log_csv, out, "--force")          # the old flag name still works, with a warning
    assert res.exit_code == 0, res.output
    assert "--force is deprecated; use --overwrite" in res.output
    assert Dataset.load(out).frame["outlier"].sum() == 0


def test_import_errors_reach_the_user(tmp_path, log_csv):
    runner = CliRunner()
    res = runner.invoke(cli, ["dataset", "import", str(log_csv), "--out", str(tmp_path / "ds"),
                              "--units", "rad,m"])
    assert res.exit_code == 1          # a DatasetError: one line on stderr, no traceback
    assert "Error: " in res.stderr and "missing column(s) for ['alpha_1', 'beta_1']" in res.stderr
    res = _import(runner, log_csv, tmp_path / "ds", "--map", "oops")
    assert res.exit_code == 2 and "expected LOG_COLUMN=FIELD" in res.output
    res = _import(runner, log_csv, tmp_path / "ds", "--units", "furlong")
    assert res.exit_code == 2 and "use deg|rad, mm|m" in res.output
    assert not (tmp_path / "ds").exists()


def test_split_by_sequence_with_fractions(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    runner = CliRunner()
    res = runner.invoke(cli, ["dataset", "split", str(folder), "--seed", "2", "--fractions", "0.6,0.2,0.2"])
    assert res.exit_code == 0, res.output
    split = Dataset.load(folder).split
    assert split is not None and split.kind == "sequence" and split.fractions == (0.6, 0.2, 0.2)
    sid = small_dataset.frame["sequence_id"].to_numpy()
    assert not set(sid[split.train]) & set(sid[split.test])
    res = runner.invoke(cli, ["dataset", "split", str(folder), "--fractions", "0.6,0.4"])
    assert res.exit_code == 2 and "three fractions needed" in res.output
    res = runner.invoke(cli, ["dataset", "split", str(folder), "--fractions", "0.6,0.3,0.3"])
    assert res.exit_code == 1 and "summing to 1" in res.stderr


def test_info_reports_measurement_error_against_truth(tmp_path, small_dataset):
    for c in ("x", "y", "z", "q0", "qx", "qy"):
        small_dataset.frame[f"true_{c}"] = small_dataset.frame[c]
    small_dataset.frame["true_x"] += 0.3
    small_dataset.meta["virtual_robot"] = {"config": {"noise_mm": 0.25, "readings_per_sample": 5}}
    folder = small_dataset.save(tmp_path / "ds")
    res = CliRunner().invoke(cli, ["dataset", "info", str(folder), "--json"])
    noise = json.loads(res.output)["noise"]
    assert noise["measured_vs_true_position_rms_mm"] == pytest.approx(0.3)
    assert noise["measured_vs_true_tangent_rms_deg"] == pytest.approx(0.0, abs=1e-6)
    assert (noise["noise_mm"], noise["readings_per_sample"]) == (0.25, 5)
    assert json.loads(res.output)["ranges"]["true_x"]["unit"] == "mm"
