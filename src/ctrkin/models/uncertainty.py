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
- **Out of distribution**. Per step the features g(x_t) and their last two changes (FK: cos and sin of
  each relative rotation αi − αN, the translations; IK: the target pose), standardised by the training
  rows' spread. The configuration part g and the history part each get the mean distance to the k
  nearest of up to `max_reference` (1,000) training rows in that part (brute force in numba: the same kernel
  for batch and streaming, so both give the same score), over its median on the calibration rows;
  the score is the larger of the two (a joint combination never visited stands out in the few
  configuration columns, not diluted by the history's, and the reverse), plus the features' excess
  beyond their trained ranges in units of 1 % of their spread (outside the trained range is out of
  distribution however near: the score then passes every in-range neighbour distance).
  Joints beyond the trained ranges, combinations the protocols never visited and histories unlike
  the recorded ones (larger steps, reversals) all land far from every training row. The flag's
  threshold is the calibration rows' score at `1 − false_alarm` (1 % by default), so an in-range row
  is flagged with that probability.

Saved beside the model as `uncertainty.npz` (a model folder without one, every folder written before
this, loads as before with no uncertainty).
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numba
import numpy as np

from ctrkin.errors import ModelError

FILE = "uncertainty.npz"
FORMAT = 1
HISTORY = 2           # changes of g over the last HISTORY steps are features (the "history" part)
RANGE_UNIT = 0.01    # a feature 1 % of its training spread beyond its trained range adds 1 to the score
FLOOR = 1e-6          # a feature that never varied in training: its spread floored (no division by 0)


def wrap_deg(x: np.ndarray) -> np.ndarray:
    """Angles (deg) wrapped into [−180, 180)."""
    return (np.asarray(x, float) + 180.0) % 360.0 - 180.0


def base_features(task: str, n_tubes: int, x: np.ndarray) -> np.ndarray:
    """g(x) (T, G) of raw inputs x (T, 2N) joints (FK) or (T, 6) target poses (IK): module docstring.
    FK: cos, sin of αi − αN (i < N; a common turn of every tube is the same robot turned, which the
    outer-tube frame makes exact), then βi/10 mm (a tenth of a degree's scale is set by the standardising)."""
    x = np.atleast_2d(np.asarray(x, float))
    if task == "ik":
        return x.copy()
    rel = np.deg2rad(x[:, :n_tubes - 1] - x[:, n_tubes - 1:n_tubes])
    return np.hstack([np.cos(rel), np.sin(rel), x[:, n_tubes:]])


def step_changes(task: str, n_tubes: int, x: np.ndarray) -> np.ndarray:
    """d(x_t, x_{t−1}) (T−1, D): the change between consecutive raw inputs x (T, ·) that the history
    features stack (FK: relative rotations wrapped, deg, and translations, mm; IK: pose change)."""
    x = np.atleast_2d(np.asarray(x, float))
    d = np.diff(x, axis=0)
    if task == "fk":
        rel = x[:, :n_tubes - 1] - x[:, n_tubes - 1:n_tubes]
        return np.hstack([wrap_deg(np.diff(rel, axis=0)), d[:, n_tubes:]])
    return d


def sequence_features(task: str, n_tubes: int, x: np.ndarray, bounds: list[tuple[int, int]]) -> np.ndarray:
    """OOD features (T, F) of rows x (T, ·) split into sequences [a, b): g(x_t) and the changes
    d_t, …, d_{t−HISTORY+1} (zero before a sequence's start: a robot at rest before it)."""
    g = base_features(task, n_tubes, x)
    dim = step_changes(task, n_tubes, x[:2]).shape[1] if len(x) >= 2 else (
        2 * n_tubes - 1 if task == "fk" else x.shape[1])
    hist = np.zeros((len(x), HISTORY * dim))
    for a, b in bounds:
        d = step_changes(task, n_tubes, x[a:b])
        for h in range(HISTORY):
            if b - a > 1 + h:
                hist[a + 1 + h:b, h * dim:(h + 1) * dim] = d[:len(d) - h]
    return np.hstack([g, hist])


@numba.njit(cache=True)
def _knn_score(z: np.ndarray, ref: np.ndarray, lo: int, hi: int, k: int, best: np.ndarray) -> float:
    """Mean Euclidean distance of z (F,) to its k nearest rows of ref (M, F), over columns lo..hi−1;
    best (k,) scratch."""
    for j in range(k):
        best[j] = np.inf
    for m in range(ref.shape[0]):
        s = 0.0
        lim = best[k - 1]
        for f in range(lo, hi):
            e = z[f] - ref[m, f]
            s += e * e
            if s >= lim:          # already further than the k-th nearest: the rest cannot help
                break
        if s < lim:
            j = k - 1
            while j > 0 and best[j - 1] > s:
                best[j] = best[j - 1]
                j -= 1
            best[j] = s
    tot = 0.0
    for j in range(k):
        tot += math.sqrt(best[j])
    return tot / k


@numba.njit(cache=True)
def _stream_features(fk: bool, n: int, rows: np.ndarray, count: int, center: np.ndarray, spread: np.ndarray,
                     out: np.ndarray) -> None:
    """The standardised OOD features of the last of `count` (≤ HISTORY + 1) raw inputs rows (·, W),
    oldest first, into out (F,): `sequence_features` of one row, for the stream."""
    last = rows[count - 1]
    f = 0
    if fk:
        for i in range(n - 1):
            out[f] = math.cos(math.radians(last[i] - last[n - 1]))
            out[f + n - 1] = math.sin(math.radians(last[i] - last[n - 1]))
            f += 1
        f += n - 1
        for i in range(n):
            out[f] = last[n + i]
            f += 1
        dim = 2 * n - 1
    else:
        for i in range(rows.shape[1]):
            out[f] = last[i]
            f += 1
        dim = rows.shape[1]
    for h in range(HISTORY):
        a, b = count - 2 - h, count - 1 - h          # the change from row a to row b
        for j in range(dim):
            v = 0.0
            if a >= 0:
                if fk and j < n - 1:
                    d = (rows[b, j] - rows[b, n - 1]) - (rows[a, j] - rows[a, n - 1])
                    v = (d + 180.0) % 360.0 - 180.0
                elif fk:
                    v = rows[b, n + j - (n - 1)] - rows[a, n + j - (n - 1)]
                else:
                    v = rows[b, j] - rows[a, j]
            out[f] = v
            f += 1
    for j in range(out.shape[0]):
        out[j] = (out[j] - center[j]) / spread[j]


@numba.njit(cache=True)
def _score(z: np.ndarray, ref: np.ndarray, g: int, k: int, tau: np.ndarray, lo: np.ndarray, hi: np.ndarray,
           best: np.ndarray) -> float:
    """The OOD score of standardised features z (F,): the larger of the configuration's (columns < g)
    and the history's k-NN distance, each over its calibration median tau (2,), plus the excess
    beyond the trained range [lo, hi] (F,) in units of RANGE_UNIT."""
    a = _knn_score(z, ref, 0, g, k, best) / tau[0]
    b = _knn_score(z, ref, g, ref.shape[1], k, best) / tau[1]
    excess = 0.0
    for f in range(z.shape[0]):
        excess += max(z[f] - hi[f], 0.0) + max(lo[f] - z[f], 0.0)
    return max(a, b) + excess / RANGE_UNIT


@numba.njit(cache=True)
def _stream_score(fk: bool, n: int, rows: np.ndarray, count: int, center: np.ndarray, spread: np.ndarray,
                  z: np.ndarray, ref: np.ndarray, g: int, k: int, tau: np.ndarray, lo: np.ndarray,
                  hi: np.ndarray, best: np.ndarray) -> float:
    """One streamed step's OOD score (one call: the features into z, then the score)."""
    _stream_features(fk, n, rows, count, center, spread, z)
    return _score(z, ref, g, k, tau, lo, hi, best)


@numba.njit(cache=True)
def _part_scores(Z: np.ndarray, ref: np.ndarray, lo: int, hi: int, k: int) -> np.ndarray:
    """(T,) k-NN distances of rows Z (T, F) over columns lo..hi−1."""
    out = np.empty(Z.shape[0])
    best = np.empty(k)
    for t in range(Z.shape[0]):
        out[t] = _knn_score(Z[t], ref, lo, hi, k, best)
    return out


@numba.njit(cache=True)
def _scores(Z: np.ndarray, ref: np.ndarray, g: int, k: int, tau: np.ndarray, lo: np.ndarray,
            hi: np.ndarray) -> np.ndarray:
    out = np.empty(Z.shape[0])
    best = np.empty(k)
    for t in range(Z.shape[0]):
        out[t] = _score(Z[t], ref, g, k, tau, lo, hi, best)
    return out


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
    center, spread: (F,) standardisation of the OOD features; reference: (M, F) standardised training
    rows; k: neighbours; n_config: the configuration's features (the first columns; the rest are the
    history's); tau: (2,) the calibration rows' median k-NN distance in each part; lo, hi: (F,) the
    standardised features' trained range;
    threshold: the OOD flag's score; false_alarm: its in-range rate;
    n_calibration: rows the radius and threshold came from."""

    task: str
    n_tubes: int
    level: float
    radius: float
    joint_scale: np.ndarray
    center: np.ndarray
    spread: np.ndarray
    reference: np.ndarray
    k: int
    n_config: int
    tau: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    threshold: float
    false_alarm: float
    n_calibration: int

    @classmethod
    def fit(cls, task: str, n_tubes: int, train_x: np.ndarray, train_bounds: list[tuple[int, int]],
            cal_x: np.ndarray, cal_bounds: list[tuple[int, int]], cal_errors: np.ndarray,
            level: float = 0.9, false_alarm: float = 0.01, k: int = 5, max_reference: int = 1000
            ) -> Uncertainty:
        """From training rows train_x (T, ·) and calibration rows cal_x (C, ·) with their sequences, and
        the model's errors on the calibration rows: FK (C, 3) predicted − measured tip (mm), IK (C, 2N)
        predicted − recorded joints (deg, mm)."""
        if not 0.0 < level < 1.0 or not 0.0 < false_alarm < 1.0:
            raise ModelError(f"level and false_alarm must lie in (0, 1), got {level}, {false_alarm}")
        err = np.atleast_2d(np.asarray(cal_errors, float))
        if len(err) != len(cal_x):
            raise ModelError(f"{len(err)} calibration errors for {len(cal_x)} calibration rows")
        radius, scale = interval(task, n_tubes, err, level, cal_bounds)
        ok = np.all(np.isfinite(err), axis=1)
        feats = sequence_features(task, n_tubes, train_x, train_bounds)
        center, spread = feats.mean(axis=0), np.maximum(feats.std(axis=0), FLOOR)
        pick = np.linspace(0, len(feats) - 1, min(max_reference, len(feats))).round().astype(int)
        z_train = (feats - center) / spread
        ref = np.ascontiguousarray(z_train[np.unique(pick)])
        g = base_features(task, n_tubes, train_x[:1]).shape[1]
        unc = cls(task, n_tubes, float(level), radius, scale, center, spread, ref, int(min(k, len(ref))),
                  g, np.ones(2), z_train.min(axis=0), z_train.max(axis=0), math.inf, float(false_alarm),
                  int(ok.sum()))
        z = np.ascontiguousarray((sequence_features(task, n_tubes, cal_x, cal_bounds) - center) / spread)
        if len(z):
            tau = np.maximum([np.median(_part_scores(z, ref, lo, hi, unc.k))
                              for lo, hi in ((0, g), (g, ref.shape[1]))], FLOOR)
            unc = cls(**{**unc.__dict__, "tau": tau})
        cal = unc.ood_scores(cal_x, cal_bounds)
        thr = float(np.quantile(cal, 1.0 - false_alarm)) if len(cal) else math.inf
        return cls(**{**unc.__dict__, "threshold": thr})

    # --- use ------------------------------------------------------------------------------------
    def ood_scores(self, x: np.ndarray, bounds: list[tuple[int, int]]) -> np.ndarray:
        """(T,) OOD scores of rows x (T, ·) in sequences `bounds` (larger: further from training)."""
        z = (sequence_features(self.task, self.n_tubes, x, bounds) - self.center) / self.spread
        return _scores(np.ascontiguousarray(z), self.reference, self.n_config, self.k, self.tau, self.lo,
                       self.hi)

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
                 radius=self.radius, joint_scale=self.joint_scale, center=self.center, spread=self.spread,
                 reference=self.reference, k=self.k, n_config=self.n_config, tau=self.tau, lo=self.lo,
                 hi=self.hi,
                 threshold=self.threshold,
                 false_alarm=self.false_alarm, n_calibration=self.n_calibration)
        os.replace(tmp, folder / FILE)
        return folder / FILE

    @classmethod
    def load(cls, folder: str | Path) -> Uncertainty | None:
        """The folder's uncertainty, or None where it has none (a model never calibrated)."""
        path = Path(folder) / FILE
        if not path.is_file():
            return None
        with np.load(path, allow_pickle=False) as f:
            if int(f["format"]) > FORMAT:
                raise ModelError(f"{path} has uncertainty format {int(f['format'])}; this ctrkin reads up "
                                 f"to {FORMAT}: update ctrkin")
            return cls(str(f["task"]), int(f["n_tubes"]), float(f["level"]), float(f["radius"]),
                       f["joint_scale"].copy(), f["center"].copy(), f["spread"].copy(),
                       np.ascontiguousarray(f["reference"]), int(f["k"]), int(f["n_config"]),
                       f["tau"].copy(), f["lo"].copy(), f["hi"].copy(), float(f["threshold"]),
                       float(f["false_alarm"]), int(f["n_calibration"]))


class UncertainStream:
    """The OOD score one step at a time (equal to `Uncertainty.ood_scores` on the whole sequence):
    keeps the last HISTORY + 1 raw inputs."""

    def __init__(self, unc: Uncertainty) -> None:
        self.unc = unc
        self._fk = unc.task == "fk"
        width = 2 * unc.n_tubes if self._fk else 6
        self._rows = np.zeros((HISTORY + 1, width))
        self._z = np.empty(len(unc.center))
        self._best = np.empty(max(unc.k, 1))
        self.half_widths = unc.half_widths()          # the same every step
        self.half_widths.flags.writeable = False
        self.reset()

    def reset(self) -> None:
        self._count = 0

    def step(self, x: np.ndarray) -> float:
        """The OOD score of raw input x (joints (2N,) or pose (6,)) as the next step."""
        u, rows = self.unc, self._rows
        if self._count == HISTORY + 1:
            rows[:-1] = rows[1:]
        else:
            self._count += 1
        rows[self._count - 1] = x
        return float(_stream_score(self._fk, u.n_tubes, rows, self._count, u.center, u.spread, self._z,
                                   u.reference, u.n_config, u.k, u.tau, u.lo, u.hi, self._best))


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
