"""How a training run ended, in words a user can act on (issue 22: `ctrkin train`'s defaults stopped
a 63-sample set at epoch 175, 10-14 mm off even on its own training files, and said nothing).

Two signs are read from the run, both in the normalised loss the engine minimises:
- *still improving*: the budget (max_epochs or max_seconds) ended the run before early stopping's
  patience had run out (the validation loss improved within the last `patience_epochs`), so more
  epochs would probably have helped;
- *under-fits*: the network fits its own training rows hardly better than the validation rows
  (training loss at least UNDERFIT_RATIO of the validation loss) while its training loss was still
  falling by more than FALLING_FRACTION over the last quarter of the epochs: it stopped before it
  learned what the training set holds. (A model that has converged on a large set has training and
  validation losses alike too, but a flat training loss: that is not flagged.)
"""

from __future__ import annotations

from typing import Any

UNDERFIT_RATIO = 0.7      # training loss / validation loss above which the training rows are not fitted
FALLING_FRACTION = 0.1    # relative fall of the training loss over the last quarter: still learning


def training_trend(history: list[dict[str, float]]) -> float:
    """Relative fall of the epoch training loss over the last quarter of the run (0.2: it fell by 20 %
    from the start of that quarter to its end; 0 for runs of fewer than 4 epochs)."""
    n = len(history)
    if n < 4:
        return 0.0
    a = history[n - 1 - n // 4]["train_loss"]
    b = history[-1]["train_loss"]
    return (a - b) / a if a > 0 else 0.0


def diagnose(history: list[dict[str, float]], best_epoch: int, patience_epochs: int, stopped_by: str,
             train_loss: float, val_loss: float) -> dict[str, Any]:
    """The fit summary saved in metrics.json (`training.fit`): the losses of the kept weights on the
    training and validation rows (normalised MAE), the training loss's recent fall, the verdict
    ("fits", "still improving" or "under-fits") and one warning line per sign (module docstring)."""
    epochs = len(history)
    trend = training_trend(history)
    ratio = train_loss / val_loss if val_loss > 0 else 0.0
    warnings = []
    improving = stopped_by != "patience" and epochs - best_epoch < patience_epochs
    underfit = ratio >= UNDERFIT_RATIO and trend > FALLING_FRACTION
    if improving:
        warnings.append(f"training stopped at its budget ({stopped_by}, {epochs} epochs) while the "
                        f"validation loss was still improving (best epoch {best_epoch}, patience "
                        f"{patience_epochs} epochs): raise --epochs (or --max-seconds) and run the same "
                        "command again to continue")
    if underfit:
        warnings.append(f"the model under-fits: its training loss ({train_loss:.4g}) is {ratio:.0%} of "
                        f"the validation loss ({val_loss:.4g}) and fell by {trend:.0%} over the last "
                        f"quarter of the {epochs} epochs ({stopped_by} ended it): it has not learned its "
                        "own training rows yet; raise --epochs / --min-steps or --patience-steps")
    verdict = "under-fits" if underfit else "still improving" if improving else "fits"
    return {"stopped_by": stopped_by, "train_loss": train_loss, "val_loss": val_loss,
            "train_to_val": ratio, "train_loss_fall_last_quarter": trend, "verdict": verdict,
            "warnings": warnings}
