"""Calibrating a trained model's uncertainty, and predicting with it (issue 24, goal 2; the method:
ctrkin.models.uncertainty, docs/planning.md: Uncertainty).

    from ctrkin.inference.uncertainty import calibrate
    unc = calibrate(fk, ds, train_rows, cal_rows)     # rows of ds: the model's training and a held-out part
    unc.save(fk.path)                                 # beside the model: Kinematics.load reads it
    fk = ctrkin.Kinematics.load(fk.path)
    pred = fk.predict_uncertain(Q)                    # poses (T, 6), radius mm, ood score and flag (T,)
    fk.reset()
    s = fk.step_uncertain(q)                          # one step: the pose, the same radius, score, flag
    ik.step_uncertain(pose, joints=q_now)             # an IK's score takes the robot's joints too

An IK's OOD score takes the target pose and the robot's joints when it was asked (ctrkin.models.ood):
from a Dataset, the recorded joints of the row before (a sequence's first row: its own, where the
robot starts); `joints=` gives them otherwise; without them, the IK's own answers stand in (the
joints a loop that executes each answer is at), the first row at the start joints given, else its
own answer.

The calibration rows must be rows the network never trained on (a by-sequence split's validation
part, or a part of its own): their errors set the interval; the training rows set what "in
distribution" means.
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.errors import ModelError
from ctrkin.models.ik import IKResult
from ctrkin.models.ood import DEFAULT_SPLIT, joints_before
from ctrkin.models.uncertainty import UncertainPrediction, UncertainStep, Uncertainty

if TYPE_CHECKING:
    from ctrkin.inference.kinematics import Kinematics

__all__ = ["UncertainPrediction", "UncertainStep", "Uncertainty", "calibrate", "ood_scores", "predict_rows",
           "scored_inputs"]


def row_runs(sid: np.ndarray, rows: np.ndarray) -> list[tuple[int, int]]:
    """Sequences [a, b) (positions in `rows`) of the selected rows (in order): a new one where
    sequence_id changes or a row is skipped."""
    rows = np.asarray(rows)
    if len(rows) == 0:
        return []
    cut = np.flatnonzero((np.diff(rows) != 1) | (np.diff(sid[rows]) != 0)) + 1
    edges = [0, *cut.tolist(), len(rows)]
    return list(itertools.pairwise(edges))


def raw_inputs(kin: Kinematics, ds: Dataset) -> np.ndarray:
    """The model's raw inputs of every row of ds: joints (T, 2N) (FK) or the poses it takes (T, 6) (IK),
    as its predictor reads them."""
    return np.asarray(kin.predictor.raw_inputs(ds, None)[0])  # type: ignore[attr-defined]


def scored_inputs(kin: Kinematics, ds: Dataset, inputs: str) -> np.ndarray:
    """The OOD score's inputs of every row of ds (ctrkin.models.ood.INPUTS): FK joints (T, 2N); IK
    "pose" the poses (T, 6); IK "pose+joints" (T, 6 + 2N) the poses and the robot's joints when each
    was asked (the recorded joints of the row before; a sequence's first row its own)."""
    x = raw_inputs(kin, ds)
    if inputs != "pose+joints":
        return x
    return np.hstack([x, joints_before(ds.joints(), ds.sequence_bounds())])


def predict_rows(kin: Kinematics, ds: Dataset) -> tuple[np.ndarray, np.ndarray]:
    """The model's prediction of every row of ds, sequence by sequence with history, and the truth it
    is judged against: FK measured tip (T, 3) mm; IK recorded joints (T, 2N) (deg, mm)."""
    if kin.task == "fk":
        return np.asarray(kin.predict(ds))[:, :3], ds.poses()[:, :3]
    options = {}
    if "start_joints" in kin.predictor.accepts.get("predict", frozenset()):
        options["start_joints"] = ds.joints()[[a for a, _ in ds.sequence_bounds()]]
    res = kin.predict(ds, None, False, **options)
    assert isinstance(res, IKResult)
    return res.joints, ds.joints()


def calibrate(kin: Kinematics, ds: Dataset, train_rows: np.ndarray, cal_rows: np.ndarray,
              level: float = 0.9, false_alarm: float = 0.01, inputs: str | None = None,
              split: str = DEFAULT_SPLIT) -> Uncertainty:
    """The model's uncertainty (ctrkin.models.uncertainty.Uncertainty) from rows of ds: train_rows
    (the rows it trained on: what is in distribution), cal_rows (held-out rows: the interval and the
    flag's threshold). Rows are indices into ds.frame, each set in time order. inputs, split: the
    OOD score's (Uncertainty.fit; an IK's default scores the pose and the robot's joints; the default
    split, ctrkin.models.ood.DEFAULT_SPLIT, counts the joints' translations in a part of their own too)."""
    kin.check_robot(ds.robot)
    train_rows, cal_rows = np.sort(np.asarray(train_rows)), np.sort(np.asarray(cal_rows))
    if np.intersect1d(train_rows, cal_rows).size:
        raise ModelError("calibration rows must be held out: some are training rows")
    pred, truth = predict_rows(kin, ds)
    sid = ds.frame["sequence_id"].to_numpy()
    inputs = inputs or ("joints" if kin.task == "fk" else "pose+joints")
    x = scored_inputs(kin, ds, inputs)
    return Uncertainty.fit(kin.task, ds.n_tubes, x[train_rows], row_runs(sid, train_rows),
                           x[cal_rows], row_runs(sid, cal_rows), pred[cal_rows] - truth[cal_rows],
                           level=level, false_alarm=false_alarm, inputs=inputs, split=split)


def ood_scores(unc: Uncertainty, kin: Kinematics, ds: Dataset, rows: np.ndarray | None = None) -> np.ndarray:
    """(R,) OOD scores of rows of ds (default all), each run of consecutive rows one sequence."""
    sid = ds.frame["sequence_id"].to_numpy()
    rows = np.arange(len(sid)) if rows is None else np.sort(np.asarray(rows))
    return unc.ood_scores(scored_inputs(kin, ds, unc.inputs)[rows], row_runs(sid, rows))
