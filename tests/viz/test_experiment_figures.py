"""The reproduction figures: directions told apart, the snap marker in the legend, one colour scale
per unit, axis labels on 3-D panels."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest

from ctrkin.evaluation.experiments_fk import TURN_ROWS, turn_curves
from ctrkin.viz import experiments as fx

matplotlib.use("Agg")


@pytest.fixture
def saved(monkeypatch):
    """The figures the functions would save, kept open for inspection."""
    figs = []
    monkeypatch.setattr(fx, "_save", lambda fig, path: figs.append(fig))
    return figs


def test_directions_split_a_turn_and_break_at_the_reversal_and_jumps() -> None:
    a0 = np.r_[np.arange(0.0, 5.0), np.arange(3.0, -1.0, -1.0), np.arange(100.0, 103.0)]
    fw, brk = fx._directions(a0)
    np.testing.assert_array_equal(fw, [1, 1, 1, 1, 1, 0, 0, 0, 0, 1, 1, 1])
    np.testing.assert_array_equal(np.nonzero(brk)[0], [0, 5, 9])   # start, reversal, 96° jump
    y = fx._stretch(np.arange(12.0), fw, brk)
    assert len(y) == 14 and np.isnan(y[5]) and np.isnan(y[10])      # a gap before each break


def test_sweeps_figure_legend_has_directions_and_snaps(tmp_path, monkeypatch) -> None:
    figs = []
    monkeypatch.setattr(fx.plt, "close", lambda fig=None: figs.append(fig))
    a0 = np.r_[np.arange(0.0, 361.0, 5.0), np.arange(355.0, -1.0, -5.0)]
    tl = np.where(a0 < 180, -70.0, -120.0) - 360.0                    # a turn away: shown in [−180, 180)
    snaps = np.zeros(len(a0), bool)
    snaps[36] = True
    panel = {"label": "d = 20 mm", "alpha0": a0, "measured": tl, "truth": tl, "lstm_mlp_branch": tl,
             "snaps": snaps}
    fx.sweeps_figure([panel, panel], tmp_path / "s.png", turn_curves(TURN_ROWS))
    assert (tmp_path / "s.png").stat().st_size > 5_000
    fig = figs[0]
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    for want in ("measured", "truth", "snap-aware LSTM-MLP", "forward (α0 increasing)", "backward",
                 "snap (in the data)"):
        assert want in labels
    ax = fig.axes[0]
    assert -180.0 <= ax.get_ylim()[0] and ax.get_ylim()[1] < 180.0
    assert ax.get_xlabel() == "α0 = α1 − αN (deg)" and ax.get_ylabel() == "T(L) (deg)"


def test_the_truth_is_drawn_last_on_top_of_the_predictions(tmp_path, monkeypatch) -> None:
    figs = []
    monkeypatch.setattr(fx.plt, "close", lambda fig=None: figs.append(fig))
    a0 = np.r_[np.arange(0.0, 361.0, 5.0), np.arange(355.0, -1.0, -5.0)]
    tl = np.sin(np.radians(a0)) * 30.0
    curves = turn_curves(TURN_ROWS)
    assert list(curves)[-1] == "truth"
    panel = {"label": "d = 8 mm", "alpha0": a0, "measured": tl, "snaps": np.zeros(len(a0), bool),
             **{k: tl for k in curves}}
    fx.sweeps_figure([panel], tmp_path / "s.png", curves)
    lines = [ln for ln in figs[0].axes[0].lines if ln.get_marker() in ("None", "")]
    assert matplotlib.colors.same_color(lines[-1].get_color(), fx.TRUE)      # backward truth, on top
    assert matplotlib.colors.same_color(lines[-2].get_color(), fx.TRUE)      # forward truth


def test_grid_figure_gives_each_unit_its_own_colour_scale(tmp_path, saved) -> None:
    values = np.array([[1.0, 2.0], [0.5, 1.5], [100.0, 60.0]])
    fx.grid_figure(["FK pos", "IK β", "IK α"], ["IB=1", "IB=2"], values, tmp_path / "g.png", "t",
                   units=["mm", "mm", "deg"])
    fig = saved[0]
    images = [im for ax in fig.axes for im in ax.get_images()]
    assert [im.get_clim() for im in images] == [(0.5, 2.0), (60.0, 100.0)]
    colorbar_labels = {ax.get_ylabel() for ax in fig.axes if not ax.get_images()}
    assert colorbar_labels == {"mm", "deg"}


def test_ik_path_figure_labels_the_3d_axes(tmp_path, saved) -> None:
    rng = np.random.default_rng(0)
    targets = rng.normal(size=(10, 6))
    fx.ik_path_figure(targets, targets, targets, rng.normal(size=(10, 4)), tmp_path / "p.png", "square")
    ax3 = saved[0].axes[0]
    assert (ax3.get_xlabel(), ax3.get_ylabel(), ax3.get_zlabel()) == ("x (mm)", "y (mm)", "z (mm)")


def test_sweep_panels_name_the_papers_levels_on_the_paper_robot_only() -> None:
    from ctrkin.evaluation.experiments_fk import level_label
    from ctrkin.robots import Robot, paper_robot

    robot = paper_robot()
    assert level_label(20.0, robot) == "d = 20 mm (paper β12 = 55)"
    assert level_label(4.0, robot) == "d = 4 mm (paper β12 = 15)"
    assert level_label(20.0, Robot.from_dict({**robot.to_dict(), "name": "other"})) == "d = 20 mm"


def test_delta_overlaps_figure_has_a_panel_per_level_with_both_maes(saved) -> None:
    t = np.linspace(0, 2 * np.pi, 50)
    meas = np.c_[np.cos(t), np.sin(t), np.zeros_like(t)]
    panels = [{"label": f"d = {d} mm", "measured": meas,
               "series": {"with Δα0": (meas + 0.1, 0.1), "without Δα0": (meas + 0.5, 0.5)}}
              for d in (4, 12, 20)]
    fx.delta_overlaps_figure(panels, "unused.png")
    axes = saved[0].axes
    assert len(axes) == 3
    assert axes[1].get_title() == "d = 12 mm\nMAE 0.10 / 0.50 mm"
    assert [t.get_text() for t in axes[0].get_legend().get_texts()] == ["measured", "with Δα0", "without Δα0"]


def test_training_curves_figure_marks_each_models_best_epoch(saved) -> None:
    hist = [{"epoch": e, "train_loss": 1.0 / e, "val_loss": abs(e - 3) + 0.5} for e in range(1, 7)]
    fx.training_curves_figure({"fk": {"A": hist, "B": hist}, "ik": {"C": hist}}, "unused.png")
    fk, ik = saved[0].axes
    assert fk.get_title() == "(a) FK" and ik.get_title() == "(b) IK"
    assert len(fk.lines) == 6 and len(ik.lines) == 3           # training, validation, best per model
    best = next(ln for ln in fk.lines if ln.get_marker() == "o")
    assert list(best.get_xdata()) == [3] and list(best.get_ydata()) == [0.5]
