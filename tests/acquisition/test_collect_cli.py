"""`ctrkin collect` end to end at a small scale."""

from __future__ import annotations

from click.testing import CliRunner

from ctrkin.acquisition.task_paths import load_targets
from ctrkin.cli.main import cli
from ctrkin.data import Dataset


def test_collect_arbitrary_writes_a_dataset(tmp_path, monkeypatch):
    monkeypatch.setenv("CTRKIN_NO_PROGRESS", "1")
    out = tmp_path / "arb"
    res = CliRunner().invoke(cli, ["collect", "--protocol", "arbitrary", "--seed", "3",
                                   "--set", "glitch_rate=0", "--out", str(out)])
    assert res.exit_code == 0, res.output
    ds = Dataset.load(out)
    assert len(ds.frame) == 361 and not ds.frame["outlier"].any()
    assert ds.meta["virtual_robot"]["config"]["glitch_rate"] == 0.0
    assert ds.meta["seed"] == 3


def test_collect_square_writes_targets(tmp_path):
    res = CliRunner().invoke(cli, ["collect", "--protocol", "square", "--out", str(tmp_path / "sq")])
    assert res.exit_code == 0, res.output
    poses, meta = load_targets(tmp_path / "sq")
    assert poses.shape == (10, 6) and meta["shape"] == "square"


def test_bad_setting_is_a_usage_error(tmp_path):
    res = CliRunner().invoke(cli, ["collect", "--protocol", "sweeps", "--set", "noise_mm=-1",
                                   "--out", str(tmp_path / "x")])
    assert res.exit_code == 2
    assert "noise_mm" in res.output
