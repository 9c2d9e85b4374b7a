"""The training loop of issue 11: the whole-epoch loop follows the per-batch one (same batches, same
seeds), the learning-rate rule, early stopping on a smoothed val loss, the wall-clock budget."""

from __future__ import annotations

import math

import pytest
import torch

from ctrkin.errors import ModelError
from ctrkin.training import TrainConfig, train
from ctrkin.training.config import scaled_lr
from ctrkin.training.engine import _early_stopping

SMALL = {"structure": "L16|D16"}


def test_epoch_loop_follows_the_batch_loop(quick_ds, tmp_path):
    """Same permutation and batches: bit-identical with Adam's default kernel and torch's LSTM, equal
    up to rounding with the fused kernel and the fused window LSTM."""
    nets = {}
    for name, loop, fused in (("batch", "batch", True), ("epoch", "epoch", False), ("fused", "epoch", True)):
        cfg = TrainConfig(task="fk", loop=loop, fused_adam=fused, fused_lstm=fused, max_epochs=2, patience=2,
                          threads=1, batch_size=64, options=SMALL)
        res = train(quick_ds, cfg, tmp_path / name, progress=False)
        nets[name] = torch.load(tmp_path / name / "weights.pt", weights_only=True)
        assert res.metrics["training"]["samples_per_s"] > 0
    for k, w in nets["batch"].items():
        assert torch.equal(nets["epoch"][k], w), k
        torch.testing.assert_close(nets["fused"][k], w, rtol=0, atol=1e-4)


def test_square_root_learning_rate_rule():
    assert scaled_lr(32) == pytest.approx(1e-3)          # the paper's batch and lr
    assert scaled_lr(512) == pytest.approx(4e-3)
    assert scaled_lr(128, base_lr=2e-3, base_batch=32) == pytest.approx(4e-3)


def _stopping(losses: list[float], smoothing: float, patience: int = 3) -> tuple[int, int]:
    """(stop epoch, best epoch) for a val-loss curve."""
    cfg = TrainConfig(val_smoothing=smoothing, patience=patience)
    state = {"epoch": 0, "best_val": math.inf, "best_epoch": 0, "since_best": 0}
    for loss in losses:
        state["epoch"] += 1
        _early_stopping(state, loss, cfg)
        if state["since_best"] >= cfg.patience:
            break
    return state["epoch"], state["best_epoch"]


def test_smoothed_early_stopping_rides_out_noise_but_stops_on_a_plateau():
    # a falling trend with a lucky dip at epoch 3, then a noisy plateau from epoch 41
    trend = [1.0 - 0.01 * k - (0.05 if k == 3 else 0.0) for k in range(1, 41)]
    curve = trend + [0.6 + (0.01 if k % 2 else -0.01) for k in range(40)]
    assert _stopping(curve, 0.0) == (6, 3)              # raw: the dip exhausts the patience
    stop, best = _stopping(curve, 0.5)
    assert 41 < stop < 60 and best == 41                 # smoothed: on to the plateau, best raw kept


def test_wall_clock_budget_stops_and_resumes(quick_ds, tmp_path):
    cfg = TrainConfig(task="fk", max_epochs=50, patience=50, threads=1, options=SMALL, max_seconds=1e-6)
    assert train(quick_ds, cfg, tmp_path / "m", progress=False).metrics["training"]["epochs"] == 1
    more = TrainConfig.from_dict({**cfg.to_dict(), "max_seconds": 1e6, "max_epochs": 3})
    assert train(quick_ds, more, tmp_path / "m", progress=False).metrics["training"]["epochs"] == 3


@pytest.mark.parametrize(("key", "value"), [("loop", "fast"), ("val_smoothing", 1.0), ("max_seconds", 0.0)])
def test_new_options_are_validated(key, value):
    with pytest.raises(ModelError, match=key):
        TrainConfig(**{key: value})


def test_the_fused_lstm_is_on_for_the_epochs_only(quick_ds, tmp_path, monkeypatch):
    """The engine turns the window LSTM on for its epochs and off after them (the export, the
    evaluation and the saved network see torch's nn.LSTM); the batch loop and --no-fused-lstm never
    turn it on."""
    from ctrkin.training import engine

    seen: list[tuple[bool, bool]] = []
    real = engine.use_window_lstm

    def spy(net, on):
        seen.append((on, any(getattr(m, "fused_lstm", False) for m in net.modules())))
        real(net, on)

    monkeypatch.setattr(engine, "use_window_lstm", spy)
    for name, loop, fused in (("on", "epoch", True), ("off", "epoch", False), ("batch", "batch", True)):
        seen.clear()
        cfg = TrainConfig(task="fk", loop=loop, fused_lstm=fused, max_epochs=1, patience=1, threads=1,
                          batch_size=256, options=SMALL)
        train(quick_ds, cfg, tmp_path / name, progress=False)
        assert seen == [(name == "on", False), (False, name == "on")], name
