"""Errors in physical units, in one place for training (metrics.json) and evaluation (results.json)
(docs/design.md: Evaluation).

Per sample:
  position error     Euclidean distance of the tip positions (mm)               pose.position_error
  orientation error  angle between the tip tangents (deg): what a 5-DOF sensor  pose.tangent_angle_error
                     observes, so q and −q (and any roll) give zero
  joint errors       Euclidean norm over the tubes of the α errors (deg) and of the β errors (mm)
                     (paper III.A: a distance in joint space)

α wrapping: data angles are unwrapped (a sweep 0→360→0° stays continuous), but a tube base turned by a
full turn is the same configuration, which no tip pose can tell apart. `joint_error_norms(wrap=True)`
takes each tube's α difference modulo 360° into [−180°, 180°) first: the configuration error, which
results.json reports as `alpha_deg`. The unwrapped norm (`wrap=False`) is what a network's loss sees;
metrics.json of a trained IK model keeps both (`alpha_deg` unwrapped, `alpha_wrapped_deg` wrapped).

Summaries: RMSE, MAE, max (and median, count) over samples. A NaN error (a failed prediction) makes
the summary NaN instead of being dropped.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ctrkin.geometry import position_error, tangent_angle_error

__all__ = [
    "error_stats",
    "joint_error_norms",
    "joint_errors",
    "metrics_json_joint_errors",
    "metrics_json_pose_errors",
    "orientation_error",
    "pose_errors",
    "position_error",
    "timing_stats",
    "wrap_deg",
]

orientation_error = tangent_angle_error


def wrap_deg(a: np.ndarray) -> np.ndarray:
    """Wrap angles to [−180°, 180°) (+180° maps to −180°).

    Parameters
    ----------
    a : ndarray
        Angles (deg), any shape.

    Returns
    -------
    ndarray
        The same shape, wrapped.
    """
    return (np.asarray(a, float) + 180.0) % 360.0 - 180.0


def error_stats(e: np.ndarray) -> dict[str, float]:
    """Summary statistics of errors.

    Parameters
    ----------
    e : ndarray
        Errors, any shape; signs are ignored.

    Returns
    -------
    dict
        ``rmse``, ``mae``, ``max``, ``median`` over every entry (in the errors' unit) and the count
        ``n``. A NaN entry counts as a failure and makes the statistics NaN; an empty `e` gives NaN
        statistics and ``n = 0``.
    """
    e = np.abs(np.asarray(e, dtype=float).ravel())
    if e.size == 0:
        return {"rmse": float("nan"), "mae": float("nan"), "max": float("nan"), "median": float("nan"),
                "n": 0}
    return {
        "rmse": float(np.sqrt(np.mean(e**2))),
        "mae": float(np.mean(e)),
        "max": float(np.max(e)),
        "median": float(np.median(e)),
        "n": int(e.size),
    }


def pose_errors(
    pred: np.ndarray, ref: np.ndarray, mask: np.ndarray | None = None
) -> dict[str, dict[str, float]]:
    """Position and orientation errors of predicted tip poses.

    Parameters
    ----------
    pred, ref : ndarray, shape (T, 6)
        Predicted and reference tip poses (mm, 5-DOF quaternion).
    mask : ndarray of bool, shape (T,), optional
        The rows to count (default: all).

    Returns
    -------
    dict
        ``{"position_mm": error_stats(...), "orientation_deg": error_stats(...)}``: the Euclidean
        distance (mm) and the angle between the tip tangents (deg).
    """
    pred, ref = np.asarray(pred, float), np.asarray(ref, float)
    if mask is not None:
        pred, ref = pred[mask], ref[mask]
    return {
        "position_mm": error_stats(position_error(pred, ref)),
        "orientation_deg": error_stats(orientation_error(pred, ref)),
    }


def joint_error_norms(
    pred: np.ndarray, ref: np.ndarray, n_tubes: int, wrap: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample joint errors: the norm over the tubes of the α errors and of the β errors.

    Parameters
    ----------
    pred, ref : ndarray, shape (T, 2N)
        Joints (α1..αN deg, β1..βN mm).
    n_tubes : int
        N.
    wrap : bool
        Wrap each tube's α difference to [−180°, 180°) first (a whole turn is the same
        configuration).

    Returns
    -------
    alpha : ndarray, shape (T,)
        Norm of the α errors (deg).
    beta : ndarray, shape (T,)
        Norm of the β errors (mm).
    """
    d = np.asarray(pred, float) - np.asarray(ref, float)
    da = wrap_deg(d[:, :n_tubes]) if wrap else d[:, :n_tubes]
    return np.linalg.norm(da, axis=1), np.linalg.norm(d[:, n_tubes:], axis=1)


def joint_errors(pred: np.ndarray, ref: np.ndarray, n_tubes: int) -> dict[str, dict[str, float]]:
    """Joint error statistics as results.json reports them.

    Parameters
    ----------
    pred, ref : ndarray, shape (T, 2N)
        Joints (deg, mm).
    n_tubes : int
        N.

    Returns
    -------
    dict
        ``{"alpha_deg": error_stats of the wrapped α norms, "beta_mm": error_stats of the β norms}``.
    """
    alpha, beta = joint_error_norms(pred, ref, n_tubes, wrap=True)
    return {"alpha_deg": error_stats(alpha), "beta_mm": error_stats(beta)}


def _flat(e: np.ndarray, prefix: str) -> dict[str, float]:
    """metrics.json keys `{prefix}_rmse`, `_mae`, `_max` of errors e (T,); none for an empty e."""
    if e.size == 0:
        return {}
    s = error_stats(e)
    return {f"{prefix}_{k}": s[k] for k in ("rmse", "mae", "max")}


def metrics_json_pose_errors(pred: np.ndarray, ref: np.ndarray, orientation: bool = True) -> dict[str, float]:
    """Pose errors as the flat keys of a model's metrics.json.

    Parameters
    ----------
    pred, ref : ndarray, shape (T, 6)
        Predicted and reference tip poses.
    orientation : bool
        False where the reference has no measured orientation (a position-only dataset, whose
        quaternion columns are placeholders): no orientation keys then.

    Returns
    -------
    dict
        ``position_mm_rmse``, ``_mae``, ``_max`` (mm), ``orientation_deg_*`` (deg, tip tangent) and
        ``n``.
    """
    angles = _flat(orientation_error(pred, ref), "orientation_deg") if orientation else {}
    return {**_flat(position_error(pred, ref), "position_mm"), **angles, "n": len(pred)}


def metrics_json_joint_errors(pred: np.ndarray, ref: np.ndarray, n_tubes: int) -> dict[str, float]:
    """Joint errors as the flat keys of a model's metrics.json.

    Parameters
    ----------
    pred, ref : ndarray, shape (T, 2N)
        Joints (deg, mm).
    n_tubes : int
        N.

    Returns
    -------
    dict
        ``alpha_deg_*`` (unwrapped α norms: what the loss sees), ``alpha_wrapped_deg_*`` (wrapped:
        the configuration error), ``beta_mm_*``, each for rmse/mae/max, and ``n``.
    """
    raw, beta = joint_error_norms(pred, ref, n_tubes, wrap=False)
    wrapped, _ = joint_error_norms(pred, ref, n_tubes, wrap=True)
    return {**_flat(raw, "alpha_deg"), **_flat(wrapped, "alpha_wrapped_deg"), **_flat(beta, "beta_mm"),
            "n": len(pred)}


def timing_stats(seconds: np.ndarray) -> dict[str, Any]:
    """Statistics of per-prediction times.

    Parameters
    ----------
    seconds : ndarray, shape (K,)
        Times (s).

    Returns
    -------
    dict
        ``ms_mean``, ``ms_std`` (ms), ``us_median`` (µs) and the count ``n``.
    """
    t = np.asarray(seconds, float)
    return {
        "ms_mean": float(t.mean() * 1e3),
        "ms_std": float(t.std() * 1e3),
        "us_median": float(np.median(t) * 1e6),
        "n": int(t.size),
    }
