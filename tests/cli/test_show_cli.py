"""`ctrkin show`: shapes to PNG, sweeps to GIF, with the snaps the continuation finds."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from ctrkin import follow, paper_robot, solve
from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.cli.main import cli
from ctrkin.viz.animation import frame_steps

ENV = {"CTRKIN_NO_PROGRESS": "1"}


def _run(args: list[str]) -> tuple[int, str]:
    """Exit status and stdout (stdout and stderr together where the command failed)."""
    res = CliRunner().invoke(cli, args, env=ENV)
    return res.exit_code, res.stdout if res.exit_code == 0 else res.output


def test_one_shape_to_png(tmp_path) -> None:
    out = tmp_path / "shape.png"
    code, text = _run(["show", "--q", "0,0,-15,-5", "--out", str(out), "--json"])
    assert code == 0, text
    summary = json.loads(text)
    assert summary["steps"] == 1 and summary["snaps"] == 0
    np.testing.assert_allclose(summary["tip_mm"], solve(paper_robot(), [0, 0, -15, -5]).tip_position)
    with Image.open(out) as im:
        assert im.format == "PNG" and im.size[0] > 500
    code, text = _run(["show", "--q", "0,0,-15,-5", "--out", str(out)])
    assert code == 1 and "--overwrite" in text


def test_a_path_through_a_snap_is_followed_with_its_history(tmp_path) -> None:
    """0 -> 360° at full overlap: the continuation snaps once on the way (at α0 ≈ 207°)."""
    code, text = _run(["show", "--q", "0,0,-20,0", "--q", "360,0,-20,0", "--out", str(tmp_path / "p.png"),
                       "--json"])
    assert code == 0, text
    summary = json.loads(text)
    assert summary["steps"] == 361 and summary["snaps"] == 1
    assert 190 <= summary["snap_steps"][0] <= 220
    assert (tmp_path / "p.png").stat().st_size > 10_000


def test_sweep_animation_shows_the_snap_frames(tmp_path) -> None:
    out = tmp_path / "sweep.gif"
    code, text = _run(["show", "--sweep", "d=20,step=10", "--frames", "4", "--out", str(out), "--json"])
    assert code == 0, text
    summary = json.loads(text)
    robot = paper_robot()
    trajectory = follow(robot, rotation_sweep(2, 20.0, step_deg=10.0))
    assert summary["steps"] == 73 and summary["snap_steps"] == np.flatnonzero(trajectory.snaps).tolist()
    assert summary["snaps"] == 2                      # one fold each way
    shown = frame_steps(73, trajectory.snaps, 4)
    assert set(summary["snap_steps"]) <= set(shown.tolist())
    with Image.open(out) as im:
        assert im.format == "GIF" and im.n_frames == len(shown)


def test_frame_steps() -> None:
    snaps = np.zeros(100, bool)
    snaps[[40, 41, 77]] = True
    steps = frame_steps(100, snaps, 5)
    assert steps.tolist() == [0, 25, 39, 40, 41, 50, 74, 76, 77, 99]
    with pytest.raises(ValueError):
        frame_steps(100, snaps, 1)


@pytest.mark.parametrize(("args", "message"), [
    (["--q", "0,0,-15,-5", "--sweep", "d=20"], "not both"),
    ([], "not both"),
    (["--sweep", "outer=20"], "d=20"),
    (["--sweep", "d=20,speed=3"], "KEY=VALUE"),
    (["--sweep", "d=twenty"], "not a number"),
    (["--q", "0,0,-15,-5", "--out", "shape.jpg"], ".png, .gif or .mp4"),
    (["--sweep", "d=20", "--frames", "1", "--out", "s.gif"], "at least 2 frames"),
])
def test_usage_errors(args, message, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, text = _run(["show", *args])
    assert code == 2 and message in " ".join(text.split()), text


def test_invalid_joints_are_refused(tmp_path) -> None:
    code, text = _run(["show", "--q", "0,0,5,-5", "--out", str(tmp_path / "x.png")])
    assert code == 1 and "Error" in text
    assert not (tmp_path / "x.png").exists()
