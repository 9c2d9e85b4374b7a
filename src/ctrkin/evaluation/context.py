"""What every experiment of a reproduction shares: the data, the trained models, the TCM baseline
and cached predictions."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.evaluation.datasets import ReproData, registered_truth
from ctrkin.evaluation.metrics import pose_errors
from ctrkin.evaluation.tcm_baseline import TCMBaseline
from ctrkin.inference import Kinematics


@dataclass(eq=False)
class Context:
    data: ReproData
    models: dict[str, Kinematics]
    tcm: TCMBaseline
    figures: Path
    _cache: dict[tuple[str, int], np.ndarray] = field(default_factory=dict)

    def truth(self, ds: Dataset) -> np.ndarray:
        """(T, 6) noise-free tracker view of the true poses of ds."""
        key = ("truth", id(ds))
        if key not in self._cache:
            self._cache[key] = registered_truth(ds, self.data.virtual)
        return self._cache[key]

    def fk(self, name: str, ds: Dataset) -> np.ndarray:
        """(T, 6) predictions of FK model `name` over every sequence of ds (batch, with history)."""
        key = (name, id(ds))
        if key not in self._cache:
            self._cache[key] = np.asarray(self.models[name].predict(ds), float)
        return self._cache[key]

    def tcm_rows(self, ds: Dataset, rows: np.ndarray, desc: str) -> tuple[np.ndarray, np.ndarray]:
        """TCM predictions (len(rows), 6) in the tracker frame and per-point times (s)."""
        pred = self.tcm.predict(ds.joints()[rows], desc=desc)
        return pred, self.tcm.last_times.copy()


def valid_rows(ds: Dataset, rows: np.ndarray | None = None) -> np.ndarray:
    """Rows (of `rows`, default all) whose joints are not encoder glitches (the paper removed them)."""
    idx = np.arange(len(ds.frame)) if rows is None else np.asarray(rows)
    return idx[~ds.frame["outlier"].to_numpy()[idx]]


def summary(
    pred: np.ndarray, measured: np.ndarray, truth: np.ndarray | None, mask: np.ndarray | None = None
) -> dict[str, Any]:
    """Headline numbers of one predictor: RMSE/MAE/max vs measured, RMSE vs truth."""
    e = pose_errors(pred, measured, mask)
    out: dict[str, Any] = {
        "position_rmse_mm": e["position_mm"]["rmse"],
        "position_mae_mm": e["position_mm"]["mae"],
        "position_max_mm": e["position_mm"]["max"],
        "orientation_rmse_deg": e["orientation_deg"]["rmse"],
        "orientation_mae_deg": e["orientation_deg"]["mae"],
        "n": e["position_mm"]["n"],
    }
    if truth is not None:
        t = pose_errors(pred, truth, mask)
        out["position_rmse_true_mm"] = t["position_mm"]["rmse"]
        out["orientation_rmse_true_deg"] = t["orientation_deg"]["rmse"]
    return out
