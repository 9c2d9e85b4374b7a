"""The true tip poses of a dataset as its tracker reports them without noise.

A virtual-robot dataset's `true_*` columns are the true tube tip in the robot base frame; its measured
columns are the tracker's sensor (`offset` beyond the tip, seen through an imperfect registration)
plus noise. A model trained on measurements learns the tracker's view, so its error against the truth
is measured against this view (same frame and sensor point, field warp, no noise); the rest is the
tracker's own error. The registration, sensor offset and field warp are read from the tracker
recorded in meta.json
("virtual_robot" → "tracker", ctrkin.virtual.tracker.Tracker.to_dict), so no virtual robot is rebuilt
(ctrkin.virtual.truth does that where the whole virtual robot is needed).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ctrkin.errors import DatasetError
from ctrkin.geometry import RigidTransform, sensor_view, wave_warp

if TYPE_CHECKING:
    from ctrkin.data.dataset import Dataset


def recorded_tracker_view(ds: Dataset) -> np.ndarray | None:
    """(T, 6) true poses through the dataset's recorded tracker registration, at its sensor point;
    None for a dataset without true_* columns or without a recorded tracker (a real robot's)."""
    vr = ds.meta.get("virtual_robot")
    tracker = vr.get("tracker") if isinstance(vr, dict) else None
    if not ds.has_truth or not isinstance(tracker, dict):
        return None
    try:
        registration = RigidTransform(np.array(tracker["registration_rotation"], dtype=float),
                                      np.array(tracker["registration_translation_mm"], dtype=float))
        offset = float(tracker["sensor_offset_mm"])
    except (KeyError, TypeError, ValueError) as e:
        raise DatasetError(f"the dataset's recorded tracker (meta virtual_robot.tracker) is incomplete: {e}; "
                           "record the dataset again") from None
    if registration.rotation.shape != (3, 3) or registration.translation.shape != (3,):
        raise DatasetError("the dataset's recorded tracker registration is not a 3 × 3 rotation and a "
                           "3-vector; record the dataset again")
    view = sensor_view(ds.poses(true=True), registration, offset)
    if tracker.get("field_warp") is None:
        return view
    warp = tracker["field_warp"]
    try:
        amp, wave, phase, centre = (np.array(warp[k], dtype=float) for k in
                                    ("amplitude_mm", "wave_per_mm", "phase_rad", "centre_mm"))
    except (KeyError, TypeError, ValueError) as e:
        raise DatasetError(f"the dataset's recorded field warp (meta virtual_robot.tracker.field_warp) is "
                           f"incomplete: {e}; record the dataset again") from None
    m = amp.shape[0] if amp.ndim == 2 else -1
    if amp.shape != (m, 3) or wave.shape != (m, 3) or phase.shape != (m,) or centre.shape != (3,):
        raise DatasetError("the dataset's recorded field warp is not amplitude and wave (M, 3), phase "
                           "(M,) and centre (3,); record the dataset again")
    view[:, :3] += wave_warp(view[:, :3], amp, wave, phase, centre)   # positions only (virtual.field)
    return view
