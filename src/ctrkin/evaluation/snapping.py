"""Snap prediction scored by the paper's 10° T(L) rule (docs/design.md: Conventions): T(L) series, snap
events, their matching against a reference, and the row windows around snaps and encoder glitches.
Pose and joint errors are in ctrkin.metrics."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ctrkin.geometry import tip_azimuth
from ctrkin.metrics import wrap_deg

SNAP_THRESHOLD_DEG = 10.0  # paper II.B: a snap is a step where T(L) changes by more than 10°


def azimuth_series(
    poses: np.ndarray, joints: np.ndarray, n_tubes: int, bounds: list[tuple[int, int]]
) -> np.ndarray:
    """T(L) (deg) of every row, unwrapped within each sequence: tip azimuth about z from the outer
    tube's base rotation αN. poses (T, 6), joints (T, 2N)."""
    out = np.empty(len(poses))
    for a, b in bounds:
        out[a:b] = tip_azimuth(poses[a:b, :3], joints[a:b, n_tubes - 1])
    return out


def snap_steps(
    azimuth: np.ndarray, bounds: list[tuple[int, int]], threshold: float = SNAP_THRESHOLD_DEG
) -> np.ndarray:
    """Rows n (not a sequence start) where |T(L)_n − T(L)_{n−1}| > threshold (deg)."""
    rows = []
    for a, b in bounds:
        jumps = np.abs(np.diff(azimuth[a:b]))
        rows.append(a + 1 + np.nonzero(jumps > threshold)[0])
    return np.concatenate(rows) if rows else np.zeros(0, dtype=int)


def _events(steps: np.ndarray) -> np.ndarray:
    """Merge consecutive snap rows into one event (a snap spread over two steps is one snap)."""
    if len(steps) == 0:
        return steps
    keep = np.r_[True, np.diff(steps) > 1]
    return steps[keep]


def snap_event_rows(
    azimuth: np.ndarray, bounds: list[tuple[int, int]], threshold: float = SNAP_THRESHOLD_DEG
) -> np.ndarray:
    """Rows where a snap event of T(L) starts: snap_steps with consecutive rows merged."""
    return _events(snap_steps(azimuth, bounds, threshold))


@dataclass(frozen=True)
class SnapScore:
    """Snap prediction against a reference: counts, precision, recall, timing error (steps, mean
    |Δn| over matched events) and magnitude error (deg, mean |ΔT_pred − ΔT_ref| over matched events,
    each event's magnitude being the T(L) change over rows n−1 … n+1, the difference wrapped into
    [−180°, 180°]: a tip that jumps across the axis turns T(L) by +170° or by −190° to the same
    azimuth, which the per-row unwrapping decides by a hair, so the two differ by 0°, not 360°)."""

    n_reference: int
    n_predicted: int
    n_matched: int
    precision: float
    recall: float
    timing_error_steps: float
    magnitude_error_deg: float

    def to_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in self.__dict__.items()}


def snap_score(
    pred_azimuth: np.ndarray,
    ref_azimuth: np.ndarray,
    bounds: list[tuple[int, int]],
    tolerance_steps: int = 2,
    threshold: float = SNAP_THRESHOLD_DEG,
    rows: np.ndarray | None = None,
) -> SnapScore:
    """Match predicted snap events to reference events of the same sequence within ±tolerance.
    rows: (T,) bool, count only events at these rows (e.g. one direction of rotation)."""
    pred_ev = snap_event_rows(pred_azimuth, bounds, threshold)
    ref_ev = snap_event_rows(ref_azimuth, bounds, threshold)
    if rows is not None:
        pred_ev, ref_ev = pred_ev[rows[pred_ev]], ref_ev[rows[ref_ev]]
    seq_of = np.empty(bounds[-1][1] if bounds else 0, dtype=int)
    for k, (a, b) in enumerate(bounds):
        seq_of[a:b] = k
    used = np.zeros(len(pred_ev), dtype=bool)
    timing, magnitude = [], []      # magnitude: ΔT_pred − ΔT_ref of each match, wrapped at the end

    def mag(az: np.ndarray, n: int) -> float:
        a, b = bounds[seq_of[n]]
        return float(az[min(n + 1, b - 1)] - az[max(n - 1, a)])

    for r in ref_ev:
        cand = [
            i
            for i, p in enumerate(pred_ev)
            if not used[i] and seq_of[p] == seq_of[r] and abs(int(p) - int(r)) <= tolerance_steps
        ]
        if not cand:
            continue
        i = min(cand, key=lambda j: abs(int(pred_ev[j]) - int(r)))
        used[i] = True
        timing.append(abs(int(pred_ev[i]) - int(r)))
        magnitude.append(mag(pred_azimuth, int(pred_ev[i])) - mag(ref_azimuth, int(r)))
    n_m = int(used.sum())
    return SnapScore(
        n_reference=len(ref_ev),
        n_predicted=len(pred_ev),
        n_matched=n_m,
        precision=n_m / len(pred_ev) if len(pred_ev) else float("nan"),
        recall=n_m / len(ref_ev) if len(ref_ev) else float("nan"),
        timing_error_steps=float(np.mean(timing)) if timing else float("nan"),
        magnitude_error_deg=float(np.mean(np.abs(wrap_deg(np.array(magnitude))))) if magnitude
        else float("nan"),
    )


def snap_window(snap: np.ndarray, bounds: list[tuple[int, int]], width: int = 2) -> np.ndarray:
    """(T,) bool: the `width` rows starting at each flagged snap row (the steps at a snap, where a
    history buffer lags by one or two steps), within its sequence."""
    snap = np.asarray(snap, bool)
    out = np.zeros_like(snap)
    for a, b in bounds:
        for n in np.nonzero(snap[a:b])[0]:
            out[a + n : min(a + n + width, b)] = True
    return out


def rotation_direction(joints: np.ndarray, n_tubes: int, bounds: list[tuple[int, int]]) -> np.ndarray:
    """(T,) sign of the change of α0 = α1 − αN from the previous row (0 at sequence starts): +1 on
    the forward half of a turn, −1 on the way back."""
    a0 = joints[:, 0] - joints[:, n_tubes - 1]
    out = np.zeros(len(a0))
    for a, b in bounds:
        out[a + 1:b] = np.sign(np.diff(a0[a:b]))
    return out


def snap_report(pred_azimuth: np.ndarray, ref_azimuth: np.ndarray, bounds: list[tuple[int, int]],
                direction: np.ndarray, keep: np.ndarray | None = None) -> dict[str, Any]:
    """Snap score over all events and per direction of rotation (`forward`, `backward`). keep (T,)
    bool: count only events at these rows (e.g. not just after an encoder glitch, `glitch_window`)."""
    keep = np.ones(len(direction), bool) if keep is None else np.asarray(keep, bool)
    out: dict[str, Any] = snap_score(pred_azimuth, ref_azimuth, bounds, rows=keep).to_dict()
    out["forward"] = snap_score(pred_azimuth, ref_azimuth, bounds, rows=keep & (direction > 0)).to_dict()
    out["backward"] = snap_score(pred_azimuth, ref_azimuth, bounds, rows=keep & (direction < 0)).to_dict()
    return out


def glitch_window(outlier: np.ndarray, bounds: list[tuple[int, int]], ib: int = 2) -> np.ndarray:
    """(T,) bool: each encoder-glitch row and the ib + 1 rows after it: their predictions, or the
    step into them, see the corrupted joints in the input buffer or the step change (the paper
    removed glitch rows; a T(L) jump there is the glitch, not a snap)."""
    return snap_window(outlier, bounds, width=ib + 2)
