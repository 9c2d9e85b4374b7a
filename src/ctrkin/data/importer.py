"""Import a user's own robot log (CSV) into a Dataset, with the paper's cleaning (cleaning.py).

A log has one row per tracker reading. Its columns are mapped onto dataset fields (`FIELDS`):

    alpha_1..alpha_N, beta_1..beta_N   joints (angles deg|rad, lengths mm|m)
    x, y, z                            tip position (mm|m), registered to the robot base frame
    orientation, one of:
        q0, qx, qy                     5-DOF sensor quaternion with qz = 0 (q0 is the scalar part)
        qw, qx, qy, qz                 full quaternion (roll about the tip tangent is dropped)
        tx, ty, tz                     tip tangent (any length)
    sequence_id (optional)             runs of the robot; any labels, rows of a run contiguous
    time (optional)                    time stamps (any unit), non-decreasing within a sequence
    step (optional)                    sample index; readings sharing a step are one sample
    snap (optional)                    the log's own snap flag (0/1); otherwise detected

A field not mapped is read from a column of the same name when the log has one. Every orientation
becomes the dataset's (q0, qx, qy) through the tip tangent R e3 (geometry.quat_from_tangent).

Without sequence_id, the log is one sequence, unless it has time stamps and `sequence_gap` is set:
a time gap larger than `sequence_gap` (in the log's time unit), or with "auto" larger than
AUTO_GAP_FACTOR times the median time step, starts a new sequence (logging was interrupted, so
the history seen by the input buffer is broken there).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ctrkin.data import cleaning, schema
from ctrkin.data.cleaning import CleaningConfig
from ctrkin.data.dataset import Dataset
from ctrkin.data.import_config import LENGTH_TO_MM, ImportConfig
from ctrkin.data.log_table import LogTable, file_sha256
from ctrkin.errors import DatasetError, JointError
from ctrkin.geometry import quat_from_tangent, tangent_from_quat, tangent_from_quaternion
from ctrkin.robots.robot import Robot

AUTO_GAP_FACTOR = 10.0


MAX_EXACT_STEP = 2**53  # integers at or above this are not exact as float64: distinct steps would merge


def import_csv(path: str | Path, robot: Robot, config: ImportConfig | None = None) -> Dataset:
    """Read a log file (CSV, one row a reading) into a cleaned Dataset (module docstring).

    The cleaning report (counts per rule) is meta["cleaning"], the tracker noise estimated from the
    spread of repeated readings meta["noise"], the resolved configuration meta["import"].
    """
    cfg = config or ImportConfig()
    src = Path(path)
    ds = import_frame(LogTable(src, robot, cfg), robot, cfg, str(src))
    ds.meta["protocol_params"] = {"source": src.name, "sha256": file_sha256(src)}
    return ds


def import_frame(log: LogTable, robot: Robot, cfg: ImportConfig, src: str) -> Dataset:
    """The rows of `log` (read from a CSV, or made by an import profile) -> a cleaned Dataset;
    src names the log(s) in messages. Stages: read the fields, drop incomplete rows, check the
    joints, orientation and sequences, check the time order, average and clean, build the dataset."""
    n = robot.n_tubes
    mode = "absent" if cfg.position_only else log.orientation_mode(log.columns)
    rows = _Rows.read(log, n, str(mode))
    incomplete = rows.drop_incomplete(cfg, src)
    joints, invalid = rows.valid_joints(robot, cfg, src)
    position = np.column_stack([rows.values[c] for c in schema.POSITION_COLUMNS])
    position = position * LENGTH_TO_MM[cfg.position_unit]
    tangent = _tangents(rows.values, mode, rows.line, log, src)
    sequence, seq_labels = _sequences(rows.labels, rows.values.get("time"), rows.line, cfg, log, src)
    rows.check_order(sequence)
    if cfg.unwrap:
        for a, b in schema.sequence_bounds(sequence):
            joints[a:b, :n] = np.unwrap(joints[a:b, :n], period=360.0, axis=0)
    s = _clean(rows, sequence, joints, position, tangent, n, cfg.cleaning, src)
    counts = {"rows_read": rows.count, "rows_incomplete_dropped": int(incomplete.sum()),
              "rows_invalid_joints_dropped": int(invalid.sum())}
    return _dataset(s, rows, seq_labels, robot, cfg, str(mode), counts)


@dataclass(eq=False)
class _Rows:
    """The log's rows still in play: their field values (R,), data-row indices `line` (for messages)
    and sequence labels; each stage drops rows from all three at once (`keep`)."""

    log: LogTable
    values: dict[str, np.ndarray]
    line: np.ndarray
    labels: np.ndarray | None
    count: int                   # rows read

    @classmethod
    def read(cls, log: LogTable, n: int, mode: str) -> _Rows:
        cols = log.columns
        pose_fields = schema.POSITION_COLUMNS + {"quaternion": ["qw", "qx", "qy", "qz"],
                                                 "tangent": ["tx", "ty", "tz"], "5dof": ["qw", "qx", "qy"],
                                                 "absent": []}[mode]
        numeric = schema.joint_columns(n) + pose_fields + [f for f in ("time", "step", "snap") if f in cols]
        values = {f: log.numbers(f) for f in numeric}
        labels = log.raw[cols["sequence_id"]].str.strip().to_numpy() if "sequence_id" in cols else None
        return cls(log, values, np.arange(len(log.raw)), labels, len(log.raw))

    def keep(self, mask: np.ndarray) -> None:
        self.values = {f: v[mask] for f, v in self.values.items()}
        self.line = self.line[mask]
        self.labels = self.labels[mask] if self.labels is not None else None

    def drop_incomplete(self, cfg: ImportConfig, src: str) -> np.ndarray:
        """Drop rows with an empty, NaN or inf cell (or fail without drop_incomplete); a missing snap
        flag reads 0. Returns the (R,) dropped mask."""
        log, nan = self.log, np.zeros(self.count, dtype=bool)
        for f, v in self.values.items():
            if f == "snap":
                continue
            col_nan = ~np.isfinite(v)
            if col_nan.any() and not cfg.drop_incomplete:
                r = int(np.argmax(col_nan))
                raise DatasetError(f"{log.where(r)}, {log.line_col(f)} is empty, NaN or inf; fix "
                                   "the log or pass --drop-incomplete to skip such rows")
            nan |= col_nan
        if "snap" in self.values:
            self.values["snap"] = np.nan_to_num(self.values["snap"], nan=0.0)
        if self.labels is not None:
            empty_label = self.labels == ""
            if empty_label.any() and not cfg.drop_incomplete:
                r = int(np.argmax(empty_label))
                raise DatasetError(f"{log.where(r)}, {log.line_col('sequence_id')} is empty; fix the "
                                   "log or pass --drop-incomplete")
            nan |= empty_label
        self.keep(~nan)
        if len(self.line) == 0:
            raise DatasetError(f"{src}: no complete rows left")
        return nan

    def valid_joints(self, robot: Robot, cfg: ImportConfig, src: str) -> tuple[np.ndarray, np.ndarray]:
        """Joints (R, 2N) in deg and mm; rows outside the robot's limits dropped (drop_invalid_joints)
        or refused with the reason. Returns (joints of the kept rows, the (R,) invalid mask)."""
        n, cols, values, log = robot.n_tubes, self.log.columns, self.values, self.log
        alpha = np.column_stack([values[c] for c in schema.alpha_columns(n)])
        if cfg.angle_unit == "rad":
            alpha = np.degrees(alpha)
        beta = np.column_stack([values[c] for c in schema.beta_columns(n)]) * LENGTH_TO_MM[cfg.beta_unit]
        joints = np.column_stack([alpha, beta])
        invalid = ~robot.is_valid(joints)
        if invalid.any() and not cfg.drop_invalid_joints:
            r = int(np.argmax(invalid))
            try:
                robot.check_joints(joints[r])
                reason = "outside the robot's limits"
            except JointError as e:
                reason = str(e).split(" (q = ")[0]
            beta_cols = [cols[c] for c in schema.beta_columns(n)]
            read = {cols[c]: float(values[c][r]) for c in schema.beta_columns(n)}
            raise DatasetError(f"{log.where(self.line[r])}: joints outside the limits of robot "
                               f"{robot.name!r}: {reason}; columns {beta_cols} read {read} "
                               f"({cfg.beta_unit}). Fix the log, {log.units_hint}, or pass "
                               "--drop-invalid to drop such rows")
        self.keep(~invalid)
        if len(self.line) == 0:
            raise DatasetError(f"{src}: every row has joints outside the limits of robot {robot.name!r}")
        return joints[~invalid], invalid

    def check_order(self, sequence: np.ndarray) -> None:
        """Steps are exact integers, and time and step never go back within a sequence."""
        log, values, line = self.log, self.values, self.line
        if "step" in values:
            big = np.abs(values["step"]) >= MAX_EXACT_STEP
            if big.any():
                r = int(np.argmax(big))
                raise DatasetError(f"{log.where(line[r])}, {log.line_col('step')}: "
                                   f"{values['step'][r]:.17g} is at least 2^53, where float64 can no longer "
                                   "tell neighbouring integers apart (distinct samples would be averaged "
                                   "together); renumber the steps, e.g. from 0, or leave step unmapped")
            frac = values["step"] != np.round(values["step"])
            if frac.any():
                r = int(np.argmax(frac))
                raise DatasetError(f"{log.where(line[r])}, {log.line_col('step')}: "
                                   f"{values['step'][r]:g} is not an integer sample index")
        for f in ("time", "step"):
            if f in values:
                v = values[f]
                back = (sequence[1:] == sequence[:-1]) & (v[1:] < v[:-1])
                if back.any():
                    r = int(np.argmax(back)) + 1
                    raise DatasetError(f"{log.where(line[r])}, {log.line_col(f)}: {v[r]:g} comes "
                                       f"after {v[r - 1]:g}; the log must be sorted by {f} within each "
                                       "sequence")


@dataclass(eq=False)
class _Cleaned:
    """The samples kept after averaging and cleaning (K,), with what cleaning found."""

    samples: cleaning.Samples    # every averaged sample (S,), before outliers are dropped
    groups: np.ndarray           # (R,) sample of each reading
    idx: np.ndarray              # (K,) the kept samples among the S
    sequence: np.ndarray         # (K,) sequence index
    line: np.ndarray             # (K,) data row of each sample's first reading
    step: np.ndarray             # (K,) int64
    joints: np.ndarray           # (K, 2N) deg, mm
    position: np.ndarray         # (K, 3) mm
    tangent: np.ndarray          # (K, 3) unit
    glitch: np.ndarray           # (S,) joint glitches
    pose_out: np.ndarray         # (S,) pose outliers
    snap: np.ndarray             # (K,) bool
    snap_source: str             # "log" | "detected"
    distinct: np.ndarray         # (R,) readings of other joints than the previous one in its step


def _clean(rows: _Rows, sequence: np.ndarray, joints: np.ndarray, position: np.ndarray,
           tangent: np.ndarray, n: int, cc: CleaningConfig, src: str) -> _Cleaned:
    """Average repeated readings into samples, flag (or drop) glitches and pose outliers, read or
    detect snaps (ctrkin.data.cleaning)."""
    values = rows.values
    if cc.average_repeats:
        groups = cleaning.repeat_groups(sequence, joints, values.get("step"), cc.repeat_tol)
    else:
        groups = np.arange(len(rows.line))
    distinct = cleaning.distinct_in_step(sequence, joints, values.get("step"), cc.repeat_tol)
    samples = cleaning.average_readings(groups, joints, position, tangent, cc)
    first = samples.first
    s_seq, s_joints, s_pos, s_tan = sequence[first], samples.joints, samples.position, samples.tangent
    if "step" in values and not distinct.any():     # else the log's steps would repeat: renumbered
        s_step = values["step"][first].astype(np.int64)
    else:
        s_step = np.concatenate([np.arange(b - a) for a, b in schema.sequence_bounds(s_seq)]).astype(np.int64)
    glitch = np.zeros(len(first), dtype=bool)
    pose_out = np.zeros(len(first), dtype=bool)
    for a, b in schema.sequence_bounds(s_seq):
        glitch[a:b] = cleaning.glitch_mask(s_joints[a:b], n, cc)
        for c, d in cleaning.continuous_runs(s_joints[a:b], n, cc):
            pose_out[a + c:a + d] = cleaning.pose_outlier_mask(s_pos[a + c:a + d], s_tan[a + c:a + d], cc)
        pose_out[a:b] &= ~glitch[a:b]
    outlier = glitch | pose_out
    keep_s = ~outlier if cc.outliers == "drop" else np.ones(len(first), dtype=bool)
    idx = np.nonzero(keep_s)[0]
    if len(idx) == 0:
        raise DatasetError(f"{src}: cleaning removed every sample; check the cleaning thresholds")
    s_seq, s_joints, s_pos = s_seq[idx], s_joints[idx], s_pos[idx]
    if "snap" in values:
        snap = pd.Series(values["snap"] != 0).groupby(groups).any().to_numpy()[idx]
    else:
        snap = np.zeros(len(idx), dtype=bool)
        for a, b in schema.sequence_bounds(s_seq):
            snap[a:b] = cleaning.snap_mask(s_joints[a:b], s_pos[a:b], n, cc)
    return _Cleaned(samples, groups, idx, s_seq, rows.line[first][idx], s_step[idx], s_joints, s_pos,
                    s_tan[idx], glitch, pose_out, snap, "log" if "snap" in values else "detected",
                    distinct)


def _dataset(s: _Cleaned, rows: _Rows, seq_labels: list[str], robot: Robot, cfg: ImportConfig, mode: str,
             counts: dict[str, int]) -> Dataset:
    """The Dataset of the cleaned samples, with the cleaning report and noise estimate in its meta."""
    n, samples, idx = robot.n_tubes, s.samples, s.idx
    warnings: list[str] = []
    if np.abs(s.position).max() < 1.0:
        warnings.append("every tip position is within 1 mm of the origin: are the positions in metres? "
                        f"({rows.log.metres_hint})")
    if np.median(s.tangent[:, 2]) < 0:
        warnings.append("most tip tangents point backwards (-z): check the quaternion order "
                        "(--quat-order) and the tracker-to-robot registration")
    if s.distinct.any():
        first = rows.log.file_line(rows.line[int(np.argmax(s.distinct))])
        warnings.append(f"{int(s.distinct.sum())} readings share their step (or group) with readings "
                        f"of other joints (first: data line {first}): distinct configurations are never "
                        "averaged, so each became its own sample and the steps were numbered anew; if "
                        "they are repeated readings of one sample, set the repeat tolerance to the "
                        "encoder's resolution")
    seq_ids = np.unique(s.sequence, return_inverse=True)[1].astype(np.int64)  # renumber 0..K-1 after drops
    pose = np.column_stack([s.position, quat_from_tangent(s.tangent)])
    outlier = s.glitch | s.pose_out
    frame = pd.DataFrame({"sequence_id": seq_ids, "step": s.step,
                          **{c: s.joints[:, k] for k, c in enumerate(schema.joint_columns(n))},
                          **{c: pose[:, k] for k, c in enumerate(schema.POSE_COLUMNS)},
                          "snap": s.snap.astype(bool), "outlier": outlier[idx].astype(bool)})
    if "time" in rows.values:
        frame["time"] = rows.values["time"][samples.first][idx]
    frame["n_readings"] = samples.n_readings[idx]
    frame["source_line"] = np.array([rows.log.file_line(r) for r in s.line], dtype=np.int64)
    kept_labels = [seq_labels[k] for k in np.unique(s.sequence)]
    report = {
        **counts,
        "readings_rejected": samples.rejected,
        "readings_distinct_in_step": int(s.distinct.sum()),
        "samples_averaged": len(samples.first),
        "readings_per_sample": {"min": int(samples.n_readings.min()),
                                "median": float(np.median(samples.n_readings)),
                                "max": int(samples.n_readings.max())},
        "joint_glitches": int(s.glitch.sum()), "pose_outliers": int(s.pose_out.sum()),
        "outliers_action": "dropped" if cfg.cleaning.outliers == "drop" else "flagged",
        "samples": len(frame), "sequences": len(kept_labels),
        "snaps": int(s.snap.sum()), "snap_source": s.snap_source,
        "orientation": mode, "warnings": warnings,
    }
    meta = {
        "protocol": "import",
        "protocol_params": {},
        "seed": None,
        "sequence_labels": kept_labels,
        "import": cfg.to_dict(),
        "orientation": "absent" if mode == "absent" else "measured",
        "cleaning": report,
        "noise": {"source": "spread of repeated readings about their mean",
                  "position_std_mm": _finite_or_none(samples.position_std_mm),
                  "tangent_std_deg": None if mode == "absent" else _finite_or_none(samples.tangent_std_deg)},
    }
    return Dataset(frame=frame, robot=robot, meta=meta)


def _tangents(values: dict[str, np.ndarray], mode: str | None, line: np.ndarray, log: LogTable,
              src: str) -> np.ndarray:
    """(R, 3) unit tip tangents from the log's orientation columns (base z when absent)."""
    if mode == "absent":
        return np.tile([0.0, 0.0, 1.0], (len(line), 1))
    if mode == "tangent":
        t = np.column_stack([values[c] for c in ("tx", "ty", "tz")])
        norm = np.linalg.norm(t, axis=1)
        if (norm == 0).any():
            r = int(np.argmax(norm == 0))
            raise DatasetError(f"{log.where(line[r])}: the tangent (tx, ty, tz) is zero")
        return t / norm[:, None]
    names = ["qw", "qx", "qy", "qz"] if mode == "quaternion" else ["qw", "qx", "qy"]
    q = np.column_stack([values[c] for c in names])
    norm = np.linalg.norm(q, axis=1)
    off = np.abs(norm - 1.0) > schema.QUAT_NORM_TOL
    if off.any():
        r = int(np.argmax(off))
        used = [log.columns[c] for c in names]
        extra = "" if mode == "quaternion" else " (a 5-DOF quaternion needs qz = 0)"
        raise DatasetError(f"{log.where(line[r])}: the quaternion in columns {used} has norm "
                           f"{norm[r]:.4f}, not 1{extra}; {log.quaternion_hint}")
    return tangent_from_quaternion(q) if mode == "quaternion" else tangent_from_quat(q)


def _sequences(labels: np.ndarray | None, time: np.ndarray | None, line: np.ndarray, cfg: ImportConfig,
               log: LogTable, src: str) -> tuple[np.ndarray, list[str]]:
    """(R,) sequence index 0..K-1 in file order, and the K labels."""
    r_count = len(line)
    if labels is not None:
        start = np.r_[True, labels[1:] != labels[:-1]]
        seen: dict[str, int] = {}
        seq = np.empty(r_count, dtype=np.int64)
        k = -1
        for r in range(r_count):
            if start[r]:
                if labels[r] in seen:
                    raise DatasetError(
                        f"{log.where(line[r])}, {log.line_col('sequence_id')}: sequence "
                        f"{labels[r]!r} starts again after other sequences; the rows of a sequence "
                        "must be contiguous (sort the log by sequence, then time)")
                k += 1
                seen[str(labels[r])] = k
            seq[r] = k
        return seq, list(seen)
    new = np.zeros(r_count, dtype=bool)
    if time is not None and cfg.sequence_gap is not None and r_count > 1:
        dt = np.diff(time)
        if cfg.sequence_gap == "auto":
            positive = dt[dt > 0]
            gap = AUTO_GAP_FACTOR * float(np.median(positive)) if positive.size else np.inf
        else:
            gap = float(cfg.sequence_gap)
        new[1:] = dt > gap
    seq = np.cumsum(new).astype(np.int64)
    return seq, [f"segment {k}" for k in range(int(seq[-1]) + 1)]


def _finite_or_none(v: float) -> float | None:
    return v if np.isfinite(v) else None
