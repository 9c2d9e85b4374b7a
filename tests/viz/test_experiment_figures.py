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
