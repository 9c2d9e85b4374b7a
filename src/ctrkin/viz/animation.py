"""Animation of a joint path followed by continuation: the robot's 3-D shape step by step beside
T(L), with the snaps marked where they happen (`ctrkin show --sweep`).

GIF (matplotlib's pillow writer, always available) or MP4 (ffmpeg, where installed).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib import animation

from ctrkin.mechanics.continuation import Trajectory
from ctrkin.mechanics.shape import dense_backbone
from ctrkin.robots.robot import Robot
from ctrkin.viz.shape import SNAP, TRACE, draw_front_plate, draw_robot, set_equal_aspect

FORMATS = {".gif": "pillow", ".mp4": "ffmpeg"}


def frame_steps(n_steps: int, snaps: np.ndarray, frames: int) -> np.ndarray:
    """The steps an animation shows: `frames` evenly spaced steps, plus every snap step and the step
    before it (so the jump is on screen whatever the spacing), in order."""
    if frames < 2:
        raise ValueError(f"an animation needs at least 2 frames, got {frames}")
    even = np.round(np.linspace(0, n_steps - 1, min(frames, n_steps))).astype(int)
    at = np.flatnonzero(np.asarray(snaps, bool))
    return np.unique(np.r_[even, at, np.maximum(at - 1, 0)])


def writer_for(path: str | Path) -> str:
    """The matplotlib writer for `path`'s suffix; a ValueError that says what to use otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"{path}: an animation is written as {' or '.join(FORMATS)}, not {suffix!r}")
    writer = FORMATS[suffix]
    if not animation.writers.is_available(writer):
        raise ValueError(f"{path}: writing {suffix} needs {writer}, which is not installed here; "
                         "write a .gif instead")
    return writer


def animate_path(robot: Robot, Q: np.ndarray, trajectory: Trajectory, path: str | Path, *,
                 frames: int = 120, fps: int = 12, spacing: float = 0.5, title: str = "") -> Path:
    """Write an animation of the followed path `Q` (T, 2N) with its `trajectory` (`ctrkin.follow`).

    Parameters
    ----------
    robot : Robot
    Q : ndarray, shape (T, 2N)
        The joints (deg, mm) the trajectory followed.
    trajectory : Trajectory
        `ctrkin.follow(robot, Q)`: equilibria, T(L) and snap flags per step.
    path : str or Path
        Output file, `.gif` (pillow) or `.mp4` (ffmpeg), written atomically.
    frames : int
        About how many steps to show (evenly spaced; snap steps and the steps before them are
        always shown).
    fps : int
        Frames per second.
    spacing : float
        Backbone spacing of the drawing (mm).
    title : str
        Shown above the frames.

    Returns
    -------
    Path
        The file written.
    """
    writer = writer_for(path)
    Q = np.asarray(Q, dtype=float)
    n = robot.n_tubes
    steps = frame_steps(len(Q), trajectory.snaps, frames)
    backbones = {int(t): dense_backbone(trajectory.equilibria[t], spacing) for t in steps}
    tips = trajectory.tip_poses[:, :3]
    alpha0 = Q[:, 0] - Q[:, n - 1]
    snap_steps = np.flatnonzero(trajectory.snaps)
    every = np.vstack([*(bb.points for bb in backbones.values()), tips[np.isfinite(tips).all(axis=1)],
                       np.zeros((1, 3))])

    fig = plt.figure(figsize=(11.0, 5.2))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    fig.subplots_adjust(left=0.02, right=0.97, wspace=0.25)
    ax2.plot(alpha0, trajectory.azimuth, color="0.8", lw=1.0)
    ax2.plot(alpha0[snap_steps], trajectory.azimuth[snap_steps], "x", color=SNAP, ms=9, mew=2.5,
             label=f"snap ({len(snap_steps)})")
    (done,) = ax2.plot([], [], color="tab:blue", lw=1.5)
    (now,) = ax2.plot([], [], "o", color="tab:blue", ms=7)
    ax2.set_xlabel("relative rotation α0 = α1 − αN (deg)")
    ax2.set_ylabel("T(L), tip azimuth (deg)")
    ax2.grid(alpha=0.3)
    ax2.legend(loc="upper left", fontsize=8)
    fig.suptitle(title or f"{robot.name}: {len(Q)} steps followed by continuation", fontsize=11)
    plate = 0.15 * float(np.nanmax(np.abs(every[:, :2])) + 1.0)

    def draw(t: int) -> None:
        ax3.cla()
        draw_robot(ax3, robot, backbones[t])
        ax3.plot(*tips[: t + 1].T, color=TRACE, lw=1.0)
        past = snap_steps[snap_steps <= t]
        if len(past):
            ax3.plot(*tips[past].T, "x", color=SNAP, ms=9, mew=2.5)
        draw_front_plate(ax3, plate)
        set_equal_aspect(ax3, every)
        snapping = bool(trajectory.snaps[t])
        joints = ", ".join(f"{v:.0f}" for v in Q[t])
        ax3.set_title(f"step {t}: q = ({joints})" + ("   SNAP" if snapping else ""),
                      color=SNAP if snapping else "k", fontsize=10)
        done.set_data(alpha0[: t + 1], trajectory.azimuth[: t + 1])
        now.set_data([alpha0[t]], [trajectory.azimuth[t]])
        now.set_color(SNAP if snapping else "tab:blue")

    anim = animation.FuncAnimation(fig, draw, frames=[int(t) for t in steps], interval=1000 / fps,
                                   repeat=False)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    # the writers choose the format by the file's suffix: render under the real name in a temporary
    # folder beside the target, then move it in with one rename (a reader never sees half a file)
    with tempfile.TemporaryDirectory(prefix=f".{out.name}.", dir=out.parent) as tmp:
        anim.save(str(Path(tmp) / out.name), writer=writer, fps=fps, dpi=80)
        os.replace(Path(tmp) / out.name, out)
    plt.close(fig)
    return out
