"""Errors in physical units (DESIGN.md: Evaluation): position mm, tip-tangent angle deg, joints mm / deg."""

from __future__ import annotations

import numpy as np

from ctrkin.pose import position_error, tangent_angle_error


def _stats(e: np.ndarray, prefix: str) -> dict[str, float]:
    if e.size == 0:
        return {}
    return {f"{prefix}_rmse": float(np.sqrt(np.mean(e**2))), f"{prefix}_mae": float(np.mean(np.abs(e))),
            f"{prefix}_max": float(np.max(np.abs(e)))}


def pose_errors(pred: np.ndarray, ref: np.ndarray, orientation: bool = True) -> dict[str, float]:
    """pred, ref: (T, 6) tip poses -> position (mm) and orientation (deg, tip tangent) RMSE/MAE/max.
    orientation=False: the reference has no measured orientation (a position-only dataset, whose
    quaternion columns are placeholders), so no orientation errors are given."""
    angles = _stats(tangent_angle_error(pred, ref), "orientation_deg") if orientation else {}
    return {**_stats(position_error(pred, ref), "position_mm"), **angles, "n": len(pred)}


def joint_errors(pred: np.ndarray, ref: np.ndarray, n_tubes: int) -> dict[str, float]:
    """pred, ref: (T, 2N) joints (deg, mm). Per sample the Euclidean norm of the α error (deg) and
    of the β error (mm) (paper III.A: distance in joint space), then RMSE/MAE/max over samples.
    alpha_wrapped_deg: the α errors taken modulo 360° first (α and α + 360° turn the tube base to the
    same place; the unwrapped value is ambiguous from a pose at the ends of a full turn)."""
    d = np.asarray(pred, float) - np.asarray(ref, float)
    wrapped = (d[:, :n_tubes] + 180.0) % 360.0 - 180.0
    return {**_stats(np.linalg.norm(d[:, :n_tubes], axis=1), "alpha_deg"),
            **_stats(np.linalg.norm(wrapped, axis=1), "alpha_wrapped_deg"),
            **_stats(np.linalg.norm(d[:, n_tubes:], axis=1), "beta_mm"), "n": len(pred)}
