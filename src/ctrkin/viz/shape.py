"""3-D drawings of a concentric tube robot: each tube as a tube of its outer diameter along the
backbone, over the part of the backbone where it is the outermost tube, the tip's path and the
snaps along it (`ctrkin show`).

The backbone comes from `ctrkin.mechanics.shape.dense_backbone` (points at most `spacing` mm
apart), so the curve is drawn as it is, not as the solve's 6–9 grid points.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from mpl_toolkits.mplot3d.axes3d import Axes3D

from ctrkin.mechanics.pointwise import Equilibrium
from ctrkin.mechanics.shape import Backbone, dense_backbone
from ctrkin.robots.robot import Robot
from ctrkin.util.files import atomic_path

SNAP = "tab:red"
TRACE = "0.35"


def tube_colors(n_tubes: int) -> list[tuple[float, float, float, float]]:
    """One colour per tube, innermost first (light to dark)."""
    cmap = plt.get_cmap("viridis")
    return [cmap(0.85 - 0.65 * k / max(n_tubes - 1, 1)) for k in range(n_tubes)]


def tube_surface(points: np.ndarray, radius: float, n_around: int = 16
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A tube of `radius` mm around the polyline `points` (M, 3) mm: X, Y, Z, each (M, n_around + 1).

    The circles are carried along the curve by a rotation-minimising (parallel-transport) frame,
    so the surface does not twist where the backbone bends.
    """
    p = np.asarray(points, dtype=float)
    tangent = np.gradient(p, axis=0) if len(p) > 1 else np.array([[0.0, 0.0, 1.0]])
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    seed = np.array([1.0, 0.0, 0.0]) if abs(tangent[0, 0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    normal = np.empty_like(p)
    normal[0] = np.cross(tangent[0], seed)
    for k in range(len(p)):
        n = normal[k - 1] if k else normal[0]
        n = n - np.dot(n, tangent[k]) * tangent[k]          # transport: drop the tangential part
        normal[k] = n / max(float(np.linalg.norm(n)), 1e-12)
    binormal = np.cross(tangent, normal)
    phi = np.linspace(0.0, 2.0 * np.pi, n_around + 1)
    ring = radius * (np.cos(phi)[None, :, None] * normal[:, None, :]
                     + np.sin(phi)[None, :, None] * binormal[:, None, :])
    surf = p[:, None, :] + ring
    return surf[..., 0], surf[..., 1], surf[..., 2]


def draw_robot(ax: Axes3D, robot: Robot, backbone: Backbone, alpha: float = 1.0,
               colors: Sequence[tuple[float, ...]] | None = None) -> None:
    """Draw every tube on `ax` as a tube of its outer diameter over its extent (Backbone.extent)."""
    colors = list(colors) if colors is not None else tube_colors(robot.n_tubes)
    for i, tube in enumerate(robot.tubes):
        start, end = backbone.extent(i)
        if end - start <= 1e-9:
            continue
        x, y, z = tube_surface(backbone.section(start, end), tube.od / 2.0)
        ax.plot_surface(x, y, z, color=colors[i], alpha=alpha, linewidth=0, antialiased=False,
                        shade=True)
    ax.plot(*backbone.points.T, color="k", lw=0.6, alpha=0.6 * alpha)    # the backbone itself


def set_equal_aspect(ax: Axes3D, points: np.ndarray, margin: float = 0.05) -> None:
    """Axes limits around `points` (M, 3) mm with equal scale on x, y and z (a circle stays round)."""
    lo, hi = np.nanmin(points, axis=0), np.nanmax(points, axis=0)
    centre, half = (lo + hi) / 2.0, max(float((hi - lo).max()) / 2.0, 1.0) * (1.0 + margin)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")


def draw_front_plate(ax: Axes3D, radius: float) -> None:
    """The front plate (s = 0, z = 0) as a grey disc."""
    phi = np.linspace(0.0, 2.0 * np.pi, 33)
    ax.plot(radius * np.cos(phi), radius * np.sin(phi), 0 * phi, color="0.6", lw=1.0)


def plot_shape(robot: Robot, equilibria: Sequence[Equilibrium], path: str | Path | None = None, *,
               snaps: np.ndarray | None = None, tips: np.ndarray | None = None, spacing: float = 0.5,
               title: str | None = None) -> plt.Figure:
    """The robot's shape at one or more equilibria in 3-D.

    Parameters
    ----------
    robot : Robot
        The robot (tube diameters).
    equilibria : sequence of Equilibrium
        The shapes to draw; the last one opaque, earlier ones fainter (a path's history).
    path : str or Path, optional
        Where to write the figure (PNG, written atomically); None: only return it.
    snaps : ndarray of bool, shape (T,), optional
        Snap flags of the path whose tip positions `tips` are given: those tips are marked.
    tips : ndarray, shape (T, 3), optional
        The tip's path (mm), drawn as a line.
    spacing : float
        Backbone spacing (mm) of the drawing (`dense_backbone`).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    if not equilibria:
        raise ValueError("plot_shape needs at least one equilibrium")
    backbones = [dense_backbone(eq, spacing) for eq in equilibria]
    fig = plt.figure(figsize=(7.5, 7.0))
    ax = fig.add_subplot(projection="3d")
    for k, bb in enumerate(backbones):
        last = k == len(backbones) - 1
        draw_robot(ax, robot, bb, alpha=1.0 if last else 0.25)
    extent = [bb.points for bb in backbones]
    if tips is not None:
        t = np.asarray(tips, dtype=float)
        ax.plot(*t.T, color=TRACE, lw=1.0, label="tip path")
        extent.append(t)
        if snaps is not None and np.asarray(snaps, bool).any():
            s = np.asarray(snaps, bool)
            ax.plot(*t[s].T, "x", color=SNAP, ms=9, mew=2.5, label=f"snap ({int(s.sum())})")
        ax.legend(loc="upper left", fontsize=8)
    points = np.vstack(extent)
    draw_front_plate(ax, 0.15 * float(np.nanmax(np.abs(points[:, :2])) + 1.0))
    set_equal_aspect(ax, np.vstack([points, np.zeros((1, 3))]))
    ax.set_title(title or _describe(robot, equilibria[-1]), fontsize=10)
    fig.tight_layout()
    if path is not None:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=120, format="png")
    return fig


def _describe(robot: Robot, eq: Equilibrium) -> str:
    n = robot.n_tubes
    joints = ", ".join(f"{name} = {v:g}" for name, v in zip(robot.joint_names(), eq.q, strict=True))
    state = "stable" if eq.stable else ("unstable" if eq.converged else "not converged")
    return f"{robot.name} ({n} tubes): {joints}\n{state}; tip at {np.round(eq.tip_position, 2).tolist()} mm"
