"""The plan as a table (plan.csv) and its targets read from a CSV file."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ctrkin.errors import CtrkinError
from ctrkin.geometry import POSITION_COLUMNS, QUATERNION_COLUMNS, tangent_from_quat
from ctrkin.planning.planner import Plan
from ctrkin.robots.robot import joint_names


def read_targets(path: str | Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Targets (K, 3) mm and unit tangents (K, 3) (None without q0, qx, qy) from a CSV with columns
    x, y, z (mm) and optionally q0, qx, qy (the 5-DOF tip quaternion, as `ctrkin collect` writes a
    task path's targets.csv), in the robot base frame."""
    try:
        df = pd.read_csv(path)
    except (OSError, ValueError) as e:
        raise CtrkinError(f"cannot read targets from {path}: {e}") from None
    missing = [c for c in POSITION_COLUMNS if c not in df.columns]
    if missing:
        raise CtrkinError(f"{path} has no column(s) {missing}: targets need x, y, z (mm) and "
                          "optionally q0, qx, qy")
    if len(df) == 0:
        raise CtrkinError(f"{path} holds no target")
    pos = df[list(POSITION_COLUMNS)].to_numpy(float)
    if not np.isfinite(pos).all():
        raise CtrkinError(f"{path}: every target position must be a finite number (mm)")
    if not all(c in df.columns for c in QUATERNION_COLUMNS):
        return pos, None
    quat = df[list(QUATERNION_COLUMNS)].to_numpy(float)
    if not np.isfinite(quat).all() or not np.allclose(np.linalg.norm(quat, axis=1), 1.0, atol=0.05):
        raise CtrkinError(f"{path}: q0, qx, qy must form unit quaternions (qz = 0), one per target")
    return pos, tangent_from_quat(quat / np.linalg.norm(quat, axis=1, keepdims=True))


def plan_table(plan: Plan, n_tubes: int) -> pd.DataFrame:
    """One row per step: step, the joints, the predicted tip (mm), the stability margin, the target
    reached at the step (−1 between targets), the route and flags (snap: a planned snap;
    low_margin: below 0.1, only on a planned snap's way); with a learned snap model also its branch
    state, its margin (deg of inner rotation left before its predicted snap), learned_snap (a snap it
    predicts in the step: only a planned one) and learned_jump_mm (its predicted tip jump at a flip)."""
    cols: dict[str, Any] = {"step": np.arange(len(plan.q))}
    cols |= {c: plan.q[:, k] for k, c in enumerate(joint_names(n_tubes))}
    cols |= {f"tip_{c}": plan.tips[:, k] for k, c in enumerate(POSITION_COLUMNS)}
    cols |= {"margin": plan.margin, "target": plan.target, "route": plan.route,
             "snap": plan.snap, "low_margin": plan.margin < 0.1}
    if plan.learned is not None:
        cols |= {"learned_state": plan.learned.state, "learned_margin_deg": plan.learned.margin_deg,
                 "learned_snap": plan.learned.snap, "learned_jump_mm": plan.learned.jump_mm}
    return pd.DataFrame(cols)
