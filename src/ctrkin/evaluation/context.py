"""What every experiment of a reproduction shares: the data, the trained models, the TCM baseline,
the scale and cached predictions."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ctrkin.calibration.model import CalibratedTCM
from ctrkin.data.dataset import Dataset
from ctrkin.evaluation.datasets import ReproData, registered_truth
from ctrkin.evaluation.scales import ReproScale
from ctrkin.evaluation.tcm_baseline import TCMBaseline
from ctrkin.metrics import pose_errors

if TYPE_CHECKING:
    from ctrkin.inference import Kinematics


@dataclass(eq=False)
class Context:
    """tcm: the paper's TCM baseline (nominal robot, fitted registration); tcm_cal: the TCM
    calibrated on the training rows (ctrkin.calibration, μ between the tubes included);
    seconds_per_step: the calibrated TCM rows' seconds per point or step, per call (results'
    timing)."""

    data: ReproData
    models: dict[str, Kinematics]
    tcm: TCMBaseline
    figures: Path
    scale: ReproScale
    tcm_cal: CalibratedTCM
    _cache: dict[tuple[str, int], np.ndarray] = field(default_factory=dict)
    seconds_per_step: dict[str, list[float]] = field(default_factory=dict)

    def truth(self, ds: Dataset) -> np.ndarray:
        """(T, 6) noise-free tracker view of the true poses of ds."""
        key = ("truth", id(ds))
        if key not in self._cache:
            self._cache[key] = registered_truth(ds, self.data.virtual)
        return self._cache[key]

    def fk(self, name: str, ds: Dataset, gate: str | None = None) -> np.ndarray:
        """(T, 6) predictions of FK model `name` over every sequence of ds (batch, with history);
        gate: a branch model's gate (Kinematics.predict), None for its default."""
        key = (name if gate is None else f"{name}|{gate}", id(ds))
        if key not in self._cache:
            self._cache[key] = np.asarray(self.models[name].predict(ds, gate=gate), float)
        return self._cache[key]

    def tcm_continued(self, ds: Dataset) -> np.ndarray:
        """(T, 6) the nominal TCM followed along every sequence of ds (tracker frame)."""
        key = ("tcm_continued", id(ds))
        if key not in self._cache:
            poses, snaps = self.tcm.predict_continued(ds.joints(), ds.sequence_bounds())
            self._cache[key], self._cache[("tcm_snaps", id(ds))] = poses, snaps
        return self._cache[key]

    def fk_tcm_gated(self, name: str, ds: Dataset) -> np.ndarray:
        """(T, 6) the snap-aware FK model `name` with its branch state taken from the continued TCM
        (its snaps labelled by the training rule, ctrkin.families.snap_aware.labels) instead of its
        gate."""
        key = (f"{name}|tcm_gated", id(ds))
        if key not in self._cache:
            self.tcm_continued(ds)
            snaps = self._cache[("tcm_snaps", id(ds))]
            self._cache[key] = np.asarray(self.models[name].predict(ds, snaps=snaps), float)
        return self._cache[key]

    def tcm_rows(self, ds: Dataset, rows: np.ndarray, desc: str) -> tuple[np.ndarray, np.ndarray]:
        """TCM predictions (len(rows), 6) in the tracker frame and per-point times (s)."""
        pred = self.tcm.predict(ds.joints()[rows], desc=desc)
        return pred, self.tcm.last_times.copy()

    def calibrated_point(self, ds: Dataset, rows: np.ndarray) -> np.ndarray:
        """(len(rows), 6) the calibrated TCM solved point-wise (no history) at `rows` of ds (tracker
        frame); its time per point goes to seconds_per_step["tcm_calibrated"]."""
        t0 = time.perf_counter()
        point = self.tcm_cal.predict(ds.joints()[rows])
        self.seconds_per_step.setdefault("tcm_calibrated", []).append(
            (time.perf_counter() - t0) / max(len(rows), 1))
        return point

    def calibrated_continued(self, ds: Dataset) -> np.ndarray:
        """(T, 6) the calibrated TCM followed along every sequence of ds (tracker frame), the branch
        and the friction state carried; its time per step goes to
        seconds_per_step["tcm_calibrated_continued"]."""
        key = ("tcm_calibrated_continued", id(ds))
        if key not in self._cache:
            t0 = time.perf_counter()
            self._cache[key] = self.tcm_cal.predict_continued(ds.joints(), ds.sequence_bounds())
            self.seconds_per_step.setdefault("tcm_calibrated_continued", []).append(
                (time.perf_counter() - t0) / max(len(ds.frame), 1))
        return self._cache[key]


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
