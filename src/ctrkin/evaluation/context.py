"""What every experiment of a reproduction shares: the data, the trained models, the TCM baseline
and cached predictions."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.calibration.model import CalibratedTCM
from ctrkin.data.dataset import Dataset
from ctrkin.evaluation.datasets import ReproData, registered_truth
from ctrkin.evaluation.tcm_baseline import TCMBaseline
from ctrkin.evaluation.training_runs import FK_BRANCH, FK_PAPER, IK_FOLLOW, IK_PAPER, IK_REFINED
from ctrkin.inference import Kinematics
from ctrkin.metrics import pose_errors
from ctrkin.models.branch_labels import branch_labels

# learned rows of every FK / IK experiment: results name -> model folder. The recommended model's
# figures are also written under the headline name "lstm_mlp" (results.json keeps its keys).
FK_ROWS = {"lstm_mlp_paper": FK_PAPER, "lstm_mlp_branch": FK_BRANCH}
IK_ROWS = {"lstm_mlp_paper": IK_PAPER, "lstm_mlp_refined": IK_REFINED, "follow_mlp": IK_FOLLOW}
# the follow IK (from the current joints, ctrkin.models.follow) reaches the targets the direct
# networks miss by millimetres (docs/reproduction.md)
RECOMMENDED = {"fk": "lstm_mlp_branch", "ik": "follow_mlp"}
# ablation rows: the snap-aware model's heads, branch state from the nominal TCM continued along the
# same joint path (physics gate; batch evaluation only, not a streaming model), and from the model's
# learned gate instead of its fold gate (ctrkin.models.fold_gate)
TCM_GATED = "lstm_mlp_branch_tcm_gate"
LEARNED_GATE = "lstm_mlp_branch_learned_gate"
HEADLINE = "lstm_mlp"


@dataclass(eq=False)
class Context:
    """tcm: the paper's TCM baseline (nominal robot, fitted registration); tcm_cal: the TCM
    calibrated on the training rows (ctrkin.calibration, μ between the tubes included), None where
    a reproduction skips it."""

    data: ReproData
    models: dict[str, Kinematics]
    tcm: TCMBaseline
    figures: Path
    tcm_cal: CalibratedTCM | None = None
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

    def fk_rows(self, ds: Dataset) -> dict[str, np.ndarray]:
        """(T, 6) predictions of every learned FK row (FK_ROWS) over ds."""
        out = {name: self.fk(folder, ds) for name, folder in FK_ROWS.items()}
        out[TCM_GATED] = self.fk_tcm_gated(ds)
        out[LEARNED_GATE] = self.fk(FK_BRANCH, ds, gate="learned")
        return out

    def tcm_continued(self, ds: Dataset) -> np.ndarray:
        """(T, 6) the nominal TCM followed along every sequence of ds (tracker frame)."""
        key = ("tcm_continued", id(ds))
        if key not in self._cache:
            poses, snaps = self.tcm.predict_continued(ds.joints(), ds.sequence_bounds())
            self._cache[key], self._cache[("tcm_snaps", id(ds))] = poses, snaps
        return self._cache[key]

    def fk_tcm_gated(self, ds: Dataset) -> np.ndarray:
        """(T, 6) the snap-aware FK model with its branch state taken from the continued TCM (its
        snaps labelled by the training rule, ctrkin.models.branch_labels) instead of its gate."""
        key = ("fk_tcm_gated", id(ds))
        if key not in self._cache:
            self.tcm_continued(ds)
            snaps = self._cache[("tcm_snaps", id(ds))]
            n = ds.n_tubes
            q = ds.joints()
            states, _ = branch_labels(q[:, 0] - q[:, n - 1], snaps, ds.sequence_bounds())
            self._cache[key] = np.asarray(self.models[FK_BRANCH].predict(ds, branch_states=states), float)
        return self._cache[key]

    def tcm_rows(self, ds: Dataset, rows: np.ndarray, desc: str) -> tuple[np.ndarray, np.ndarray]:
        """TCM predictions (len(rows), 6) in the tracker frame and per-point times (s)."""
        pred = self.tcm.predict(ds.joints()[rows], desc=desc)
        return pred, self.tcm.last_times.copy()

    def calibrated_rows(self, ds: Dataset, rows: np.ndarray) -> dict[str, np.ndarray]:
        """The calibrated TCM's rows at `rows` of ds (none without it): `tcm_calibrated`, point-wise
        (no history), and `tcm_calibrated_continued`, followed along every sequence (the branch
        and the friction state carried). Times per point and per step go to seconds_per_step."""
        if self.tcm_cal is None:
            return {}
        t0 = time.perf_counter()
        point = self.tcm_cal.predict(ds.joints()[rows])
        self.seconds_per_step.setdefault("tcm_calibrated", []).append(
            (time.perf_counter() - t0) / max(len(rows), 1))
        return {"tcm_calibrated": point, "tcm_calibrated_continued": self.calibrated_continued(ds)[rows]}

    def calibrated_continued(self, ds: Dataset) -> np.ndarray:
        """(T, 6) the calibrated TCM followed along every sequence of ds (tracker frame)."""
        key = ("tcm_calibrated_continued", id(ds))
        if key not in self._cache:
            assert self.tcm_cal is not None
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


def with_headline(rows: dict[str, Any], task: str) -> dict[str, Any]:
    """rows plus the recommended model's entry again under HEADLINE, naming the model it is."""
    name = RECOMMENDED[task]
    return {HEADLINE: {**rows[name], "model": name}, **rows}
