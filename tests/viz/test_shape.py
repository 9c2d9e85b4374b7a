"""viz.shape: tubes drawn with their radius around the backbone, circles square to it."""

from __future__ import annotations

import numpy as np

from ctrkin import paper_robot, solve
from ctrkin.mechanics.shape import dense_backbone
from ctrkin.viz.shape import draw_robot, plot_shape, tube_surface


def test_tube_surface_is_a_ring_of_the_radius_square_to_the_curve() -> None:
    th = np.linspace(0.0, 1.5, 60)
    curve = np.c_[0 * th, 20 * (1 - np.cos(th)), 20 * np.sin(th)]     # an arc of radius 20 mm
    x, y, z = tube_surface(curve, 0.7, n_around=12)
    assert x.shape == (60, 13)
    ring = np.stack([x, y, z], axis=-1) - curve[:, None, :]
    np.testing.assert_allclose(np.linalg.norm(ring, axis=-1), 0.7, rtol=1e-12)
    tangent = np.c_[0 * th, np.sin(th), np.cos(th)]
    inner = np.abs(np.einsum("kjc,kc->kj", ring, tangent))[1:-1]       # ends: one-sided difference
    assert inner.max() < 0.7 * 1e-3


class _Recorder:
    """The two Axes3D calls draw_robot makes, recorded."""

    def __init__(self) -> None:
        self.surfaces: list[np.ndarray] = []

    def plot_surface(self, x, y, z, **_kw) -> None:
        self.surfaces.append(np.stack([x, y, z], axis=-1))

    def plot(self, *_a, **_kw) -> None:
        pass


def test_every_tube_is_drawn_with_its_radius_over_its_extent() -> None:
    robot = paper_robot()
    eq = solve(robot, [0, 0, -15, -5])
    bb = dense_backbone(eq, 0.5)
    ax = _Recorder()
    draw_robot(ax, robot, bb)      # type: ignore[arg-type]
    assert len(ax.surfaces) == robot.n_tubes
    for i, (surface, tube) in enumerate(zip(ax.surfaces, robot.tubes, strict=True)):
        centre = surface[:, :-1].mean(axis=1)                                  # ring centres: on the backbone
        np.testing.assert_allclose(np.linalg.norm(surface - centre[:, None], axis=-1), tube.od / 2, rtol=1e-3)
        start, end = bb.extent(i)
        ends = [np.array([np.interp(v, bb.s, bb.points[:, k]) for k in range(3)]) for v in (start, end)]
        np.testing.assert_allclose(centre[0], ends[0], atol=1e-3)
        np.testing.assert_allclose(centre[-1], ends[1], atol=1e-3)
    np.testing.assert_allclose(ax.surfaces[0][:, :-1].mean(axis=1)[-1], eq.tip_position, atol=1e-3)  # the tip
    np.testing.assert_allclose(ax.surfaces[1][:, :-1].mean(axis=1)[0], 0.0, atol=1e-9)    # the plate


def test_plot_shape_writes_a_png(tmp_path) -> None:
    robot = paper_robot()
    fig = plot_shape(robot, [solve(robot, [0, 0, -15, -5])], tmp_path / "s.png")
    assert len(fig.axes[0].collections) == robot.n_tubes
    assert (tmp_path / "s.png").stat().st_size > 10_000
