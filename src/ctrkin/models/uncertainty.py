"""Calibrated uncertainty of any FK or IK model: split-conformal intervals and an out-of-distribution
score (issue 24, goal 2; docs/planning.md: Uncertainty).

Family-agnostic by construction: it reads only a model's inputs and its errors on held-out rows, so
every family (one folder of ctrkin/families) gets it without a line of its own, and the predictor's
arrays stay where callers read them (ctrkin.models.predictor: "an uncertainty beside the pose").

- **Interval** (split conformal, Vovk et al. 2005; Lei et al. 2018). On n calibration rows that the
  network never trained on, the score s = ‖p̂ − p‖ (FK: tip position, mm) or s = max_j |ê_j − e_j| / σ_j
  (IK: joints, α errors wrapped, σ_j the calibration errors' median per joint, deg or mm). The radius
  r is the ⌈(n + 1)·level⌉-th smallest s. For a new row exchangeable with the calibration rows,
  P(s ≤ r) ≥ level (and ≤ level + 1/(n + 1) without ties): the FK tip lies in the ball of radius r
  about the prediction, the IK joints in the box ±r·σ_j. Rows of one sequence are not exchangeable
  (their errors are correlated); sequences are. So the rows are pooled with each of the m
  calibration sequences weighing 1/m, and r is that pooled distribution's quantile at
  level·(m + 1)/m (Dunn, Wasserman & Ramdas 2022, two-layer hierarchical conformal): the finite-sample
  correction counts sequences, not rows.
- **Out of distribution** (the features and kernels: ctrkin.models.ood). Per step the scored input's
  configuration and its last two changes, standardised by the training rows' spread. The FK scores
  its joints (cos and sin of each relative rotation αi − αN, the translations). An IK scores the
  target pose *and the robot's joints when it was asked* (the encoders of a loop; the joints a follow
  IK steps from): its pose alone cannot tell a 3° reversal of the inner tube from any other small
  motion at the tracker's noise, nor a joint combination never recorded that reaches a recorded
  pose. The columns fall into parts (by default, split "blocks+translations": FK configuration,
  translations, history; IK pose, joints, translations, pose history, joints history; the joints'
  translations count twice, with the rotations and in a part of their own, where a joint
  combination never recorded stands out: chosen on validation walks on two robots, docs/planning.md).
  Each part gets the mean distance to the k nearest of up to
  `max_reference` (1,000) training rows in that part (an exact k-d tree search in numba, brute
  force's distances to the bit: the same kernel for batch and streaming, so both give the same
  score), over its median on the calibration rows; the score is the largest part's (a joint
  combination never visited stands out in its few columns, not diluted by the others', and the
  reverse), plus the features' excess beyond their trained ranges in units
  of 1 % of their spread (outside the trained range is out of distribution however near: the score
  then passes every in-range neighbour distance). Joints beyond the trained ranges, combinations the
  protocols never visited and histories unlike the recorded ones (larger steps, reversals) all land
  far from every training row. The flag's threshold is the calibration rows' score at
  `1 − false_alarm` (1 % by default), so an in-range row is flagged with that probability.

Saved beside the model as `uncertainty.npz` (a model folder without one, every folder written before
this, loads as before with no uncertainty). Format 2 adds the scored input's kind and the parts; a
format-1 file (written before the IK scored the joints) loads with its own score: the FK's is the
same, an IK's scores the pose alone (`inputs == "pose"`) and ignores the joints it is given. Format
3 stores the parts as (P, 2) column spans, which may overlap (the default split, "blocks+translations",
counts the joints' translations in two parts); a format-2 file's (P + 1,) boundaries are read as the
spans between them, so it keeps its score.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.errors import ModelError
from ctrkin.models.ood import (
    DEFAULT_SPLIT,
    HISTORY,
    INPUTS,
    POSE,
    SPLITS,
    KnnIndex,
    input_width,
    mode,
    part_scores,
    part_spans,
    sequence_features,
    sequence_scores,
    spans_of,
    stream_step,
    wrap_deg,
)

FILE = "uncertainty.npz"
FORMAT = 3
FLOOR = 1e-6          # a feature that never varied in training: its spread floored (no division by 0)


def conformal_radius(scores: np.ndarray, level: float) -> float:
    """The ⌈(n + 1)·level⌉-th smallest of n calibration scores (module docstring); inf if n is too
    small for the level (an infinite score, a refused prediction, ranks last)."""
    s = np.sort(np.asarray(scores, float))
    rank = math.ceil((len(s) + 1) * level)
    return float(s[rank - 1]) if rank <= len(s) else math.inf


def scores(task: str, n_tubes: int, errors: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(T,) nonconformity scores of errors (T, 3) tip mm (FK) or (T, 2N) joints (IK, scaled by
    scale (2N,)): module docstring."""
    e = np.atleast_2d(np.asarray(errors, float))
    if task == "fk":
        return np.asarray(np.linalg.norm(e[:, :3], axis=1))
    e = e.copy()
    e[:, :n_tubes] = wrap_deg(e[:, :n_tubes])
    return np.asarray(np.max(np.abs(e) / scale, axis=1))


def grouped_radius(scores: np.ndarray, bounds: list[tuple[int, int]], level: float) -> float:
    """The conformal radius for rows that come in m sequences (rows of one sequence are correlated;
    the sequences exchangeable): the pooled-CDF quantile of Dunn, Wasserman & Ramdas (2022), each
    sequence weighing 1/m, at level·(m + 1)/m; inf if m is too small for the level."""
    m = len(bounds)
    want = level * (m + 1) / m if m else math.inf
    if want > 1.0:
        return math.inf
    s = np.asarray(scores, float)
    w = np.concatenate([np.full(b - a, 1.0 / (m * (b - a))) for a, b in bounds])
    keep = np.isfinite(s)
    order = np.argsort(s[keep])
    cum = np.cumsum(w[keep][order])
    i = int(np.searchsorted(cum, want - 1e-12))
    return float(s[keep][order][i]) if i < len(order) else math.inf


def interval(task: str, n_tubes: int, errors: np.ndarray, level: float,
             bounds: list[tuple[int, int]] | None = None) -> tuple[float, np.ndarray]:
    """The conformal radius and the IK's joint scale (empty for FK) of calibration errors (C, ·) in
    sequences `bounds` (None: every row its own); a row with a NaN error (a prediction refused)
    never counts as covered."""
    e = np.atleast_2d(np.asarray(errors, float))
    ok = np.all(np.isfinite(e), axis=1)
    scale = np.empty(0)
    if task == "ik":
        w = e[ok].copy()
        w[:, :n_tubes] = wrap_deg(w[:, :n_tubes])
        scale = np.maximum(np.median(np.abs(w), axis=0), FLOOR)
    s = np.where(ok, scores(task, n_tubes, np.where(ok[:, None], e, 0.0), scale), math.inf)
    if bounds is None:
        return conformal_radius(s, level), scale
    return grouped_radius(s, bounds, level), scale


@dataclass(frozen=True, eq=False)
class Uncertainty:
    """A model's calibrated uncertainty (module docstring).

    task: "fk" or "ik"; n_tubes: N; level: the intervals' coverage (0.9); radius: FK mm of tip
    position, IK the multiple of joint_scale; joint_scale: (2N,) IK only (deg, mm), else empty;
    inputs: the scored input's kind (ctrkin.models.ood.INPUTS: "joints" FK, "pose+joints" IK, "pose"
    an IK calibrated before the joints were scored); center, spread: (F,) standardisation of the OOD
    features; reference: (M, F) standardised training rows; k: neighbours; parts: (P, 2) column
    spans [lo, hi) of the k-NN parts (ctrkin.models.ood.part_spans; they may overlap); tau: (P,) the
    calibration rows' median k-NN distance in each part;
    lo, hi: (F,) the standardised features' trained range; threshold: the OOD flag's score;
    false_alarm: its in-range rate; n_calibration: rows the radius and threshold came from."""

    task: str
    n_tubes: int
    level: float
    radius: float
    joint_scale: np.ndarray
    inputs: str
    center: np.ndarray
    spread: np.ndarray
    reference: np.ndarray
    k: int
    parts: np.ndarray
    tau: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    threshold: float
    false_alarm: float
    n_calibration: int

    @classmethod
    def fit(cls, task: str, n_tubes: int, train_x: np.ndarray, train_bounds: list[tuple[int, int]],
            cal_x: np.ndarray, cal_bounds: list[tuple[int, int]], cal_errors: np.ndarray,
            level: float = 0.9, false_alarm: float = 0.01, k: int = 5, max_reference: int = 1000,
            inputs: str | None = None, split: str = DEFAULT_SPLIT) -> Uncertainty:
        """From training rows train_x (T, ·) and calibration rows cal_x (C, ·) with their sequences, and
        the model's errors on the calibration rows: FK (C, 3) predicted − measured tip (mm), IK (C, 2N)
        predicted − recorded joints (deg, mm). The rows are the scored inputs of `inputs` (default: FK
        "joints", (·, 2N); IK "pose+joints", (·, 6 + 2N) the target pose and the robot's joints when
        it was asked; "pose" (·, 6) scores an IK's pose alone); split: the k-NN parts
        (ctrkin.models.ood.part_spans; the default chosen on validation walks, docs/planning.md:
        Uncertainty)."""
        if not 0.0 < level < 1.0 or not 0.0 < false_alarm < 1.0:
            raise ModelError(f"level and false_alarm must lie in (0, 1), got {level}, {false_alarm}")
        inputs = inputs or ("joints" if task == "fk" else "pose+joints")
        if inputs not in INPUTS or (task == "fk") != (inputs == "joints") or split not in SPLITS:
            want = "joints" if task == "fk" else "pose+joints or pose"
            raise ModelError(f"an {task.upper()}'s scored inputs are {want} and split one of {SPLITS}; got "
                             f"{inputs!r}, {split!r}")
        width = input_width(inputs, n_tubes)
        for name, x in (("training", train_x), ("calibration", cal_x)):
            if np.atleast_2d(x).shape[1] != width:
                raise ModelError(f"{name} rows have {np.atleast_2d(x).shape[1]} columns; the {inputs!r} "
                                 f"scored input has {width}")
        err = np.atleast_2d(np.asarray(cal_errors, float))
        if len(err) != len(cal_x):
            raise ModelError(f"{len(err)} calibration errors for {len(cal_x)} calibration rows")
        radius, scale = interval(task, n_tubes, err, level, cal_bounds)
        ok = np.all(np.isfinite(err), axis=1)
        feats = sequence_features(inputs, n_tubes, train_x, train_bounds)
        center, spread = feats.mean(axis=0), np.maximum(feats.std(axis=0), FLOOR)
        pick = np.linspace(0, len(feats) - 1, min(max_reference, len(feats))).round().astype(int)
        z_train = (feats - center) / spread
        ref = np.ascontiguousarray(z_train[np.unique(pick)])
        parts = part_spans(inputs, n_tubes, split)
        unc = cls(task, n_tubes, float(level), radius, scale, inputs, center, spread, ref,
                  int(min(k, len(ref))), parts, np.ones(len(parts)), z_train.min(axis=0),
                  z_train.max(axis=0), math.inf, float(false_alarm), int(ok.sum()))
        z = np.ascontiguousarray((sequence_features(inputs, n_tubes, cal_x, cal_bounds) - center) / spread)
        if len(z):
            tau = np.maximum([np.median(part_scores(z, ref, int(lo), int(hi), unc.k)) for lo, hi in parts],
                             FLOOR)
            unc = dataclasses.replace(unc, tau=tau)
        cal = unc.ood_scores(cal_x, cal_bounds)
        thr = float(np.quantile(cal, 1.0 - false_alarm)) if len(cal) else math.inf
        return dataclasses.replace(unc, threshold=thr)

    # --- use ------------------------------------------------------------------------------------
    @property
    def scores_joints(self) -> bool:
        """Whether an IK's score takes the robot's joints beside the pose (inputs "pose+joints")."""
        return self.inputs == "pose+joints"

    @functools.cached_property
    def knn_index(self) -> KnnIndex:
        """The reference rows arranged for the searched k-NN scan (ctrkin.models.ood; built on first use)."""
        return KnnIndex.of(self.reference, self.parts)

    @functools.cached_property
    def stats(self) -> np.ndarray:
        """(4, F) center, spread, lo, hi: the kernels' one array of them."""
        return np.ascontiguousarray(np.vstack([self.center, self.spread, self.lo, self.hi]), np.float64)

    def ood_scores(self, x: np.ndarray, bounds: list[tuple[int, int]]) -> np.ndarray:
        """(T,) OOD scores of scored inputs x (T, ·) (Uncertainty.fit) in sequences `bounds` (larger:
        further from training)."""
        x = np.ascontiguousarray(np.atleast_2d(np.asarray(x, np.float64)))
        width = input_width(self.inputs, self.n_tubes)
        if x.shape[1] != width:
            raise ModelError(f"the {self.inputs!r} OOD score takes rows of {width} columns, got {x.shape[1]}")
        covered = np.zeros(len(x), bool)
        for a, b in bounds:
            covered[a:b] = True
        alone = np.flatnonzero(~covered)                 # a row of no sequence: a sequence of its own
        starts = np.array([a for a, _ in bounds] + alone.tolist(), np.int64)
        ends = np.array([b for _, b in bounds] + (alone + 1).tolist(), np.int64)
        ix = self.knn_index
        return sequence_scores(mode(self.inputs), self.n_tubes, x, starts, ends, self.stats, ix.rows, ix.tree,
                               ix.boxes, self.parts, self.k, self.tau)

    def half_widths(self) -> np.ndarray:
        """The interval's half widths: FK (3,) the ball's radius on each axis (mm); IK (2N,) deg, mm."""
        return np.full(3, self.radius) if self.task == "fk" else self.radius * self.joint_scale

    def covers(self, predicted: np.ndarray, truth: np.ndarray) -> np.ndarray:
        """(T,) bool: truth inside the interval about predicted. FK (T, ≥3) tip poses; IK (T, 2N) joints."""
        e = np.atleast_2d(predicted) - np.atleast_2d(truth)
        return scores(self.task, self.n_tubes, e, self.joint_scale) <= self.radius

    def stream(self) -> UncertainStream:
        return UncertainStream(self)

    # --- the model folder -----------------------------------------------------------------------
    def save(self, folder: str | Path) -> Path:
        """Write `uncertainty.npz` into a model folder, replacing any (written aside, then renamed)."""
        folder = Path(folder)
        fd, tmp = tempfile.mkstemp(prefix=".uncertainty.", suffix=".npz", dir=folder)
        os.close(fd)
        np.savez(tmp, format=FORMAT, task=self.task, n_tubes=self.n_tubes, level=self.level,
                 radius=self.radius, joint_scale=self.joint_scale, inputs=self.inputs, center=self.center,
                 spread=self.spread, reference=self.reference, k=self.k, parts=self.parts, tau=self.tau,
                 lo=self.lo, hi=self.hi, threshold=self.threshold, false_alarm=self.false_alarm,
                 n_calibration=self.n_calibration)
        os.replace(tmp, folder / FILE)
        return folder / FILE

    @classmethod
    def load(cls, folder: str | Path) -> Uncertainty | None:
        """The folder's uncertainty, or None where it has none (a model never calibrated). Older files
        keep their score (module docstring): format 1, FK joints or IK pose alone, two parts; format 2,
        its parts' (P + 1,) column boundaries read as the spans between them."""
        path = Path(folder) / FILE
        if not path.is_file():
            return None
        with np.load(path, allow_pickle=False) as f:
            version = int(f["format"])
            if version > FORMAT:
                raise ModelError(f"{path} has uncertainty format {version}; this ctrkin reads up "
                                 f"to {FORMAT}: update ctrkin")
            task = str(f["task"])
            if version == 1:
                inputs = "joints" if task == "fk" else "pose"
                parts = spans_of(np.array([0, int(f["n_config"]), len(f["center"])]))
            elif version == 2:
                inputs, parts = str(f["inputs"]), spans_of(f["parts"])
            else:
                inputs, parts = str(f["inputs"]), np.ascontiguousarray(f["parts"], np.int64).reshape(-1, 2)
            return cls(task, int(f["n_tubes"]), float(f["level"]), float(f["radius"]),
                       f["joint_scale"].copy(), inputs, f["center"].copy(), f["spread"].copy(),
                       np.ascontiguousarray(f["reference"]), int(f["k"]), parts,
                       f["tau"].copy(), f["lo"].copy(), f["hi"].copy(), float(f["threshold"]),
                       float(f["false_alarm"]), int(f["n_calibration"]))


class UncertainStream:
    """The OOD score one step at a time (equal to `Uncertainty.ood_scores` on the whole sequence):
    keeps the last HISTORY + 1 scored inputs (the ring and the score in one compiled call)."""

    def __init__(self, unc: Uncertainty) -> None:
        self.unc = unc
        self._mode = mode(unc.inputs)
        self._width = input_width(unc.inputs, unc.n_tubes)
        self._x_width = POSE if self._mode == 2 else self._width
        self._rows = np.zeros((HISTORY + 1, self._width))
        self._count = np.zeros(1, np.int64)
        self._z = np.empty(len(unc.center))
        self._best = np.empty(max(unc.k, 1))
        self._none = np.zeros(0)
        ix = unc.knn_index
        self._args = (unc.stats, self._z, ix.rows, ix.tree, ix.boxes, unc.parts, unc.k, unc.tau, self._best,
                      np.empty(ix.tree.shape[1], np.int64), np.empty(ix.tree.shape[1]))
        self.half_widths = unc.half_widths()          # the same every step
        self.half_widths.flags.writeable = False
        self.reset()

    def reset(self) -> None:
        self._count[0] = 0

    def step(self, x: np.ndarray, joints: np.ndarray | None = None) -> float:
        """The OOD score of the next step: x the model's input (joints (2N,) or pose (6,)); joints (2N,),
        an IK's "pose+joints" score only, the robot's joints when the pose was asked (ignored by a
        "pose" score)."""
        x = np.asarray(x, np.float64)
        if x.shape != (self._x_width,):
            raise ModelError(f"the OOD score's step takes ({self._x_width},) inputs, got {x.shape}")
        q = self._none
        if self._mode == 2:
            if joints is None:
                raise ModelError("this IK's OOD score takes the robot's joints with each pose: give them")
            q = np.asarray(joints, np.float64)
            if q.shape != (self._width - POSE,):
                raise ModelError(f"the IK's OOD score takes ({self._width - POSE},) joints, got {q.shape}")
        return stream_step(self._mode, self.unc.n_tubes, x, q, self._rows, self._count,
                           *self._args)


@dataclass(frozen=True, eq=False)
class UncertainPrediction:
    """A batch prediction with its uncertainty. value: FK (T, 6) poses, IK an IKResult; half_width:
    FK (3,) mm (the ball's radius on each axis), IK (2N,) deg, mm; ood_score, ood: (T,) the OOD score
    and whether it passes the threshold; level: the intervals' coverage."""

    value: Any
    half_width: np.ndarray
    ood_score: np.ndarray
    ood: np.ndarray
    level: float


@dataclass(frozen=True, eq=False)
class UncertainStep:
    """One streamed step with its uncertainty: value (6,) pose or IKStep; the rest as above (scalars)."""

    value: Any
    half_width: np.ndarray
    ood_score: float
    ood: bool
    level: float


def with_uncertainty(unc: Uncertainty, value: Any, x: np.ndarray, bounds: list[tuple[int, int]]
                     ) -> UncertainPrediction:
    """A batch prediction `value` of raw inputs x (T, ·) in sequences `bounds` with its uncertainty."""
    score = unc.ood_scores(x, bounds)
    return UncertainPrediction(value, unc.half_widths(), score, score > unc.threshold, unc.level)
