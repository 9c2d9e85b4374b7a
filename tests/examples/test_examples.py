"""Every script in examples/ runs, at a tiny size, and its figures make sense.

The scripts run in this process (runpy, their `main(argv)`), in the order a reader takes them: the
recording feeds the training, the trained model the control loop. The whole file takes ~30-60 s on
the two-core development machine.
"""

from __future__ import annotations

import runpy
from pathlib import Path
from typing import Any

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
SCRIPTS = ("solve_and_sweep.py", "record_virtual_robot.py", "train_and_stream.py", "control_loop.py",
           "import_log.py")


def run(script: str, *args: str) -> Any:
    return runpy.run_path(str(EXAMPLES / script), run_name="example")["main"](list(args))


def test_every_example_is_tested() -> None:
    assert sorted(p.name for p in EXAMPLES.glob("*.py")) == sorted(SCRIPTS)


def test_solve_and_sweep(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = run("solve_and_sweep.py", "--step", "5", "--plot", str(tmp_path / "sweep.png"))
    assert len(out["snap_steps"]) == 2                 # d = 20 mm: one snap each way
    assert out["steps"] == 145 and (tmp_path / "sweep.png").stat().st_size > 10_000
    assert run("solve_and_sweep.py", "--d", "8", "--step", "10")["snap_steps"] == []
    assert "snap forward at α1" in capsys.readouterr().out


def test_record_train_stream_and_control_loop(tmp_path: Path) -> None:
    data, model = tmp_path / "sweeps", tmp_path / "fk"
    rec = run("record_virtual_robot.py", "--levels", "4,12,20", "--out", str(data))
    assert rec["samples"] == 3 * 721 and rec["snap_samples"] >= 2
    assert rec["position_mean_mm_vs_true"] < rec["position_mean_mm_vs_measured"]
    trained = run("train_and_stream.py", "--data", str(data), "--out", str(model), "--epochs", "2")
    assert trained["epochs"] == 2 and trained["steps"] == 721
    assert trained["stream_vs_batch"] < 1e-4          # streaming equals batch (mm, quaternion)
    assert np.isfinite(trained["rmse_mm"])
    loop = run("control_loop.py", "--model", str(model), "--rate", "200", "--seconds", "0.5")
    assert loop["ticks"] == 100 and np.isfinite(loop["tip_error_mm_mean"])
    assert loop["step_us_median"] < 5_000               # far below the 5 ms period


def test_import_log(tmp_path: Path) -> None:
    out = run("import_log.py", "--demo", "--out", str(tmp_path / "mylog"))
    assert out["samples"] == 4 * 30 and out["sequences"] == 4
    assert out["noise_mm"] is not None and np.max(out["noise_mm"]) < 0.05     # the log's 0.02 mm
    with pytest.raises(SystemExit):
        run("import_log.py", "--out", str(tmp_path / "x"))                  # neither a log nor --demo
