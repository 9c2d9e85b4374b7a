"""Which gate a snap-aware FK switches branches by, chosen on its validation rows
(docs/learned_kinematics.md: The gate chosen on validation).

The fold gate places a snap where the nominal robot folds, shifted by offsets fitted to the training
snaps (ctrkin.families.snap_aware.fold_gate): a physics prior, and the default. Where the real tubes
snap elsewhere, or the recording holds too few snaps to fit the offsets (a second two-tube design at
the top of the effect ranges: 3 training snaps, 32° RMS from its fitted folds), the network's learned
gate, which learns the switches from the labels alone, can be the better one. The model keeps the
fold gate unless the learned one is better on the validation sequences with confidence:

    P( RMSE_learned < RMSE_fold )  over B bootstrap resamples of the validation sequences  ≥ LEVEL

(whole sequences resampled, as a snap moves every later row of its sequence; positions against the
poses the model learned). Both predictions follow the whole dataset, so every validation row has the
history it had in the recording. With fewer than two validation sequences the fold gate stays.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from ctrkin.data.dataset import Dataset
    from ctrkin.families.snap_aware.predictor import SnapAwarePredictor

RESAMPLES = 2000     # bootstrap resamples of the validation sequences
LEVEL = 0.95         # the share of resamples in which the learned gate must be better
SEED = 0


@dataclass(frozen=True)
class GateChoice:
    """fold_mm, learned_mm: validation position RMSE with each gate; p_learned_better: the share of
    bootstrap resamples in which the learned gate's RMSE is the lower; sequences: how many validation
    sequences; use_fold: the choice."""

    fold_mm: float
    learned_mm: float
    p_learned_better: float
    sequences: int
    use_fold: bool

    def to_dict(self) -> dict[str, Any]:
        return {"gate": "fold" if self.use_fold else "learned", "val_position_rmse_fold_mm": self.fold_mm,
                "val_position_rmse_learned_mm": self.learned_mm, "p_learned_better": self.p_learned_better,
                "val_sequences": self.sequences, "level": LEVEL, "resamples": RESAMPLES}


def choose_gate(fold_pos: np.ndarray, learned_pos: np.ndarray, target_pos: np.ndarray,
                sequence: np.ndarray) -> GateChoice:
    """The choice from predicted positions (V, 3) with each gate, the targets (V, 3) and each row's
    sequence (V,), over the validation rows."""
    seqs, which = np.unique(sequence, return_inverse=True)
    sse_fold = np.bincount(which, np.sum((fold_pos - target_pos) ** 2, axis=1), len(seqs))
    sse_learned = np.bincount(which, np.sum((learned_pos - target_pos) ** 2, axis=1), len(seqs))
    rows = np.bincount(which, minlength=len(seqs)).astype(float)
    total = max(rows.sum(), 1.0)
    fold_mm, learned_mm = float(np.sqrt(sse_fold.sum() / total)), float(np.sqrt(sse_learned.sum() / total))
    if len(seqs) < 2:
        return GateChoice(fold_mm, learned_mm, 0.0, len(seqs), True)
    draw = np.random.default_rng(SEED).integers(0, len(seqs), (RESAMPLES, len(seqs)))
    # the same rows under both gates, so comparing the sums of squares compares the RMSEs
    p = float(np.mean(sse_learned[draw].sum(axis=1) < sse_fold[draw].sum(axis=1)))
    return GateChoice(fold_mm, learned_mm, p, len(seqs), p < LEVEL)


def gate_positions(model: SnapAwarePredictor, ds: Dataset) -> tuple[np.ndarray, np.ndarray]:
    """(T, 3) tip positions of `model` (with a fold gate, in use or aside) over every row of `ds` by
    its fold gate and by its learned gate, each along the whole dataset (its runs' histories)."""
    return (np.asarray(model.predict(ds, gate="fold"))[:, :3],
            np.asarray(model.predict(ds, gate="learned"))[:, :3])


def judge_gates(model: SnapAwarePredictor, ds: Dataset, val: np.ndarray, target: np.ndarray) -> GateChoice:
    """The choice for `model` on rows `val` of `ds` (`gate_positions`); target (T, ≥3): the poses it
    learned."""
    fold, learned = gate_positions(model, ds)
    return choose_gate(fold[val], learned[val], target[val, :3], ds.frame["sequence_id"].to_numpy()[val])
