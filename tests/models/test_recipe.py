"""The paper's recipe (ctrkin.models.recipe.WindowRecipe) in the outer tube's frame: a lagged frame's
network sees the frame's angle."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

import ctrkin.models.recipe as recipe
from ctrkin.models.recipe import TrainingData, WindowRecipe
from ctrkin.training import TrainConfig
from ctrkin.training.data import split_rows


def test_lagged_frame_feeds_the_outer_tubes_angle(quick_ds, monkeypatch):
    """With a fitted lag, the αN feature (and α0 = α1 − αN, eq. 1) of every window's last step is the
    frame's angle αN − λ(β)·m_N, and the frame is saved with lagged_inputs."""
    monkeypatch.setattr(recipe, "fit_outer_lag", lambda *a, **k: (2.0, 0.4))
    cfg = TrainConfig(task="fk", model="lstm_mlp_branch", target_frame="outer", threads=1)
    ds = replace(quick_ds, frame=quick_ds.frame.assign(run=0))   # one run: the outer turns in between
    prep = WindowRecipe(cfg)
    prepared = prep.prepare(TrainingData(ds, cfg, *split_rows(ds, cfg)))
    assert prepared.frame is prep.frame
    assert prep.frame is not None and prep.frame.lags_inputs and prep.outer_deg is not None
    q = ds.joints()
    lagged = np.abs(prep.outer_deg - q[:, 1]) > 1e-6
    assert 0 < lagged.sum() < len(q)                    # some rows after outer turns, some at rest
    last = prep.x_norm.inverse(prep.X[:, -1].astype(np.float64))
    names = list(prep.layout.input_names)
    np.testing.assert_allclose(last[:, names.index("alpha_2")], prep.outer_deg, atol=1e-3)
    np.testing.assert_allclose(last[:, names.index("alpha_0")], q[:, 0] - prep.outer_deg, atol=1e-3)
    np.testing.assert_allclose(last[:, names.index("alpha_1")], q[:, 0], atol=1e-3)
