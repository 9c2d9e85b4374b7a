"""Exit status and messages: 0 done, 1 a domain error (one line on stderr), 2 a usage error; --quiet."""

from __future__ import annotations

import os
import subprocess
import sys

import pandas as pd
from click.testing import CliRunner

from ctrkin.cli.main import cli


def test_the_console_script_prints_one_line_and_no_traceback(tmp_path) -> None:
    env = {**os.environ, "CTRKIN_NO_PROGRESS": "1"}
    run = subprocess.run([sys.executable, "-m", "ctrkin.cli.main", "solve", "--q", "0,0,5,-5"],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert run.returncode == 1 and run.stdout == ""
    assert run.stderr.startswith("Error: ") and "beta_1 <= beta_2" in run.stderr
    assert "Traceback" not in run.stderr and len(run.stderr.strip().splitlines()) == 1


def test_domain_errors_exit_1() -> None:
    runner = CliRunner()
    for args, words in ((["solve", "--robot", "nosuch.toml", "--q", "0,0,-15,-5"], "does not exist"),
                        (["solve", "--q", "0,0,-15"], "2N = 4"),
                        (["dataset", "info", "."], "not a ctrkin dataset")):
        res = runner.invoke(cli, args)
        assert res.exit_code == 1 and words in res.stderr, (args, res.output)


def test_usage_errors_exit_2() -> None:
    runner = CliRunner()
    for args in (["solve"], ["solve", "--q", "0,x"], ["collect", "--protocol", "nope", "--out", "x"],
                 ["no-such-command"]):
        res = runner.invoke(cli, args)
        assert res.exit_code == 2, (args, res.output)


def test_quiet_keeps_results_and_drops_messages(tmp_path, monkeypatch) -> None:
    monkeypatch.delenv("CTRKIN_NO_PROGRESS", raising=False)     # --quiet alone turns progress off
    runner = CliRunner()
    res = runner.invoke(cli, ["--quiet", "solve", "--q", "0,0,-15,-5"])
    assert res.exit_code == 0 and "tip position (mm)" in res.stdout       # the result itself stays
    out = tmp_path / "sw"
    res = runner.invoke(cli, ["--quiet", "sweep", "--translations", "4", "--step", "90", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert res.output == ""
    assert len(pd.read_csv(out / "sweep.csv")) == 9
    res = runner.invoke(cli, ["sweep", "--translations", "4", "--step", "90", "--out", str(out),
                              "--overwrite"])
    assert res.exit_code == 0 and "wrote" in res.stdout and "sweeps: 9/9" in res.stderr    # progress lines


def test_quiet_does_not_leak_into_the_environment() -> None:
    before = os.environ.get("CTRKIN_NO_PROGRESS")
    assert CliRunner().invoke(cli, ["-q", "solve", "--q", "0,0,-15,-5"]).exit_code == 0
    assert os.environ.get("CTRKIN_NO_PROGRESS") == before


def test_help_documents_quiet_progress_and_exit_status() -> None:
    text = " ".join(CliRunner().invoke(cli, ["--help"]).output.split())
    for words in ("--quiet", "CTRKIN_NO_PROGRESS=1", "Exit status: 0 done; 1", "2 a usage error"):
        assert words in text
