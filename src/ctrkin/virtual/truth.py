"""The truth of a virtual-robot dataset as the tracker would report it without noise.

A dataset's `true_*` columns are the true tube tip in the robot base frame; its measured columns are
the tracker's sensor (offset beyond the tip, seen through an imperfect registration) plus noise. A model
trained on measurements learns the tracker's view, so its error against the truth is measured against
`tracker_truth` (same frame and sensor point, no noise); the rest is the tracker's own error.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ctrkin.errors import DatasetError
from ctrkin.virtual.config import VirtualConfig
from ctrkin.virtual.robot import VirtualRobot

if TYPE_CHECKING:
    from ctrkin.data.dataset import Dataset


def virtual_from_meta(ds: Dataset) -> VirtualRobot:
    """Rebuild the virtual robot a dataset was recorded on (its hardware draw is seeded)."""
    vr = ds.meta.get("virtual_robot")
    if not isinstance(vr, dict) or "seed" not in vr or "config" not in vr:
        raise DatasetError("this dataset was not recorded on the virtual robot (no virtual_robot in meta)")
    virtual = VirtualRobot(ds.robot, VirtualConfig.from_dict(vr["config"]), seed=int(vr["seed"]))
    recorded = np.asarray(vr["tracker"]["registration_rotation"], float)
    if not np.allclose(recorded, virtual.tracker.rotation, atol=1e-12):
        raise DatasetError("the dataset's virtual robot cannot be rebuilt with this ctrkin version")
    return virtual


def tracker_truth(ds: Dataset, virtual: VirtualRobot | None = None) -> np.ndarray | None:
    """(T, 6) true poses seen by the tracker without noise, or None for a dataset from a real robot
    (no virtual_robot in its meta, or no true_* columns)."""
    if not ds.has_truth:
        return None
    if virtual is None:
        if "virtual_robot" not in ds.meta:
            return None
        virtual = virtual_from_meta(ds)
    return virtual.tracker.registered(ds.poses(true=True))
