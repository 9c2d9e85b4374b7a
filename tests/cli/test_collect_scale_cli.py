"""`ctrkin collect --scale`: the choices and default of `ctrkin reproduce --scale`."""

from __future__ import annotations

from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.data import Dataset


def test_scale_choices_and_default_match_reproduce() -> None:
    runner = CliRunner()
    for command in ("collect", "reproduce"):
        res = runner.invoke(cli, [command, "--help"])
        assert res.exit_code == 0
        text = " ".join(res.output.split())
        assert "--scale [full|quick|tiny]" in text and "default: quick" in text, command


def test_tiny_is_the_data_of_reproduce_tiny(tmp_path) -> None:
    out = tmp_path / "tiny"
    res = CliRunner().invoke(cli, ["collect", "--protocol", "paper", "--scale", "tiny", "--workers", "1",
                                   "--out", str(out)], env={"CTRKIN_NO_PROGRESS": "1"})
    assert res.exit_code == 0, res.output
    ds = Dataset.load(out)
    assert len(ds.frame) == 2 * 4 * 721          # as tests/evaluation/test_reproduce.py: 2 levels × 4 angles
    assert ds.meta["protocol_params"]["levels_mm"] == [4.0, 20.0]
