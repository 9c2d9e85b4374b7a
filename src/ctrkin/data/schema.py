"""Dataset schema (docs/data.md: The folder format). One row a sample, time-ordered by `step` within
`sequence_id`.

Column     dtype    unit          meaning
sequence_id int64   -             a continuous run of the robot (the input buffer never crosses it)
step        int64   -             sample index within the sequence, strictly increasing
alpha_i     float64 deg           base rotation of tube i (unwrapped), i = 1..N innermost first
beta_i      float64 mm            base translation of tube i (βi ≤ 0 convention)
x, y, z     float64 mm            measured tip position (tracker, registered to the robot base)
q0, qx, qy  float64 -             measured tip orientation, unit quaternion with qz = 0
true_*      float64 mm / -        the true tip pose where known (virtual robot)
snap        bool    -             a snap happened on the way into this sample
outlier     bool    -             flagged by cleaning (encoder glitch, out of workspace)

Optional columns (kept on save and load when present):
time        float64 s (log)       time stamp of the sample's first reading, in the log's own unit
n_readings  int64   -             readings averaged into the sample (the paper averaged five)
source_line int64   -             line of the sample's first reading in the imported log file

Format version policy: FORMAT_VERSION changes whenever a reader of the old version would misread a
new file (a column renamed, a unit changed). Adding an optional column or meta key does not change it.
Readers refuse other versions with a message saying which side to upgrade.
"""

from __future__ import annotations

import itertools

import numpy as np

from ctrkin.geometry import POSE_COLUMNS as _POSE
from ctrkin.geometry import POSITION_COLUMNS as _POSITION
from ctrkin.robots.robot import alpha_names, beta_names, joint_names

FORMAT_VERSION = 1
POSE_COLUMNS = list(_POSE)            # ctrkin.geometry defines the names; a list here, as always
POSITION_COLUMNS = list(_POSITION)
TRUE_POSE_COLUMNS = [f"true_{c}" for c in POSE_COLUMNS]
INDEX_COLUMNS = ["sequence_id", "step"]
FLAG_COLUMNS = ["snap", "outlier"]
OPTIONAL_COLUMNS = ["time", "n_readings", "source_line"]
QUAT_NORM_TOL = 0.05   # |q| − 1 of a unit quaternion as read (a wrong column is rarely this close to 1)
UNITS = {"alpha": "deg", "beta": "mm", "position": "mm",
         "orientation": "unit quaternion (q0, qx, qy), qz = 0"}


alpha_columns = alpha_names      # the robot's joint names are the dataset's joint columns
beta_columns = beta_names
joint_columns = joint_names      # joint vector order (fixed): α1..αN, β1..βN


def required_columns(n_tubes: int) -> list[str]:
    return INDEX_COLUMNS + joint_columns(n_tubes) + POSE_COLUMNS + FLAG_COLUMNS


def column_unit(column: str) -> str:
    """Unit of a dataset column, for summaries ("" for dimensionless)."""
    base = column.removeprefix("true_")
    if base.startswith("alpha_"):
        return "deg"
    if base.startswith("beta_") or base in POSITION_COLUMNS:
        return "mm"
    if base == "time":
        return "log unit"
    return ""


def sequence_bounds(sequence_id: np.ndarray) -> list[tuple[int, int]]:
    """[(start, stop)) row ranges of the runs of equal, contiguous sequence ids (T,), in order."""
    sid = np.asarray(sequence_id)
    if sid.size == 0:
        return []
    edges = np.r_[0, np.nonzero(sid[1:] != sid[:-1])[0] + 1, len(sid)]
    return [(int(a), int(b)) for a, b in itertools.pairwise(edges)]


def restarted_sequence(sequence_id: np.ndarray) -> int | None:
    """The first row (of sequence ids (T,)) where a sequence id starts again after other sequences,
    or None if the rows of each sequence are contiguous. A Dataset refuses such a layout, and so does
    a model's predict: an interleaved 0, 1, 0, 1, ... would otherwise be taken as T one-step runs."""
    sid = np.asarray(sequence_id)
    if sid.size == 0:
        return None
    starts = np.r_[True, sid[1:] != sid[:-1]]
    if len(np.unique(sid)) == int(starts.sum()):
        return None
    seen: set[object] = set()
    for row in np.nonzero(starts)[0]:
        if sid[row] in seen:
            return int(row)
        seen.add(sid[row])
    return None
