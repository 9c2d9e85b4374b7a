"""`ctrkin reproduce` arguments (the pipeline itself is tested in tests/evaluation)."""

from __future__ import annotations

from click.testing import CliRunner

from ctrkin.cli.main import cli


def test_help_lists_scales() -> None:
    res = CliRunner().invoke(cli, ["reproduce", "--help"])
    assert res.exit_code == 0
    for word in ("quick", "full", "tiny", "--out", "--workers", "--executor", "RAY_ADDRESS"):
        assert word in res.output


def test_unknown_scale_is_refused() -> None:
    res = CliRunner().invoke(cli, ["reproduce", "--scale", "huge"])
    assert res.exit_code == 2 and "huge" in res.output


def test_malformed_robot_file_is_refused(tmp_path) -> None:
    bad = tmp_path / "robot.toml"
    bad.write_text("[[tubes]]\nod = 1\n")
    res = CliRunner().invoke(cli, ["reproduce", "--robot", str(bad), "--out", str(tmp_path / "o")])
    assert res.exit_code == 1 and "missing field" in res.stderr
    assert not (tmp_path / "o" / "results.json").exists()
