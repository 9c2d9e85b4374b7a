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
becomes the dataset's (q0, qx, qy) through the tip tangent R e3 (pose.quat_from_tangent).

Without sequence_id, the log is one sequence, unless it has time stamps and `sequence_gap` is set:
a time gap larger than `sequence_gap` (in the log's time unit), or with "auto" larger than
AUTO_GAP_FACTOR times the median time step, starts a new sequence (logging was interrupted, so
the history seen by the input buffer is broken there).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd

from ctrkin.data import cleaning, schema
from ctrkin.data.cleaning import CleaningConfig
from ctrkin.data.dataset import Dataset
from ctrkin.errors import DatasetError, JointError
from ctrkin.pose import quat_from_tangent
from ctrkin.robots.robot import Robot

AngleUnit = Literal["deg", "rad"]
LengthUnit = Literal["mm", "m"]
QuaternionOrder = Literal["wxyz", "xyzw"]
AUTO_GAP_FACTOR = 10.0
QUAT_NORM_TOL = 0.05          # a unit quaternion read with the wrong columns is rarely this close to 1
LENGTH_TO_MM = {"mm": 1.0, "m": 1000.0}
OPTIONAL_FIELDS = ("sequence_id", "time", "step", "snap")
ORIENTATION_FIELDS = ("q0", "qw", "qx", "qy", "qz", "tx", "ty", "tz")


def fields(n_tubes: int) -> list[str]:
    """Every field a log column can be mapped to, for an N-tube robot."""
    return [*schema.joint_columns(n_tubes), "x", "y", "z", *ORIENTATION_FIELDS, *OPTIONAL_FIELDS]


@dataclass(frozen=True)
class ImportConfig:
    """How to read a log. mapping: (log column, field) pairs (module docstring); units of the log's
    angles (alpha), joint lengths (beta) and positions; quaternion_columns: four log columns holding
    a full quaternion in `quaternion_order` (shorthand for mapping qw, qx, qy, qz); sequence_gap:
    None (never split), "auto" or a time gap in the log's time unit; drop_invalid_joints /
    drop_incomplete: drop rows with joints outside the robot's limits / with empty or NaN cells
    instead of failing; unwrap: unwrap the alpha columns (for logs that wrap angles to ±180°)."""

    mapping: tuple[tuple[str, str], ...] = ()
    angle_unit: AngleUnit = "deg"
    beta_unit: LengthUnit = "mm"
    position_unit: LengthUnit = "mm"
    quaternion_columns: tuple[str, ...] = ()
    quaternion_order: QuaternionOrder = "wxyz"
    sequence_gap: float | Literal["auto"] | None = "auto"
    drop_invalid_joints: bool = False
    drop_incomplete: bool = False
    unwrap: bool = False
    delimiter: str = ","
    cleaning: CleaningConfig = field(default_factory=CleaningConfig)

    def __post_init__(self) -> None:
        object.__setattr__(self, "mapping", tuple((str(c), str(f)) for c, f in self.mapping))
        object.__setattr__(self, "quaternion_columns", tuple(self.quaternion_columns))
        if self.angle_unit not in ("deg", "rad"):
            raise DatasetError(f"angle unit must be 'deg' or 'rad', got {self.angle_unit!r}")
        for name in ("beta_unit", "position_unit"):
            if getattr(self, name) not in LENGTH_TO_MM:
                raise DatasetError(f"{name} must be 'mm' or 'm', got {getattr(self, name)!r}")
        if self.quaternion_order not in ("wxyz", "xyzw"):
            raise DatasetError(f"quaternion order must be 'wxyz' or 'xyzw', got {self.quaternion_order!r}")
        if self.quaternion_columns and len(self.quaternion_columns) != 4:
            raise DatasetError(f"quaternion_columns needs four log columns (in {self.quaternion_order} "
                               f"order), got {list(self.quaternion_columns)}")
        gap = self.sequence_gap
        if gap is not None and gap != "auto" and not (isinstance(gap, int | float) and gap > 0):
            raise DatasetError(f"sequence_gap must be None, 'auto' or a positive time gap, got {gap!r}")
        if not isinstance(self.delimiter, str) or len(self.delimiter) != 1:
            raise DatasetError(f"delimiter must be one character, got {self.delimiter!r}")
        fields_seen: dict[str, str] = {}
        for col, fld in self.field_mapping():
            if fld in fields_seen:
                raise DatasetError(f"field {fld!r} is mapped twice (from columns {fields_seen[fld]!r} "
                                   f"and {col!r}); map each field once")
            fields_seen[fld] = col

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, str], **kw: Any) -> ImportConfig:
        """ImportConfig from a {log column: field} dict."""
        return cls(mapping=tuple(mapping.items()), **kw)

    def field_mapping(self) -> list[tuple[str, str]]:
        """(log column, field) pairs including the quaternion_columns shorthand."""
        pairs = list(self.mapping)
        if self.quaternion_columns:
            names = ("qw", "qx", "qy", "qz") if self.quaternion_order == "wxyz" else ("qx", "qy", "qz", "qw")
            pairs += list(zip(self.quaternion_columns, names, strict=True))
        return pairs

    def to_dict(self) -> dict[str, object]:
        return {"mapping": dict(self.mapping), "angle_unit": self.angle_unit, "beta_unit": self.beta_unit,
                "position_unit": self.position_unit, "quaternion_columns": list(self.quaternion_columns),
                "quaternion_order": self.quaternion_order, "sequence_gap": self.sequence_gap,
                "drop_invalid_joints": self.drop_invalid_joints, "drop_incomplete": self.drop_incomplete,
                "unwrap": self.unwrap, "delimiter": self.delimiter, "cleaning": self.cleaning.to_dict()}


def _line(row: int) -> int:
    """File line of data row `row` (0-based), the header being line 1."""
    return row + 2


class _Log:
    """The raw CSV with its field -> column resolution; errors name the file, line and column."""

    def __init__(self, path: Path, robot: Robot, cfg: ImportConfig) -> None:
        self.path, self.robot, self.cfg = path, robot, cfg
        try:
            raw = pd.read_csv(path, sep=cfg.delimiter, dtype=str, keep_default_na=False,
                              skipinitialspace=True, skip_blank_lines=False)
        except FileNotFoundError:
            raise DatasetError(f"log file {path} does not exist") from None
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
            raise DatasetError(f"{path} is not a readable CSV file: {e}") from None
        raw = raw.fillna("")  # cells missing from short rows
        raw.columns = [str(c).strip() for c in raw.columns]
        blank = (raw.apply(lambda c: c.str.strip()) == "").all(axis=1).to_numpy()
        tail = len(blank)
        while tail > 0 and blank[tail - 1]:
            tail -= 1
        self.raw = raw.iloc[:tail]
        self.field_names: dict[str, str] = {}
        if len(self.raw) == 0:
            raise DatasetError(f"{path} has a header but no data rows")
        self.columns = self._resolve()

    def _resolve(self) -> dict[str, str]:
        n = self.robot.n_tubes
        known = fields(n)
        cols = list(self.raw.columns)
        columns: dict[str, str] = {}
        for col, fld in self.cfg.field_mapping():
            if fld not in known:
                raise DatasetError(f"--map {col}={fld}: unknown field {fld!r}; fields for a {n}-tube "
                                   f"robot: {known}")
            if col not in cols:
                raise DatasetError(f"--map {col}={fld}: {self.path} has no column {col!r}; its columns "
                                   f"are {cols}")
            columns[fld] = col
        mapped_cols = set(columns.values())
        for fld in known:
            if fld not in columns and fld in cols and fld not in mapped_cols:
                columns[fld] = fld
        if "q0" in columns and "qw" in columns:
            raise DatasetError(f"{self.path}: both q0 and qw are given; they are the same scalar part, "
                               "map only one")
        if "q0" in columns:
            columns["qw"] = columns.pop("q0")
            self.field_names["qw"] = "q0"  # errors use the name the user gave
        required = [*schema.joint_columns(n), "x", "y", "z"]
        missing = [f for f in required if f not in columns]
        if self.orientation_mode(columns) is None:
            missing.append("orientation: q0,qx,qy (5-DOF) or qw,qx,qy,qz or tx,ty,tz")
        if missing:
            raise DatasetError(f"{self.path}: missing column(s) for {missing}. The log's columns are "
                               f"{cols}; name them like the fields or map them with "
                               "--map LOG_COLUMN=FIELD")
        return columns

    @staticmethod
    def orientation_mode(columns: Mapping[str, str]) -> str | None:
        if all(f in columns for f in ("qw", "qx", "qy", "qz")):
            return "quaternion"
        if all(f in columns for f in ("tx", "ty", "tz")):
            return "tangent"
        if all(f in columns for f in ("qw", "qx", "qy")) and "qz" not in columns:
            return "5dof"
        return None

    def numbers(self, fld: str) -> np.ndarray:
        """(R,) floats of the column mapped to `fld`; NaN for empty or NaN cells. Text that is not a
        number is an error naming the line and column."""
        col = self.columns[fld]
        text = self.raw[col].str.strip()
        vals = pd.to_numeric(text, errors="coerce").to_numpy(dtype=float)
        empty = text.str.lower().isin(["", "nan", "na", "null", "none"]).to_numpy()
        bad = np.isnan(vals) & ~empty
        if bad.any():
            r = int(np.argmax(bad))
            raise DatasetError(f"{self.path}: line {_line(r)}, {self.line_col(fld)}: "
                               f"{text.iloc[r]!r} is not a number")
        return vals

    def line_col(self, fld: str) -> str:
        return f"column {self.columns[fld]!r} ({self.field_names.get(fld, fld)})"


def import_csv(path: str | Path, robot: Robot, config: ImportConfig | None = None) -> Dataset:
    """Read a log file (CSV, one row a reading) into a cleaned Dataset (module docstring).

    The cleaning report (counts per rule) is meta["cleaning"], the tracker noise estimated from the
    spread of repeated readings meta["noise"], the resolved configuration meta["import"].
    """
    cfg = config or ImportConfig()
    src = Path(path)
    log = _Log(src, robot, cfg)
    n = robot.n_tubes
    cols = log.columns
    mode = log.orientation_mode(cols)
    pose_fields = ["x", "y", "z"] + {"quaternion": ["qw", "qx", "qy", "qz"], "tangent": ["tx", "ty", "tz"],
                                     "5dof": ["qw", "qx", "qy"]}[str(mode)]
    numeric = schema.joint_columns(n) + pose_fields + [f for f in ("time", "step", "snap") if f in cols]
    values = {f: log.numbers(f) for f in numeric}
    rows_read = len(log.raw)
    line = np.arange(rows_read)

    # --- incomplete rows ---------------------------------------------------------------------------
    nan = np.zeros(rows_read, dtype=bool)
    for f in numeric:
        if f == "snap":
            continue
        col_nan = ~np.isfinite(values[f])
        if col_nan.any() and not cfg.drop_incomplete:
            r = int(np.argmax(col_nan))
            raise DatasetError(f"{src}: line {_line(r)}, {log.line_col(f)} is empty, NaN or inf; fix "
                               "the log or pass --drop-incomplete to skip such rows")
        nan |= col_nan
    if "snap" in values:
        values["snap"] = np.nan_to_num(values["snap"], nan=0.0)
    labels = log.raw[cols["sequence_id"]].str.strip().to_numpy() if "sequence_id" in cols else None
    if labels is not None:
        empty_label = labels == ""
        if empty_label.any() and not cfg.drop_incomplete:
            r = int(np.argmax(empty_label))
            raise DatasetError(f"{src}: line {_line(r)}, {log.line_col('sequence_id')} is empty; fix the "
                               "log or pass --drop-incomplete")
        nan |= empty_label
    keep = ~nan
    values = {f: v[keep] for f, v in values.items()}
    line = line[keep]
    labels = labels[keep] if labels is not None else None
    if len(line) == 0:
        raise DatasetError(f"{src}: no complete rows left")

    # --- joints: units, limits ----------------------------------------------------------------------
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
        raise DatasetError(f"{src}: line {_line(line[r])}: joints outside the limits of robot "
                           f"{robot.name!r}: {reason}; columns {beta_cols} read {read} "
                           f"({cfg.beta_unit}). Fix the log, check --units and --map, or pass "
                           "--drop-invalid to drop such rows")
    ok = ~invalid
    joints, line = joints[ok], line[ok]
    values = {f: v[ok] for f, v in values.items()}
    labels = labels[ok] if labels is not None else None
    if len(line) == 0:
        raise DatasetError(f"{src}: every row has joints outside the limits of robot {robot.name!r}")

    # --- pose: units, orientation -------------------------------------------------------------------
    position = np.column_stack([values[c] for c in ("x", "y", "z")]) * LENGTH_TO_MM[cfg.position_unit]
    tangent = _tangents(values, mode, line, log, src)
    warnings: list[str] = []

    # --- sequences and time order -------------------------------------------------------------------
    sequence, seq_labels = _sequences(labels, values.get("time"), line, cfg, log, src)
    if "step" in values:
        # a float holds integers exactly only below 2^53: larger steps would merge distinct samples
        frac = (values["step"] != np.round(values["step"])) | (np.abs(values["step"]) >= 2.0**53)
        if frac.any():
            r = int(np.argmax(frac))
            raise DatasetError(f"{src}: line {_line(line[r])}, {log.line_col('step')}: "
                               f"{values['step'][r]:g} is not an integer sample index below 2^53")
    for f in ("time", "step"):
        if f in values:
            v = values[f]
            back = (sequence[1:] == sequence[:-1]) & (v[1:] < v[:-1])
            if back.any():
                r = int(np.argmax(back)) + 1
                raise DatasetError(f"{src}: line {_line(line[r])}, {log.line_col(f)}: {v[r]:g} comes "
                                   f"after {v[r - 1]:g}; the log must be sorted by {f} within each "
                                   "sequence")
    if cfg.unwrap:
        for a, b in schema.sequence_bounds(sequence):
            joints[a:b, :n] = np.unwrap(joints[a:b, :n], period=360.0, axis=0)

    # --- cleaning -----------------------------------------------------------------------------------
    cc = cfg.cleaning
    if cc.average_repeats:
        groups = cleaning.repeat_groups(sequence, joints, values.get("step"), cc.repeat_tol)
    else:
        groups = np.arange(len(line))
    samples = cleaning.average_readings(groups, joints, position, tangent, cc)
    first = samples.first
    s_seq, s_line = sequence[first], line[first]
    s_joints, s_pos, s_tan = samples.joints, samples.position, samples.tangent
    if "step" in values:
        s_step = values["step"][first].astype(np.int64)
    else:
        s_step = np.concatenate([np.arange(b - a) for a, b in schema.sequence_bounds(s_seq)]).astype(np.int64)
    glitch = np.zeros(len(first), dtype=bool)
    pose_out = np.zeros(len(first), dtype=bool)
    for a, b in schema.sequence_bounds(s_seq):
        glitch[a:b] = cleaning.glitch_mask(s_joints[a:b], n, cc)
        pose_out[a:b] = cleaning.pose_outlier_mask(s_pos[a:b], s_tan[a:b], cc) & ~glitch[a:b]
    outlier = glitch | pose_out
    keep_s = ~outlier if cc.outliers == "drop" else np.ones(len(first), dtype=bool)
    idx = np.nonzero(keep_s)[0]
    if len(idx) == 0:
        raise DatasetError(f"{src}: cleaning removed every sample; check the cleaning thresholds")
    s_seq, s_line, s_step = s_seq[idx], s_line[idx], s_step[idx]
    s_joints, s_pos, s_tan = s_joints[idx], s_pos[idx], s_tan[idx]
    if "snap" in values:
        snap_read = pd.Series(values["snap"] != 0).groupby(groups).any().to_numpy()
        snap = snap_read[idx]
    else:
        snap = np.zeros(len(idx), dtype=bool)
        for a, b in schema.sequence_bounds(s_seq):
            snap[a:b] = cleaning.snap_mask(s_joints[a:b], s_pos[a:b], n, cc)
    if np.abs(s_pos).max() < 1.0:
        warnings.append("every tip position is within 1 mm of the origin: are the positions in metres? "
                        "(--units position=m)")
    if np.median(s_tan[:, 2]) < 0:
        warnings.append("most tip tangents point backwards (-z): check the quaternion order "
                        "(--quat-order) and the tracker-to-robot registration")

    # --- the dataset --------------------------------------------------------------------------------
    seq_ids = np.unique(s_seq, return_inverse=True)[1].astype(np.int64)  # renumber 0..K-1 after drops
    pose = np.column_stack([s_pos, quat_from_tangent(s_tan)])
    frame = pd.DataFrame({"sequence_id": seq_ids, "step": s_step,
                          **{c: s_joints[:, k] for k, c in enumerate(schema.joint_columns(n))},
                          **{c: pose[:, k] for k, c in enumerate(schema.POSE_COLUMNS)},
                          "snap": snap.astype(bool), "outlier": outlier[idx].astype(bool)})
    if "time" in values:
        frame["time"] = values["time"][first][idx]
    frame["n_readings"] = samples.n_readings[idx]
    frame["source_line"] = np.array([_line(r) for r in s_line], dtype=np.int64)
    kept_labels = [seq_labels[k] for k in np.unique(s_seq)]
    report = {
        "rows_read": rows_read,
        "rows_incomplete_dropped": int(nan.sum()),
        "rows_invalid_joints_dropped": int(invalid.sum()),
        "readings_rejected": samples.rejected,
        "samples_averaged": len(first),
        "readings_per_sample": {"min": int(samples.n_readings.min()),
                                "median": float(np.median(samples.n_readings)),
                                "max": int(samples.n_readings.max())},
        "joint_glitches": int(glitch.sum()), "pose_outliers": int(pose_out.sum()),
        "outliers_action": "dropped" if cc.outliers == "drop" else "flagged",
        "samples": len(frame), "sequences": len(kept_labels),
        "snaps": int(snap.sum()), "snap_source": "log" if "snap" in values else "detected",
        "orientation": mode, "warnings": warnings,
    }
    meta = {
        "protocol": "import",
        "protocol_params": {"source": src.name, "sha256": _sha256(src)},
        "seed": None,
        "sequence_labels": kept_labels,
        "import": cfg.to_dict(),
        "cleaning": report,
        "noise": {"source": "spread of repeated readings about their mean",
                  "position_std_mm": _finite_or_none(samples.position_std_mm),
                  "tangent_std_deg": _finite_or_none(samples.tangent_std_deg)},
    }
    return Dataset(frame=frame, robot=robot, meta=meta)


def _tangents(values: dict[str, np.ndarray], mode: str | None, line: np.ndarray, log: _Log,
              src: Path) -> np.ndarray:
    """(R, 3) unit tip tangents from the log's orientation columns."""
    if mode == "tangent":
        t = np.column_stack([values[c] for c in ("tx", "ty", "tz")])
        norm = np.linalg.norm(t, axis=1)
        if (norm == 0).any():
            r = int(np.argmax(norm == 0))
            raise DatasetError(f"{src}: line {_line(line[r])}: the tangent (tx, ty, tz) is zero")
        return t / norm[:, None]
    names = ["qw", "qx", "qy", "qz"] if mode == "quaternion" else ["qw", "qx", "qy"]
    q = np.column_stack([values[c] for c in names])
    norm = np.linalg.norm(q, axis=1)
    off = np.abs(norm - 1.0) > QUAT_NORM_TOL
    if off.any():
        r = int(np.argmax(off))
        used = [log.columns[c] for c in names]
        extra = "" if mode == "quaternion" else " (a 5-DOF quaternion needs qz = 0)"
        raise DatasetError(f"{src}: line {_line(line[r])}: the quaternion in columns {used} has norm "
                           f"{norm[r]:.4f}, not 1{extra}; check --map, --quaternion and --quat-order")
    q = q / norm[:, None]
    w, x, y = q[:, 0], q[:, 1], q[:, 2]
    z = q[:, 3] if mode == "quaternion" else np.zeros_like(w)
    # third column of the rotation matrix of (w, x, y, z): the tip tangent R e3
    return np.column_stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])


def _sequences(labels: np.ndarray | None, time: np.ndarray | None, line: np.ndarray, cfg: ImportConfig,
               log: _Log, src: Path) -> tuple[np.ndarray, list[str]]:
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
                        f"{src}: line {_line(line[r])}, {log.line_col('sequence_id')}: sequence "
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


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _finite_or_none(v: float) -> float | None:
    return v if np.isfinite(v) else None
