"""A user's robot log as read: its cells as text, each dataset field resolved to a column (by --map,
the quaternion shorthand, or a column named like the field), and the file and line of every row, so
that every error of the import names where it is (ctrkin.data.importer cleans what this reads; an
import profile, ctrkin.data.profile_import, reads the cells itself and hands them over)."""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from ctrkin.data import schema
from ctrkin.data.import_config import ImportConfig, fields
from ctrkin.errors import DatasetError
from ctrkin.robots.robot import Robot


def _line(row: int) -> int:
    """File line of data row `row` (0-based), the header being line 1."""
    return row + 2


class LogTable:
    """The raw CSV with its field -> column resolution; errors name the file, line and column."""

    def __init__(self, path: Path, robot: Robot, cfg: ImportConfig, raw: pd.DataFrame | None = None,
                 origins: list[tuple[str, int]] | None = None, profile: str | None = None) -> None:
        """raw: the log's cells as text, already read (an import profile reads them); origins: the
        (file, line) of each of its rows, for messages; profile: the import profile that read them
        (messages then point at its keys, not at --map and --units, which a profile ignores)."""
        self.path, self.robot, self.cfg = path, robot, cfg
        self.origins = origins
        self.units_hint = ("check --units and --map" if profile is None else
                           f"check {profile}: its [columns] (positions, scale, offset, zero) and "
                           "[pose] unit")
        self.metres_hint = "--units position=m" if profile is None else f'{profile}: [pose] unit = "m"'
        self.quaternion_hint = ("check --map, --quaternion and --quat-order" if profile is None else
                                f"check {profile}: the quaternion columns and [pose] quaternion_order")
        if raw is not None:
            self.raw = raw.reset_index(drop=True)
            self.field_names: dict[str, str] = {}
            if len(self.raw) == 0:
                raise DatasetError(f"{path}: no data rows")
            self.columns = self._resolve()
            return
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
        self.field_names = {}
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
        required = [*schema.joint_columns(n), *schema.POSITION_COLUMNS]
        missing = [f for f in required if f not in columns]
        if self.orientation_mode(columns) is None and not self.cfg.position_only:
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
            what = ("a complex number; this field must be real" if _looks_complex(text.iloc[r])
                    else "not a number")
            raise DatasetError(f"{self.where(r)}, {self.line_col(fld)}: {text.iloc[r]!r} is {what}")
        return vals

    def where(self, row: int) -> str:
        """'file: line N' of data row `row` (0-based, before any drop)."""
        if self.origins is not None:
            name, line = self.origins[row]
            return f"{name}: line {line}"
        return f"{self.path}: line {_line(row)}"

    def file_line(self, row: int) -> int:
        return self.origins[row][1] if self.origins is not None else _line(row)

    def line_col(self, fld: str) -> str:
        return f"column {self.columns[fld]!r} ({self.field_names.get(fld, fld)})"


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file (hex), read in 1 MiB chunks: a dataset records the logs it came from."""
    h = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _looks_complex(text: str) -> bool:
    try:
        complex(text.strip().replace(" ", ""))
    except ValueError:
        return False
    return True
