"""A small TCM-made dataset for demos and tests, without the virtual robot.

    from ctrkin.acquisition.demo import sweep_dataset
    ds = sweep_dataset(ctrkin.paper_robot(), translations=(8, 20))   # d = 20 mm snaps on the paper robot

Each sequence is one paper rotation sweep (inner tube start -> +360° -> start, Fig. 2b) followed by
continuation (`ctrkin.follow`): history-dependent through snapping only (the TCM has no friction).
The measured pose is the true pose plus seeded Gaussian tracker noise on the position.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.data.dataset import Dataset
from ctrkin.data.schema import POSE_COLUMNS, TRUE_POSE_COLUMNS
from ctrkin.mechanics import follow
from ctrkin.robots.robot import Robot


def sweep_dataset(robot: Robot, translations: Sequence[float] = (8.0, 20.0),
                  outer_alphas: Sequence[float] = (0.0,), step_deg: float = 2.0, noise_mm: float = 0.0,
                  seed: int = 0) -> Dataset:
    """One sequence per (relative translation d mm, outer rotation deg); rows (T, ...) per schema."""
    rng = np.random.default_rng(seed)
    n = robot.n_tubes
    frames = []
    sid = 0
    for d in translations:
        for a_out in outer_alphas:
            Q = rotation_sweep(n, d, outer_alpha=a_out, step_deg=step_deg, start_deg=a_out)
            tr = follow(robot, Q)
            true = tr.tip_poses
            meas = true.copy()
            meas[:, :3] += rng.normal(0.0, noise_mm, size=(len(Q), 3)) if noise_mm > 0 else 0.0
            f = pd.DataFrame({"sequence_id": sid, "step": np.arange(len(Q))})
            for k, c in enumerate(robot.joint_names()):
                f[c] = Q[:, k]
            for k, c in enumerate(POSE_COLUMNS):
                f[c] = meas[:, k]
            for k, c in enumerate(TRUE_POSE_COLUMNS):
                f[c] = true[:, k]
            f["snap"] = np.asarray(tr.snaps, dtype=bool)
            f["outlier"] = False
            frames.append(f)
            sid += 1
    meta = {"protocol": "demo_sweeps", "translations": list(translations), "outer_alphas": list(outer_alphas),
            "step_deg": step_deg, "noise_mm": noise_mm, "seed": seed}
    return Dataset(pd.concat(frames, ignore_index=True), robot, meta)
