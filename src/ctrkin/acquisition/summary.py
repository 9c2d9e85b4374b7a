"""Figures of a recorded dataset: hysteresis per level, snaps per level, nominal-TCM error.

Hysteresis of a rotation sweep (inner tube 0 → 360 → 0°): at each commanded inner angle visited on
the way forward and on the way back, the distance between the two tip positions (mm) and the
difference of T(L) (deg, the paper's tip azimuth from the outer tube's base, Fig. 2b). A loop that
widens with overlap shows as larger mean and max distances at larger relative translation.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ctrkin.data import Dataset, schema
from ctrkin.geometry import position_error, tangent_angle_error, tip_azimuth
from ctrkin.mechanics import solve_many
from ctrkin.robots.robot import Robot


def _levels_mm(ds: Dataset) -> list[float]:
    return [float(v.get("relative_translation_mm", np.nan)) for v in ds.meta.get("levels", [])]


def sweep_hysteresis(ds: Dataset, true: bool = True) -> pd.DataFrame:
    """Hysteresis per level of a sweep dataset (the paper or sweeps protocol).

    At each commanded inner angle, the distance between the forward and the backward tip positions
    and the difference of T(L); outlier rows are left out.

    Parameters
    ----------
    ds : Dataset
        A recording with `level` and `direction` columns (the virtual robot's).
    true : bool
        Use the true poses (else the measured ones, which add tracker noise).

    Returns
    -------
    pandas.DataFrame
        One row per level: ``relative_translation_mm``, ``sequences``, ``snap_samples``,
        ``hysteresis_mean_mm``, ``hysteresis_max_mm`` (mm) and ``azimuth_gap_max_deg`` (deg).
    """
    f = ds.frame
    n = ds.n_tubes
    cols = schema.TRUE_POSE_COLUMNS if true else schema.POSE_COLUMNS
    levels = _levels_mm(ds)
    rows: dict[int, dict[str, list[float]]] = {}
    for a, b in ds.sequence_bounds():
        seq = f.iloc[a:b]
        lv = int(seq["level"].iloc[0]) if "level" in seq else -1
        acc = rows.setdefault(lv, {"mean": [], "max": [], "az": [], "snaps": [], "seqs": []})
        acc["snaps"].append(float(seq["snap"].sum()))
        acc["seqs"].append(1.0)
        keep = ~seq["outlier"].to_numpy()
        a1 = seq["alpha_1"].to_numpy()
        d = seq["direction"].to_numpy() if "direction" in seq else np.sign(np.diff(np.r_[a1[0], a1]))
        pos = seq[cols[:3]].to_numpy()
        az = tip_azimuth(pos, seq[f"alpha_{n}"].to_numpy())
        fwd = pd.DataFrame({"a": np.round(a1, 6), "i": np.arange(len(a1))})[(d >= 0) & keep]
        bwd = pd.DataFrame({"a": np.round(a1, 6), "i": np.arange(len(a1))})[(d < 0) & keep]
        m = fwd.drop_duplicates("a").merge(bwd.drop_duplicates("a"), on="a", suffixes=("_f", "_b"))
        if m.empty:
            continue
        i_f, i_b = m["i_f"].to_numpy(), m["i_b"].to_numpy()
        dist = np.linalg.norm(pos[i_f] - pos[i_b], axis=1)
        acc["mean"].append(float(dist.mean()))
        acc["max"].append(float(dist.max()))
        acc["az"].append(float(np.abs(az[i_f] - az[i_b]).max()))
    out = []
    for lv in sorted(rows):
        acc = rows[lv]
        out.append({"level": lv,
                    "relative_translation_mm": levels[lv] if 0 <= lv < len(levels) else np.nan,
                    "sequences": int(sum(acc["seqs"])), "snap_samples": int(sum(acc["snaps"])),
                    "hysteresis_mean_mm": float(np.mean(acc["mean"])) if acc["mean"] else np.nan,
                    "hysteresis_max_mm": float(np.max(acc["max"])) if acc["max"] else np.nan,
                    "azimuth_gap_max_deg": float(np.max(acc["az"])) if acc["az"] else np.nan})
    return pd.DataFrame(out)


def nominal_error(ds: Dataset, robot: Robot | None = None, every: int = 1,
                  targets_only: bool = False) -> dict[str, Any]:
    """The point-wise nominal TCM (the paper's "TCM" baseline: no history) against a recording.

    Parameters
    ----------
    ds : Dataset
        A recording with true poses (the virtual robot's).
    robot : Robot, optional
        The model robot (default: the dataset's nominal robot).
    every : int
        Use every k-th non-outlier sample.
    targets_only : bool
        Only rows with ``is_target`` (random points).

    Returns
    -------
    dict
        Mean and RMSE position errors (mm) and the mean tangent angle (deg) against the measured
        and the true poses (``position_mean_mm_vs_measured``, ``position_mean_mm_vs_true``, …), and
        the number of samples used.
    """
    robot = robot if robot is not None else ds.robot
    f = ds.frame
    keep = ~f["outlier"].to_numpy()
    if targets_only and "is_target" in f:
        keep &= f["is_target"].to_numpy()
    idx = np.nonzero(keep)[0][::max(int(every), 1)]
    q = f[schema.joint_columns(robot.n_tubes)].to_numpy()[idx]
    nom = np.array([e.tip_pose for e in solve_many(robot, q)]).reshape(len(idx), 6)
    out: dict[str, Any] = {"samples": len(idx)}
    for name, cols in (("measured", schema.POSE_COLUMNS), ("true", schema.TRUE_POSE_COLUMNS)):
        if not all(c in f for c in cols):
            continue
        ref = f[cols].to_numpy()[idx]
        pe = position_error(nom, ref)
        out[f"position_mean_mm_vs_{name}"] = float(np.nanmean(pe))
        out[f"position_rmse_mm_vs_{name}"] = float(np.sqrt(np.nanmean(pe**2)))
        out[f"position_max_mm_vs_{name}"] = float(np.nanmax(pe))
        out[f"orientation_mean_deg_vs_{name}"] = float(np.nanmean(tangent_angle_error(nom, ref)))
    return out


def measurement_error(ds: Dataset) -> dict[str, float]:
    """The tracker's own error: measured against true poses on the non-outlier rows.

    Parameters
    ----------
    ds : Dataset
        A recording with true poses.

    Returns
    -------
    dict
        ``position_mean_mm`` (sensor offset, registration and noise) and ``orientation_mean_deg``.
    """
    f = ds.frame[~ds.frame["outlier"]]
    m, t = f[schema.POSE_COLUMNS].to_numpy(), f[schema.TRUE_POSE_COLUMNS].to_numpy()
    return {"position_mean_mm": float(position_error(m, t).mean()),
            "orientation_mean_deg": float(tangent_angle_error(m, t).mean())}
