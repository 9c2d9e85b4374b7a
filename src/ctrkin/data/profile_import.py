"""Import logs with a profile (profile.py): several files make one dataset, each file a sequence.

Per file: read the cells as text; drop the rows a profile names (all-zero padding, a status value);
number the groups of repeated readings (fixed count, counted on the file's rows before dropping, or
"joints unchanged"); apply scale, offset and the travel zero; express the tip relative to the reference
body if there is one; then the rows go through the ordinary importer (importer.py: averaging,
outliers, snaps), with messages naming the file and line of the log.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import pandas as pd

from ctrkin.data.dataset import Dataset
from ctrkin.data.importer import ImportConfig, import_frame
from ctrkin.data.log_table import LogTable, file_sha256
from ctrkin.data.profile import ColumnSpec, Profile
from ctrkin.errors import DatasetError
from ctrkin.geometry import POSITION_COLUMNS, matrix_to_quaternion, quaternion_to_matrix
from ctrkin.robots.robot import Robot

LENGTH_TO_MM = {"mm": 1.0, "m": 1000.0}


def relative_pose(p_tip: np.ndarray, q_tip: np.ndarray | None, p_ref: np.ndarray,
                  q_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Tip pose in a reference body's frame: p = R_refᵀ (p_tip − p_ref), R = R_refᵀ R_tip.
    p_*: (R, 3); q_*: (R, 4) (w, x, y, z); q_tip may be None (position only)."""
    R_ref = quaternion_to_matrix(q_ref)
    p = np.einsum("rji,rj->ri", R_ref, p_tip - p_ref)
    if q_tip is None:
        return p, None
    R = np.einsum("rji,rjk->rik", R_ref, quaternion_to_matrix(q_tip))
    return p, matrix_to_quaternion(R)


class _File:
    """One log file's cells (text) with column lookup by position or header name. Rows may have
    different lengths (a tracker that leaves out a missing tool's fields): short rows are padded
    with empty cells. Blank lines are skipped; `lines` keeps each row's line in the file."""

    def __init__(self, path: Path, profile: Profile) -> None:
        self.path = path
        try:
            text = path.read_text()
        except FileNotFoundError:
            raise DatasetError(f"log file {path} does not exist") from None
        except UnicodeDecodeError as e:
            raise DatasetError(f"{path} is not a readable CSV file: {e}") from None
        reader = csv.reader(io.StringIO(text), delimiter=profile.delimiter)
        rows, lines = [], []
        try:
            for row in reader:
                if any(c.strip() for c in row):
                    rows.append(row)
                    lines.append(reader.line_num)
        except csv.Error as e:
            raise DatasetError(f"{path} is not a readable CSV file: {e}") from None
        if profile.header:
            if not rows:
                raise DatasetError(f"{path} is empty")
            head, rows, lines = rows[0], rows[1:], lines[1:]
        width = max((len(r) for r in rows), default=0)
        if profile.header:
            width = max(width, len(head))
            self.names = [c.strip() for c in head] + [""] * (width - len(head))
        else:
            self.names = [str(k) for k in range(width)]
        self.raw = pd.DataFrame([r + [""] * (width - len(r)) for r in rows], dtype=str,
                                columns=range(width) if width else None)
        self.lines = np.array(lines, dtype=np.int64)

    def cells(self, ref: int | str, what: str) -> pd.Series:
        if isinstance(ref, int):
            if ref > self.raw.shape[1]:
                raise DatasetError(f"{self.path}: {what}: column {ref} does not exist; the file has "
                                   f"{self.raw.shape[1]} columns")
            return self.raw.iloc[:, ref - 1].str.strip()
        if ref not in self.names:
            raise DatasetError(f"{self.path}: {what}: no column named {ref!r}; its columns are {self.names}"
                               + ("" if self.names and not self.names[0].replace(".", "").isdigit()
                                  else " (a file without a header row: use [file] header = false and "
                                       "column positions)"))
        return self.raw.iloc[:, self.names.index(ref)].str.strip()

    def numbers(self, spec: ColumnSpec, what: str, keep: np.ndarray | None = None) -> np.ndarray:
        """scale · cell + offset; NaN for empty cells. Text that is not a number is an error in the
        rows kept (keep; default all), NaN in rows a [drop] rule removes."""
        text = self.cells(spec.column, what)
        vals = pd.to_numeric(text, errors="coerce").to_numpy(dtype=float)
        bad = np.isnan(vals) & (text != "").to_numpy() & (True if keep is None else keep)
        if bad.any():
            r = int(np.argmax(bad))
            raise DatasetError(f"{self.path}: line {self.lines[r]}, column {spec.column!r} ({what}): "
                               f"{text.iloc[r]!r} is not a number")
        return spec.scale * vals + spec.offset


def _beta_zero(spec: ColumnSpec, robot: Robot, field: str) -> float:
    if spec.zero is None:
        return 0.0
    if spec.zero == "straight_length":
        i = int(field.split("_")[1]) - 1
        return -float(robot.tubes[i].straight_length)
    return float(spec.zero)


def _drops(f: _File, profile: Profile, counts: dict[str, int]) -> np.ndarray:
    """(R,) rows kept after [drop]: all-zero padding, then the status rules."""
    keep = np.ones(len(f.raw), dtype=bool)
    if profile.drop_all_zero and len(f.raw):
        numeric = pd.DataFrame({c: pd.to_numeric(f.raw[c].str.strip(), errors="coerce")
                                for c in f.raw.columns})
        used = numeric.loc[:, numeric.notna().any(axis=0)]
        zero = (used.fillna(0.0) == 0).all(axis=1).to_numpy()
        counts["rows_all_zero"] = int((zero & keep).sum())
        keep &= ~zero
    for rule in profile.status:
        ok = f.cells(rule.column, "status").isin(rule.keep).to_numpy()
        counts["rows_status"] += int((~ok & keep).sum())
        keep &= ok
    return keep


def _check_expect(f: _File, profile: Profile, keep: np.ndarray) -> None:
    """[expect]: columns that stay zero or equal another in every kept row (the robot the profile
    describes); the first row that breaks one is an error with the profile's hint."""
    hint = f"; {profile.expect_hint}" if profile.expect_hint else ""
    for col in profile.expect_zero:
        v = f.numbers(ColumnSpec(col), "[expect] zero", keep)
        bad = keep & np.isfinite(v) & (v != 0)
        if bad.any():
            r = int(np.argmax(bad))
            raise DatasetError(f"{f.path}: line {f.lines[r]}, column {col!r} reads {v[r]:g} where "
                               f"{profile.source} [expect] says it stays 0: this log moves a joint the "
                               f"profile does not map{hint}")
    for a, b in profile.expect_equal:
        va = f.numbers(ColumnSpec(a), "[expect] equal", keep)
        vb = f.numbers(ColumnSpec(b), "[expect] equal", keep)
        bad = keep & (np.abs(va - vb) > 1e-9)
        if bad.any():
            r = int(np.argmax(bad))
            raise DatasetError(f"{f.path}: line {f.lines[r]}: columns {a!r} and {b!r} read {va[r]:g} and "
                               f"{vb[r]:g} where {profile.source} [expect] says they are equal: this log "
                               f"moves a joint the profile does not map{hint}")


def _check_groups(f: _File, profile: Profile, joints: np.ndarray, padding: np.ndarray) -> None:
    """[groups] count must be the log's readings per configuration: the joints stay the same within
    each group, and the runs of equal joints (padding rows left out) are `count` rows long. A wrong
    count would average different configurations, or split one into several "samples"."""
    count = profile.group_count
    rows = np.nonzero(~padding)[0]
    if count == 0 or len(rows) < 2:
        return
    q = np.round(joints[rows], 9)
    change = np.r_[True, (q[1:] != q[:-1]).any(axis=1) & ~(np.isnan(q[1:]) & np.isnan(q[:-1])).all(axis=1)]
    starts = np.nonzero(change)[0]
    runs = np.diff(np.r_[starts, len(rows)])
    values, freq = np.unique(runs, return_counts=True)
    typical = int(values[np.argmax(freq * values)])          # the run length most rows belong to
    where = f"{profile.source}: [groups] count = {count}"
    group = rows // count
    mixed = np.nonzero(change[1:] & (group[1:] == group[:-1]))[0]
    if mixed.size:
        r = rows[mixed[0] + 1]
        raise DatasetError(f"{f.path}: line {f.lines[r]}: the joints change inside a group of {count} "
                           f"readings ({where}); in this log a configuration lasts {typical} rows: set "
                           f"[groups] count = {typical} (or joints_unchanged = true)")
    if typical != count and typical % count == 0 and (runs == typical).mean() >= 0.5:
        raise DatasetError(f"{f.path}: {where}, but the joints stay the same for {typical} rows: each "
                           f"configuration would be split into {typical // count} samples; set [groups] "
                           f"count = {typical} (or joints_unchanged = true)")


def read_file(path: Path, profile: Profile, robot: Robot, label: str
              ) -> tuple[pd.DataFrame, list[tuple[str, int]], dict[str, int]]:
    """One file -> (fields as text in dataset units, (file, line) per row, drop counts)."""
    f = _File(path, profile)
    n_rows = len(f.raw)
    counts = {"rows_read": n_rows, "rows_all_zero": 0, "rows_status": 0}
    keep = _drops(f, profile, counts)
    padding = np.zeros(n_rows, dtype=bool)
    if profile.drop_all_zero:
        padding = ~keep.copy()
        for rule in profile.status:                        # status drops are not padding
            padding &= f.cells(rule.column, "status").isin(rule.keep).to_numpy() | (
                f.cells(rule.column, "status") == "").to_numpy()
    _check_expect(f, profile, keep)
    vals = {k: f.numbers(s, k, keep) for k, s in profile.columns.items()}
    ref = {k: f.numbers(s, f"reference {k}", keep) for k, s in profile.reference.items()}
    joint_keys = [k for k in vals if k.startswith(("alpha_", "beta_"))]
    lenient = {k: f.numbers(profile.columns[k], k, np.zeros(n_rows, dtype=bool)) for k in joint_keys}
    _check_groups(f, profile, np.column_stack([lenient[k] for k in joint_keys]), padding)
    for k, spec in profile.columns.items():
        if k.startswith("beta_"):
            vals[k] = vals[k] + _beta_zero(spec, robot, k)
    unit = LENGTH_TO_MM[profile.position_unit]
    p_tip = np.column_stack([vals[k] for k in POSITION_COLUMNS]) * unit
    q_tip = None
    if profile.orientation == "tangent":
        q_tip = np.column_stack([vals[k] for k in ("qw", "qx", "qy", "qz")])
    if ref:
        p_ref = np.column_stack([ref[k] for k in POSITION_COLUMNS]) * unit
        q_ref = np.column_stack([ref[k] for k in ("qw", "qx", "qy", "qz")])
        bad = keep & ~(np.isfinite(q_ref).all(axis=1) & (np.linalg.norm(q_ref, axis=1) > 0.5))
        if bad.any():
            r = int(np.argmax(bad))
            raise DatasetError(f"{path}: line {f.lines[r]}: the reference body's quaternion is "
                               "missing or not a unit quaternion; drop such rows ([drop] status) or fix "
                               "[reference]")
        safe = np.where(keep[:, None], q_ref, [1.0, 0.0, 0.0, 0.0])
        p_tip, q_tip = relative_pose(p_tip, q_tip, p_ref, safe)
    out = {k: v for k, v in vals.items() if k.startswith(("alpha_", "beta_"))}
    out.update(x=p_tip[:, 0], y=p_tip[:, 1], z=p_tip[:, 2])
    if q_tip is not None:
        out.update(qw=q_tip[:, 0], qx=q_tip[:, 1], qy=q_tip[:, 2], qz=q_tip[:, 3])
    if profile.group_count:
        out["step"] = np.arange(n_rows) // profile.group_count
    frame = pd.DataFrame({k: np.asarray(v, dtype=float) for k, v in out.items()})
    text = frame.map(lambda v: "" if not np.isfinite(v) else format(float(v), ".17g"))
    if "step" in text:
        text["step"] = [str(int(v)) for v in out["step"]]
    text["sequence_id"] = label
    origins = [(str(path), int(line)) for line in f.lines]
    idx = np.nonzero(keep)[0]
    return text.iloc[idx].reset_index(drop=True), [origins[r] for r in idx], counts


def import_with_profile(paths: list[str | Path], profile: Profile, robot: Robot,
                        config: ImportConfig | None = None) -> Dataset:
    """Logs (one sequence per file, in the order given) -> one cleaned Dataset. config: cleaning
    and drop options of the ordinary importer (its column mapping and units are ignored)."""
    if not paths:
        raise DatasetError("no log files given")
    parts, origins, report = [], [], []
    labels: list[str] = []
    for p in map(Path, paths):
        label = p.stem if p.stem not in labels else f"{p.stem}#{len(labels)}"
        labels.append(label)
        text, orig, counts = read_file(p, profile, robot, label)
        if len(text) == 0:
            raise DatasetError(f"{p}: no rows left after [drop] (read {counts['rows_read']}, all-zero "
                               f"{counts['rows_all_zero']}, status {counts['rows_status']})")
        parts.append(text)
        origins += orig
        report.append({"file": p.name, **counts, "sha256": file_sha256(p)})
    base = config or ImportConfig()
    cfg = ImportConfig(
        position_only=profile.orientation != "tangent", sequence_gap=None,
        drop_invalid_joints=bool(base.drop_invalid_joints), drop_incomplete=bool(base.drop_incomplete),
        unwrap=bool(base.unwrap), cleaning=base.cleaning,
        quaternion_columns=("qw", "qx", "qy", "qz") if profile.orientation == "tangent" else ())
    if profile.group_count == 0 and not profile.joints_unchanged:
        # every row its own sample: a fresh step per row stops the importer merging equal joints
        for t in parts:
            t["step"] = [str(k) for k in range(len(t))]
    raw = pd.concat(parts, ignore_index=True)
    label = ", ".join(str(p) for p in paths)
    log = LogTable(Path(paths[0]), robot, cfg, raw=raw, origins=origins, profile=profile.source)
    ds = import_frame(log, robot, cfg, label)
    ds.meta["protocol_params"] = {"source": [r["file"] for r in report], "profile": profile.source}
    ds.meta["import"].update(profile=profile.to_dict(), files=report)
    ds.meta["cleaning"]["profile_drops"] = {
        "rows_all_zero": sum(int(str(r["rows_all_zero"])) for r in report),
        "rows_status": sum(int(str(r["rows_status"])) for r in report)}
    return ds
