"""`ctrkin show`: the robot's 3-D shape (PNG) or an animated sweep with its snaps (GIF/MP4).

    ctrkin show --q 0,0,-15,-5                                 # one shape -> shape.png
    ctrkin show --q 0,0,-20,0 --q 200,0,-20,0 --out path.png   # a path, followed with its history
    ctrkin show --sweep d=20 --out sweep.gif                   # inner tube 0 -> 360 -> 0 deg at d = 20 mm
    ctrkin show --sweep d=20,outer=90 --out sweep.png          # the same sweep as a still
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click
import numpy as np

from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.cli.common import ROBOT_HELP, emit_json, output_file, output_options, parse_floats, say
from ctrkin.cli.from_config import config_options, option
from ctrkin.mechanics import follow
from ctrkin.robots import load_robot

SWEEP_KEYS = {"d": "relative translation d = βN − β1 (mm)", "outer": "the other tubes' α (deg)",
              "beta_outer": "the other tubes' β (mm)", "step": "inner rotation step (deg)"}
PATH_STEP = (1.0, 0.1)   # deg, mm: a path between --q configurations is followed in these steps
STILL_SHAPES = 8         # shapes drawn along a path in a still image


def parse_sweep(text: str) -> dict[str, float]:
    """`d=20,outer=90` -> {"d": 20.0, "outer": 90.0, ...} with the defaults of the rest."""
    out = {"outer": 0.0, "beta_outer": 0.0, "step": 1.0}
    for item in filter(None, (part.strip() for part in text.split(","))):
        key, sep, value = item.partition("=")
        if not sep or key.strip() not in SWEEP_KEYS:
            raise click.BadParameter(f"{item!r}: give KEY=VALUE with KEY one of {', '.join(SWEEP_KEYS)}",
                                     param_hint="--sweep")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            raise click.BadParameter(f"{item!r}: {value!r} is not a number", param_hint="--sweep") from None
    if "d" not in out:
        raise click.BadParameter("give the relative translation, e.g. --sweep d=20", param_hint="--sweep")
    if out["step"] <= 0:
        raise click.BadParameter("step must be > 0 deg", param_hint="--sweep")
    return out


def _path(configs: list[list[float]], n_tubes: int) -> tuple[np.ndarray, np.ndarray]:
    """Joints through the given configurations in steps of ≤ 1°/0.1 mm, and where each one is."""
    from ctrkin.acquisition.plan import move

    rows, marks = [np.asarray(configs[0], float)[None]], [0]
    for a, b in itertools.pairwise(configs):
        seg = move(np.asarray(a, float), np.asarray(b, float), n_tubes, *PATH_STEP)
        rows.append(seg)
        marks.append(marks[-1] + len(seg))
    return np.vstack(rows), np.array(marks)


@dataclass(frozen=True)
class ShowConfig:
    """What `ctrkin show` draws (one option per field)."""

    robot: str = option(ROBOT_HELP, "paper")
    q: tuple[str, ...] = option(
        "Joints α1..αN (deg), β1..βN (mm), comma-separated (repeat for a path: it is followed by "
        "continuation in 1°/0.1 mm steps, with its history and snaps).", (), repeat=True, metavar="JOINTS")
    sweep: str | None = option(
        "The inner tube turning 0 -> 360 -> 0° at relative translation d (paper Fig. 2b), the other tubes "
        "at α = outer, β = beta_outer.", None, metavar="d=MM[,outer=DEG,beta_outer=MM,step=DEG]")
    out: str | None = option(
        "Output: .png (a still), .gif or .mp4 (an animation; .mp4 needs ffmpeg). Default: shape.png for "
        "--q, sweep.gif for --sweep.", None, path="out_file")
    frames: int | None = option(
        "Animation: about how many steps to show (default 120; snap steps always). Still image of a path: "
        f"shapes drawn along it (default {STILL_SHAPES}).", None, range=(1, None))
    spacing: float = option("Largest distance between drawn backbone points (mm).", 0.5, range=(0.01, None))


@click.command("show", epilog="""\b
Examples:
  ctrkin show --q 0,0,-15,-5
  ctrkin show --q 0,0,-20,0 --q 200,0,-20,0 --out path.png
  ctrkin show --sweep d=20 --out sweep.gif
  ctrkin show --sweep d=20,outer=90,step=2 --frames 60 --out sweep.gif""")
@config_options(ShowConfig)
@output_options
def show_cmd(overwrite: bool, as_json: bool, **settings: Any) -> None:
    """Draw the robot's 3-D shape (tubes with their diameters, the tip's path, snaps marked), or
    animate a sweep with its snap."""
    cfg = ShowConfig(**settings)
    robot_spec, q_texts, sweep_text, out_file = cfg.robot, cfg.q, cfg.sweep, cfg.out
    frames, spacing = cfg.frames, cfg.spacing
    if bool(q_texts) == bool(sweep_text):
        raise click.UsageError("give --q (one or more configurations) or --sweep, not both")
    robot = load_robot(robot_spec)
    n = robot.n_tubes
    if sweep_text:
        sw = parse_sweep(sweep_text)
        Q = rotation_sweep(n, sw["d"], sw["beta_outer"], sw["outer"], sw["step"])
        marks = np.arange(0, len(Q))
        what = f"inner sweep at d = {sw['d']:g} mm, outer α = {sw['outer']:g}°"
        default = "sweep.gif"
    else:
        configs = [parse_floats(t, "--q") for t in q_texts]
        for c in configs:
            robot.check_joints(np.asarray(c, float))
        Q, marks = _path(configs, n)
        what = "1 configuration" if len(configs) == 1 else f"a path through {len(configs)} configurations"
        default = "shape.png"
    robot.check_joints(Q)
    target = Path(out_file or default)
    suffix = target.suffix.lower()
    if suffix not in (".png", ".gif", ".mp4"):
        raise click.BadParameter(f"{target}: write a .png, .gif or .mp4", param_hint="--out")
    if suffix != ".png":
        from ctrkin.viz.animation import writer_for

        try:
            writer_for(target)
        except ValueError as e:
            raise click.BadParameter(str(e), param_hint="--out") from None
        if frames is not None and frames < 2:
            raise click.BadParameter("an animation needs at least 2 frames", param_hint="--frames")
    out = output_file(target, "figure", overwrite, inputs=[robot_spec])
    trajectory = follow(robot, Q)
    snaps = np.flatnonzero(trajectory.snaps)
    if suffix == ".png":
        from ctrkin.viz.shape import plot_shape

        count = min(frames or STILL_SHAPES, len(marks))
        shown = marks[np.round(np.linspace(0, len(marks) - 1, count)).astype(int)]
        plot_shape(robot, [trajectory.equilibria[t] for t in shown], out, spacing=spacing,
                   snaps=trajectory.snaps if len(Q) > 1 else None,
                   tips=trajectory.tip_poses[:, :3] if len(Q) > 1 else None)
    else:
        from ctrkin.viz.animation import animate_path

        animate_path(robot, Q, trajectory, out, frames=frames or 120, spacing=spacing,
                     title=f"{robot.name}: {what}")
    say(f"{what}: {len(Q)} steps, {len(snaps)} snap(s)"
        + (f" at steps {snaps.tolist()}" if len(snaps) else "") + f"; wrote {out}")
    if as_json:
        emit_json({"robot": robot.name, "steps": len(Q), "snaps": len(snaps), "snap_steps": snaps.tolist(),
                   "tip_mm": trajectory.tip_poses[-1, :3].tolist(), "out": out})
