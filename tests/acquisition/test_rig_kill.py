"""Kill test of a rig collection: `ctrkin collect --rig` (the virtual rig) interrupted by Ctrl-C
(SIGINT) and killed (SIGKILL) at moments the journal decides, then resumed by the same command,
gives the dataset of an uninterrupted run. Everything in tmp_path."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from ctrkin.data import Dataset

RIG = """name = "kill-test"
robot = "paper"
home = [0.0, 0.0, -4.0, 0.0]
[actuator]
kind = "virtual"
[tracker]
kind = "virtual"
readings = 3
registration = { rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]], translation_mm = [0, 0, 0] }
[virtual]
seed = 5
"""


def _command(rig: Path, out: Path) -> list[str]:
    return [sys.executable, "-m", "ctrkin.cli.main", "collect", "--rig", str(rig), "--protocol", "sweeps",
            "--levels", "4,12,20", "--out", str(out)]


def _env() -> dict[str, str]:
    return {**os.environ, "CTRKIN_NO_PROGRESS": "1"}


def _run_until(cmd: list[str], journal: Path, lines: int, sig: int) -> tuple[int, str]:
    """Start `cmd`, send `sig` once the journal has `lines` lines; returns the exit status and what
    the command wrote to stderr (read to the end, so a full pipe never blocks it)."""
    # SIGINT as an interactive shell leaves it (a background pytest inherits it ignored)
    p = subprocess.Popen(cmd, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 240
    try:
        while time.monotonic() < deadline and p.poll() is None:
            if journal.is_file() and journal.read_text().count("\n") >= lines:
                p.send_signal(sig)
                break
            time.sleep(0.01)
        _, err = p.communicate(timeout=60)
        return p.returncode, err.decode(errors="replace")
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()


@pytest.mark.slow
def test_interrupted_and_killed_collections_resume_to_the_uninterrupted_dataset(tmp_path):
    rig = tmp_path / "rig.toml"
    rig.write_text(RIG)
    whole = tmp_path / "whole"
    subprocess.run(_command(rig, whole), env=_env(), check=True, capture_output=True)
    out = tmp_path / "cut"
    journal = out / "readings.csv"
    # early in the 2163 samples, so that a loaded machine cannot finish before the signal lands
    status, err = _run_until(_command(rig, out), journal, 1 + 3 * 50, signal.SIGINT)
    assert status == 130, err                                  # Ctrl-C
    part = Dataset.load(out)                                   # what was recorded was kept
    assert 50 <= len(part.frame) < 2163 and not part.meta["collection"]["complete"]
    status, err = _run_until(_command(rig, out), journal, 1 + 3 * 700, signal.SIGKILL)
    assert status == -signal.SIGKILL, err
    done = subprocess.run(_command(rig, out), env=_env(), capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "resuming" in done.stderr
    a, b = Dataset.load(out), Dataset.load(whole)
    assert a.meta["collection"]["complete"] and len(a.frame) == 2163
    pd.testing.assert_frame_equal(a.frame.drop(columns=["time"]), b.frame.drop(columns=["time"]))
