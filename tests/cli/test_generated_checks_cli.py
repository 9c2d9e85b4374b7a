"""The checks of commands generated from their configurations (ctrkin.cli.from_config) refuse what
their hand-written options refused: a usage error (exit status 2) naming the option, before any
work or any output folder."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli


@pytest.mark.parametrize(("args", "words"), [
    (["collect", "--protocol", "random-points", "--n-points", "0"], "--n-points"),
    (["collect", "--protocol", "random-points", "--n-points", "100001"], "--n-points"),
    (["collect", "--protocol", "square", "--n-points", "3"], "a square needs at least 4 points"),
    (["collect", "--protocol", "triangle", "--n-points", "2"], "a triangle needs at least 3 points"),
    (["collect", "--protocol", "paper", "--n-points", "5"], "--n-points applies to random-points"),
    (["collect", "--protocol", "arbitrary", "--levels", "4"], "--levels applies to the paper and sweeps"),
    (["sweep", "--step", "0"], "--step"),
    (["sweep", "--step", "361"], "--step"),
    (["sweep", "--translations", ","], "at least one relative translation"),
])
def test_a_generated_command_refuses_bad_values(tmp_path, args, words) -> None:
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, [*args, "--out", str(out)])
    assert res.exit_code == 2, res.output
    assert words in " ".join(res.output.split())
    assert not out.exists()
