"""Issue 22: `ctrkin train`'s defaults on a small set. The budget adapts to the set's size (optimiser
steps, not epochs), the patience counts steps, and the end of a run says plainly when the model
under-fits or stopped at its budget while still improving (a warning line and metrics.json)."""

from __future__ import annotations

import json
import math

import pytest

from ctrkin.acquisition.demo import sweep_dataset
from ctrkin.robots import paper_robot
from ctrkin.training import TrainConfig, train
from ctrkin.training.fit import diagnose

SMALL = {"structure": "L8|D8"}


@pytest.fixture(scope="module")
def small_ds():
    """3 coarse sweeps (d = 8, 14, 20 mm at 30° steps): 75 rows, a few optimiser steps an epoch."""
    return sweep_dataset(paper_robot(), translations=(8, 14, 20), outer_alphas=(0,), step_deg=30,
                         noise_mm=0.02, seed=3)


def test_the_default_budget_is_in_optimiser_steps():
    cfg = TrainConfig(task="fk")
    assert cfg.max_epochs is None
    assert cfg.epoch_budget(44) == math.ceil(cfg.min_steps / 2)      # 44 rows at batch 32: 2 steps an epoch
    assert cfg.epoch_budget(1_000_000) == 500                         # a large set keeps the paper's 500
    assert TrainConfig(task="fk", max_epochs=7).epoch_budget(44) == 7  # a given budget is kept
    assert cfg.patience_epochs(44) == math.ceil(cfg.patience_steps / 2)
    assert cfg.patience_epochs(1_000_000) == cfg.patience == 20


def _history(train_losses, val_losses):
    return [{"epoch": i + 1, "train_loss": t, "val_loss": v, "seconds": 0.0}
            for i, (t, v) in enumerate(zip(train_losses, val_losses, strict=True))]


def test_diagnose_tells_under_fitting_from_convergence():
    falling = _history([1.0 - 0.02 * i for i in range(40)], [0.5] * 40)
    fit = diagnose(falling, best_epoch=10, patience_epochs=30, stopped_by="patience", train_loss=0.45,
                   val_loss=0.5)
    assert fit["verdict"] == "under-fits" and "under-fits" in fit["warnings"][0]
    flat = _history([0.2] * 40, [0.21] * 40)       # a large set, converged: alike losses, flat training loss
    assert diagnose(flat, 20, 20, "patience", 0.2, 0.21)["verdict"] == "fits"
    overfit = _history([1.0 - 0.02 * i for i in range(40)], [0.5] * 40)
    assert diagnose(overfit, 10, 30, "patience", 0.1, 0.5)["verdict"] == "fits"   # fits its training rows
    assert diagnose(flat, 10, 20, "max_epochs", 0.2, 0.21)["verdict"] == "fits"   # patience ran out too
    late = diagnose(flat, 35, 20, "max_epochs", 0.2, 0.21)
    assert late["verdict"] == "still improving" and "raise --epochs" in late["warnings"][0]


def test_a_small_set_gets_a_budget_and_patience_in_steps(small_ds, tmp_path):
    cfg = TrainConfig(task="fk", options=SMALL, threads=1, min_steps=1200, patience_steps=300, lr=3e-3)
    said: list[str] = []
    res = train(small_ds, cfg, tmp_path / "m", progress=False, log=said.append)
    tr = res.metrics["training"]
    per_epoch = tr["steps_per_epoch"]
    assert per_epoch <= 3                                         # a small set: a few steps an epoch
    assert tr["max_epochs"] == max(500, math.ceil(1200 / per_epoch))
    assert tr["patience_epochs"] == max(20, math.ceil(300 / per_epoch))
    assert tr["steps"] == tr["epochs"] * per_epoch
    saved = json.loads((tmp_path / "m" / "config.json").read_text())["train"]
    assert saved["max_epochs"] == tr["max_epochs"]                # the budget it ran with is stored
    fit = tr["fit"]
    assert fit["stopped_by"] == tr["stopped_by"] in ("patience", "max_epochs")
    assert fit["train_loss"] == pytest.approx(res.metrics["train"]["loss"])
    assert fit["val_loss"] == pytest.approx(res.metrics["val"]["loss"])
    assert all(f"warning: {w}" in said for w in fit["warnings"])     # said, and saved


def test_a_run_cut_short_says_so(small_ds, tmp_path):
    said: list[str] = []
    res = train(small_ds, TrainConfig(task="fk", options=SMALL, threads=1, max_epochs=3, lr=3e-3),
                tmp_path / "m", progress=False, log=said.append)
    fit = res.metrics["training"]["fit"]
    assert res.metrics["training"]["stopped_by"] == "max_epochs"
    assert fit["verdict"] != "fits" and fit["warnings"]
    assert any(m.startswith("warning: ") and ("under-fits" in m or "raise --epochs" in m) for m in said)
    saved = json.loads((tmp_path / "m" / "metrics.json").read_text())
    assert saved["training"]["fit"]["verdict"] == fit["verdict"]
