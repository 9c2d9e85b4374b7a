"""Cleaning of robot logs, as the paper did for its hardware data (Sec. III.A).

The paper averaged five tracker readings per joint sample and removed outliers caused by encoder
errors. Here, on (R,) readings grouped into samples and then per sequence:

1. Repeated readings: consecutive readings of one joint sample (identical joints, to repeat_tol, the
   encoder's resolution, and the same `step` where the log has one) are averaged; readings of
   different joints are never averaged, even where the log gives them one step (`distinct_in_step`
   counts them; the importer then numbers the steps itself and warns): joints and positions by
   the mean, orientations by the mean tip tangent. Within a sample of three or more readings, a
   reading farther from the sample's median position than max(k·1.4826·MAD, floor) is left out
   first. The spread of the readings about their
   mean is the tracker noise estimate reported in meta["noise"].
2. Encoder glitches: a joint value far from the midpoint of its neighbours while the neighbours
   agree with each other (|q_t − (q_t−1 + q_t+1)/2| > thr and |q_t+1 − q_t−1| ≤ thr), with
   thr = max(factor · median |Δq| of the sequence, floor). A real motion is a step (the neighbours
   disagree), not a one-sample spike, so it is never flagged.
3. Pose outliers (Hampel filter): a sample whose position (or tip tangent) lies farther from the
   centred moving median of its sequence than max(k·1.4826·MAD of those distances, floor). A moving
   median keeps steps, so a snap (the tip jumping to another branch and staying) is never removed.
   The window never reaches across a commanded joint jump (|Δα| > pose_break_deg or |Δβ| >
   pose_break_mm, e.g. from the end of one sweep to the start of the next, or between random
   points): there the neighbours are not the same motion, and a coordinate-wise median of two
   different motions is a point neither visited; runs shorter than the window are not tested, nor
   the first and last window // 2 samples of a run (their window is one-sided: on a moving tip its
   median lags by a step and would flag the run's ends).
4. Snaps: |ΔT(L)| > 10° between consecutive samples (the paper's definition), counted only where the
   joints moved by less than the threshold themselves (a large joint step, as between random points,
   says nothing about snapping) and the tip is off the axis (T(L) is undefined on the z axis).
"""

from __future__ import annotations

import itertools
from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np
import pandas as pd

from ctrkin.errors import DatasetError
from ctrkin.geometry import tip_azimuth

MAD_TO_SIGMA = 1.4826  # MAD of a normal distribution times this is its standard deviation


@dataclass(frozen=True)
class CleaningConfig:
    """Thresholds of the cleaning rules (module docstring). Lengths mm, angles deg."""

    average_repeats: bool = True
    repeat_tol: float = 1e-6          # deg / mm: consecutive joints this close are one command
    mad_k: float = 6.0                # robust z-score beyond which a reading or sample is an outlier
    glitch_factor: float = 5.0        # a glitch is off by more than this many typical joint steps ...
    glitch_floor_deg: float = 2.0     # ... and by more than these floors
    glitch_floor_mm: float = 1.0
    pose_window: int = 5              # samples in the centred moving median (odd, >= 3)
    pose_floor_mm: float = 1.0        # positions closer than this to the moving median are kept
    pose_floor_deg: float = 5.0       # tangents closer than this to the moving median are kept
    pose_break_deg: float = 10.0      # a joint jump larger than this ends a run of the pose rule ...
    pose_break_mm: float = 2.0        # ... or than this for a translation
    outliers: Literal["drop", "flag"] = "drop"   # drop (the paper) or keep with outlier = True
    snap_threshold_deg: float = 10.0  # the paper's snap definition: |ΔT(L)| above this
    snap_min_radius_mm: float = 2.0   # T(L) is only defined with the tip this far off the z axis

    def __post_init__(self) -> None:
        positive = ("repeat_tol", "mad_k", "glitch_factor", "glitch_floor_deg", "glitch_floor_mm",
                    "pose_floor_mm", "pose_floor_deg", "snap_threshold_deg", "pose_break_deg",
                    "pose_break_mm")
        for name in positive:
            v = getattr(self, name)
            if not (isinstance(v, int | float) and np.isfinite(v) and v > 0):
                raise DatasetError(f"CleaningConfig.{name} must be a positive number, got {v!r}")
        if self.snap_min_radius_mm < 0:
            raise DatasetError(f"CleaningConfig.snap_min_radius_mm must be >= 0, "
                               f"got {self.snap_min_radius_mm}")
        if not isinstance(self.pose_window, int) or self.pose_window < 3 or self.pose_window % 2 == 0:
            raise DatasetError(f"CleaningConfig.pose_window must be an odd integer >= 3, "
                               f"got {self.pose_window!r}")
        if self.outliers not in ("drop", "flag"):
            raise DatasetError(f"CleaningConfig.outliers must be 'drop' or 'flag', got {self.outliers!r}")

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


@dataclass(frozen=True)
class Samples:
    """Readings averaged into samples. joints (S, 2N) deg/mm; position (S, 3) mm; tangent (S, 3)
    unit; first (S,) index of each sample's first reading; n_readings (S,); rejected: readings left
    out of the means; position_std_mm / tangent_std_deg: pooled spread of the readings (NaN when
    no sample has two readings)."""

    joints: np.ndarray
    position: np.ndarray
    tangent: np.ndarray
    first: np.ndarray
    n_readings: np.ndarray
    rejected: int
    position_std_mm: float
    tangent_std_deg: float


def repeat_groups(sequence: np.ndarray, joints: np.ndarray, step: np.ndarray | None,
                  tol: float) -> np.ndarray:
    """(R,) sample index of each reading: a new sample starts with a new sequence, a new `step`
    (when the log has one) or joints differing by more than `tol` (deg / mm, the encoder's
    resolution) from the previous reading. joints: (R, 2N)."""
    new = np.ones(len(sequence), dtype=bool)
    if len(sequence) > 1:
        same = (sequence[1:] == sequence[:-1]) & _same_joints(joints, tol)
        if step is not None:
            same &= step[1:] == step[:-1]
        new[1:] = ~same
    return np.cumsum(new) - 1


def _same_joints(joints: np.ndarray, tol: float) -> np.ndarray:
    """(R − 1,) consecutive readings whose joints agree to `tol`."""
    return np.abs(np.diff(joints, axis=0)).max(axis=1, initial=0.0) <= tol


def distinct_in_step(sequence: np.ndarray, joints: np.ndarray, step: np.ndarray | None,
                     tol: float) -> np.ndarray:
    """(R,) readings that repeat the previous reading's step (same sequence) with joints differing by
    more than `tol`: distinct configurations the log numbered as one sample (never averaged)."""
    out = np.zeros(len(sequence), dtype=bool)
    if step is not None and len(sequence) > 1:
        out[1:] = ((sequence[1:] == sequence[:-1]) & (step[1:] == step[:-1])
                   & ~_same_joints(joints, tol))
    return out


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (deg) between unit vectors (..., 3)."""
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.degrees(np.arctan2(cross, np.sum(a * b, axis=-1)))


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def average_readings(groups: np.ndarray, joints: np.ndarray, position: np.ndarray,
                     tangent: np.ndarray, cfg: CleaningConfig) -> Samples:
    """Average the readings (R,) of each group (contiguous, numbered 0..S-1) into one sample."""
    g = pd.Series(groups)
    size = g.map(g.value_counts()).to_numpy()
    pos = pd.DataFrame(position)
    med = pos.groupby(groups).median().to_numpy()[groups]
    dist = np.linalg.norm(position - med, axis=1)
    mad = pd.Series(dist).groupby(groups).median().to_numpy()[groups]
    keep = ~((size >= 3) & (dist > np.maximum(cfg.mad_k * MAD_TO_SIGMA * mad, cfg.pose_floor_mm)))
    kept_per_group = np.bincount(groups, weights=keep, minlength=int(groups.max()) + 1)
    keep |= kept_per_group[groups] == 0  # never lose a whole sample to this rule
    gk = groups[keep]
    joints_m = pd.DataFrame(joints[keep]).groupby(gk).mean().to_numpy()
    pos_m = pd.DataFrame(position[keep]).groupby(gk).mean().to_numpy()
    tan_m = _unit(pd.DataFrame(tangent[keep]).groupby(gk).mean().to_numpy())
    n_kept = np.bincount(gk)
    first = np.r_[0, np.nonzero(np.diff(groups))[0] + 1]
    dof = int((n_kept - 1).sum())
    if dof > 0:
        dev = position[keep] - pos_m[gk]
        pos_std = float(np.sqrt((dev**2).sum() / (3 * dof)))
        ang = _angle_deg(tangent[keep], tan_m[gk])
        tan_std = float(np.sqrt((ang**2).sum() / dof))
    else:
        pos_std = tan_std = float("nan")
    return Samples(joints=joints_m, position=pos_m, tangent=tan_m, first=first,
                   n_readings=n_kept.astype(np.int64), rejected=int((~keep).sum()),
                   position_std_mm=pos_std, tangent_std_deg=tan_std)


def glitch_mask(joints: np.ndarray, n_tubes: int, cfg: CleaningConfig) -> np.ndarray:
    """(S,) True where a joint spikes away from its neighbours (rule 2; one sequence, joints (S, 2N)
    deg/mm). The first and last samples of a sequence have one neighbour and are never flagged."""
    s = len(joints)
    out = np.zeros(s, dtype=bool)
    if s < 3:
        return out
    step = np.abs(np.diff(joints, axis=0))
    floors = np.r_[np.full(n_tubes, cfg.glitch_floor_deg), np.full(n_tubes, cfg.glitch_floor_mm)]
    thr = np.maximum(cfg.glitch_factor * np.median(step, axis=0), floors)
    prev, cur, nxt = joints[:-2], joints[1:-1], joints[2:]
    spike = (np.abs(cur - 0.5 * (prev + nxt)) > thr) & (np.abs(nxt - prev) <= thr)
    out[1:-1] = spike.any(axis=1)
    return out


def _hampel_distance(values: np.ndarray, window: int, angular: bool) -> np.ndarray:
    """(S,) distance of each sample to the centred moving median (mm, or deg for unit tangents)."""
    med = pd.DataFrame(values).rolling(window, center=True, min_periods=1).median().to_numpy()
    if angular:
        return _angle_deg(values, _unit(med))
    return np.linalg.norm(values - med, axis=1)


def pose_outlier_mask(position: np.ndarray, tangent: np.ndarray, cfg: CleaningConfig) -> np.ndarray:
    """(S,) True for samples far from their neighbours (Hampel rule on one sequence)."""
    if len(position) < cfg.pose_window:
        return np.zeros(len(position), dtype=bool)
    out = np.zeros(len(position), dtype=bool)
    for values, floor, angular in ((position, cfg.pose_floor_mm, False),
                                   (tangent, cfg.pose_floor_deg, True)):
        d = _hampel_distance(values, cfg.pose_window, angular)
        thr = max(cfg.mad_k * MAD_TO_SIGMA * float(np.median(d)), floor)
        out |= d > thr
    half = cfg.pose_window // 2
    out[:half] = False
    out[len(out) - half:] = False
    return out


def continuous_runs(joints: np.ndarray, n_tubes: int, cfg: CleaningConfig) -> list[tuple[int, int]]:
    """[start, end) runs of one sequence (joints (S, 2N) deg/mm) without a commanded joint jump."""
    if len(joints) == 0:
        return []
    step = np.abs(np.diff(joints, axis=0))
    jump = ((step[:, :n_tubes] > cfg.pose_break_deg).any(axis=1)
            | (step[:, n_tubes:] > cfg.pose_break_mm).any(axis=1))
    cuts = np.r_[0, np.nonzero(jump)[0] + 1, len(joints)]
    return [(int(a), int(b)) for a, b in itertools.pairwise(cuts)]


def snap_mask(joints: np.ndarray, position: np.ndarray, n_tubes: int, cfg: CleaningConfig) -> np.ndarray:
    """(S,) True where the robot snapped on the way into the sample (one sequence; module docstring).

    joints: (S, 2N) deg/mm; position: (S, 3) mm in the robot base frame.
    """
    out = np.zeros(len(joints), dtype=bool)
    if len(joints) < 2:
        return out
    azimuth = tip_azimuth(position, joints[:, n_tubes - 1])
    jump = np.abs(np.diff(azimuth)) > cfg.snap_threshold_deg
    small = np.abs(np.diff(joints[:, :n_tubes], axis=0)).max(axis=1) <= cfg.snap_threshold_deg
    radius = np.linalg.norm(position[:, :2], axis=1)
    off_axis = (radius[1:] >= cfg.snap_min_radius_mm) & (radius[:-1] >= cfg.snap_min_radius_mm)
    out[1:] = jump & small & off_axis
    return out
