"""Import logs with a profile (profile.py): several files make one dataset, each file a sequence.

Per file: read the cells as text; drop the rows a profile names (all-zero padding, a status value);
number the groups of repeated readings (fixed count, counted on the file's rows before dropping, or
"joints unchanged"); apply scale, offset and the travel zero; express the tip relative to the reference
body if there is one; then the rows go through the ordinary importer (importer.py: averaging,
outliers, snaps), with messages naming the file and line of the log.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ctrkin.data.dataset import Dataset
from ctrkin.data.importer import ImportConfig, _Log, _sha256, import_frame
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
    """One log file's cells (text) with column lookup by position or header name."""

    def __init__(self, path: Path, profile: Profile) -> None:
        self.path = path
        try:
            raw = pd.read_csv(path, sep=profile.delimiter, dtype=str, keep_default_na=False,
                              header=0 if profile.header else None, skipinitialspace=True)
        except FileNotFoundError:
            raise DatasetError(f"log file {path} does not exist") from None
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
            raise DatasetError(f"{path} is not a readable CSV file: {e}") from None
        self.raw = raw.fillna("")
        self.first_line = 2 if profile.header else 1
        self.names = [str(c).strip() for c in self.raw.columns]

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

    def numbers(self, spec: ColumnSpec, what: str) -> np.ndarray:
        text = self.cells(spec.column, what)
        vals = pd.to_numeric(text, errors="coerce").to_numpy(dtype=float)
        bad = np.isnan(vals) & (text != "").to_numpy()
        if bad.any():
            r = int(np.argmax(bad))
            raise DatasetError(f"{self.path}: line {r + self.first_line}, column {spec.column!r} ({what}): "
                               f"{text.iloc[r]!r} is not a number")
        return spec.scale * vals + spec.offset


def _beta_zero(spec: ColumnSpec, robot: Robot, field: str) -> float:
    if spec.zero is None:
        return 0.0
    if spec.zero == "straight_length":
        i = int(field.split("_")[1]) - 1
        return -float(robot.tubes[i].straight_length)
    return float(spec.zero)


def read_file(path: Path, profile: Profile, robot: Robot, label: str
              ) -> tuple[pd.DataFrame, list[tuple[str, int]], dict[str, int]]:
    """One file -> (fields as text in dataset units, (file, line) per row, drop counts)."""
    f = _File(path, profile)
    n_rows = len(f.raw)
    keep = np.ones(n_rows, dtype=bool)
    counts = {"rows_read": n_rows, "rows_all_zero": 0, "rows_status": 0}
    vals = {k: f.numbers(s, k) for k, s in profile.columns.items()}
    ref = {k: f.numbers(s, f"reference {k}") for k, s in profile.reference.items()}
    if profile.drop_all_zero:
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
            raise DatasetError(f"{path}: line {r + f.first_line}: the reference body's quaternion is "
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
    origins = [(str(path), r + f.first_line) for r in range(n_rows)]
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
        report.append({"file": p.name, **counts, "sha256": _sha256(p)})
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
    log = _Log(Path(paths[0]), robot, cfg, raw=raw, origins=origins)
    ds = import_frame(log, robot, cfg, label)
    ds.meta["protocol_params"] = {"source": [r["file"] for r in report], "profile": profile.source}
    ds.meta["import"].update(profile=profile.to_dict(), files=report)
    ds.meta["cleaning"]["profile_drops"] = {
        "rows_all_zero": sum(int(str(r["rows_all_zero"])) for r in report),
        "rows_status": sum(int(str(r["rows_status"])) for r in report)}
    return ds
