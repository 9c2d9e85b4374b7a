"""Import profiles: a small TOML file that says how to read one lab's log format.

A profile names the log's columns by position (1-based) or header name, with a scale and an offset per
column, and says how travel becomes β, which unit and quaternion order the tracker uses, which rows
are repeated readings of one configuration, which rows to drop, whether the tip is measured relative
to a reference body, and whether the orientation is the tip tangent. Example (docs/real_robot.md has
both comet-lab formats; examples/profiles/ has the files):

    [file]
    header = false                 # no header row: columns by position
    delimiter = ","

    [columns]                      # field = column, or field = { column, scale, offset, zero }
    alpha_1 = 12                   # inner rotation (deg)
    alpha_2 = 11
    beta_1 = { column = 9, zero = "straight_length" }   # travel (mm) -> β = travel − straight length
    beta_2 = { column = 8, zero = "straight_length" }
    x = 14
    y = 15
    z = 16

    [pose]
    unit = "m"                     # of x, y, z (and of the reference body): "mm" or "m"
    quaternion_order = "wxyz"      # of `quaternion = [c1, c2, c3, c4]` shorthands
    orientation = "absent"         # tangent | marker (a marker body's frame: ignored) | absent

    [groups]
    count = 10                     # or: joints_unchanged = true

    [drop]
    all_zero = true                # preallocated rows that are all zero

    [expect]                       # what this format must hold, or the log is not of this robot
    zero = [7]                     # columns that stay 0 (an unused rotation)
    equal = [[3, 4]]               # columns that hold the same value (a carriage moving with another)
    hint = "a three-tube log? use comet_ndi_3tube.toml"   # added to the message when they do not

Column value = scale · cell + offset. For β, `zero` is β at zero travel (mm, a number) or
"straight_length": β = travel − the tube's straight length (the curved part starts at the front plate
at zero travel). `[expect]` guards against a log of another robot read with this profile (a
three-tube log read as two tubes): a column that should stay zero or equal another but does not is
an error naming the line and the hint. Orientation "tangent" needs qw, qx, qy, qz columns whose
rotation turns z onto the tip tangent. A reference body (`[reference]` with x, y, z, qw, qx, qy,
qz columns) makes the tip pose relative to it: p = R_refᵀ (p_tip − p_ref). Errors name the
profile file, its line and the key.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from ctrkin.data.import_config import check_delimiter
from ctrkin.errors import DatasetError
from ctrkin.geometry import POSITION_COLUMNS
from ctrkin.robots.robot import joint_names

Orientation = Literal["tangent", "marker", "absent"]
ORIENTATIONS = ("tangent", "marker", "absent")
POSE_FIELDS = POSITION_COLUMNS
QUAT_FIELDS = ("qw", "qx", "qy", "qz")
REFERENCE_FIELDS = (*POSE_FIELDS, *QUAT_FIELDS)
SECTIONS = {"file", "columns", "pose", "reference", "groups", "drop", "expect"}
MAX_GROUP = 100_000     # readings per configuration ([groups] count): far beyond any tracker log
MAX_COLUMN = 100_000    # column positions


@dataclass(frozen=True)
class ColumnSpec:
    """One field's source: column (1-based position, int) or header name (str); value =
    scale · cell + offset; zero: for β only, β at zero travel (mm) or "straight_length"."""

    column: int | str
    scale: float = 1.0
    offset: float = 0.0
    zero: float | str | None = None

    def to_dict(self) -> dict[str, object]:
        d: dict[str, object] = {"column": self.column, "scale": self.scale, "offset": self.offset}
        if self.zero is not None:
            d["zero"] = self.zero
        return d


@dataclass(frozen=True)
class StatusRule:
    """Keep only rows whose `column` holds one of `keep` (e.g. NDI's "Enabled")."""

    column: int | str
    keep: tuple[str, ...]


@dataclass(frozen=True)
class Profile:
    """A parsed import profile (module docstring). columns: field -> ColumnSpec for alpha_i, beta_i,
    x, y, z and, with orientation "tangent", qw, qx, qy, qz; reference: the reference body's x, y, z,
    qw, qx, qy, qz columns (empty: none); group_count: readings per configuration (0: none);
    joints_unchanged: group consecutive readings with equal joints instead."""

    columns: dict[str, ColumnSpec]
    header: bool = True
    delimiter: str = ","
    position_unit: Literal["mm", "m"] = "mm"
    quaternion_order: Literal["wxyz", "xyzw"] = "wxyz"
    orientation: Orientation = "tangent"
    reference: dict[str, ColumnSpec] = field(default_factory=dict)
    group_count: int = 0
    joints_unchanged: bool = False
    drop_all_zero: bool = False
    status: tuple[StatusRule, ...] = ()
    expect_zero: tuple[int | str, ...] = ()
    expect_equal: tuple[tuple[int | str, int | str], ...] = ()
    expect_hint: str = ""
    source: str = "profile"

    def to_dict(self) -> dict[str, object]:
        return {"source": self.source, "header": self.header, "delimiter": self.delimiter,
                "columns": {k: v.to_dict() for k, v in self.columns.items()},
                "position_unit": self.position_unit, "quaternion_order": self.quaternion_order,
                "orientation": self.orientation,
                "reference": {k: v.to_dict() for k, v in self.reference.items()},
                "group_count": self.group_count, "joints_unchanged": self.joints_unchanged,
                "drop_all_zero": self.drop_all_zero,
                "status": [{"column": s.column, "keep": list(s.keep)} for s in self.status],
                "expect": {"zero": list(self.expect_zero), "equal": [list(e) for e in self.expect_equal],
                           "hint": self.expect_hint}}


class _Where:
    """Locates a key in the profile text, for messages: 'P.toml: line 7, [columns] beta_1'."""

    def __init__(self, path: str, text: str) -> None:
        self.path, self.lines = path, text.splitlines()

    def __call__(self, section: str, key: str | None = None) -> str:
        in_section = False
        for k, raw in enumerate(self.lines, start=1):
            line = raw.strip()
            m = re.match(r"^\[\s*([A-Za-z0-9_.]+)\s*\]", line)
            if m:
                in_section = m.group(1) == section
                if in_section and key is None:
                    return f"{self.path}: line {k}, [{section}]"
                continue
            if in_section and key is not None and re.match(rf"^{re.escape(key)}\s*=", line):
                return f"{self.path}: line {k}, [{section}] {key}"
        return f"{self.path}: [{section}]" + (f" {key}" if key else "")


def _number(value: object, where: str, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise DatasetError(f"{where}: {what} must be a number, got {value!r}")
    try:
        out = float(value)
    except OverflowError:
        out = math.inf
    if not math.isfinite(out):
        raise DatasetError(f"{where}: {what} must be a finite number, got {value!r}")
    return out


def _column_ref(value: object, where: str) -> int | str:
    if isinstance(value, bool):
        raise DatasetError(f"{where}: a column is a position (1, 2, ...) or a header name, got {value!r}")
    if isinstance(value, int):
        if not 1 <= value <= MAX_COLUMN:
            raise DatasetError(f"{where}: column positions count from 1 (at most {MAX_COLUMN}), got {value}")
        return value
    if isinstance(value, str) and value.strip():
        return value.strip()
    raise DatasetError(f"{where}: a column is a position (1, 2, ...) or a header name, got {value!r}")


def _spec(value: object, where: str, beta: bool) -> ColumnSpec:
    if not isinstance(value, Mapping):
        return ColumnSpec(_column_ref(value, where))
    allowed = {"column", "scale", "offset"} | ({"zero"} if beta else set())
    unknown = set(value) - allowed
    if unknown:
        raise DatasetError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(allowed)}")
    if "column" not in value:
        raise DatasetError(f"{where}: needs column = POSITION or column = \"header name\"")
    zero = value.get("zero")
    if zero is not None and zero != "straight_length":
        zero = _number(zero, where, "zero (β at zero travel, mm, or \"straight_length\")")
    scale = _number(value.get("scale", 1.0), where, "scale")
    if scale == 0:
        raise DatasetError(f"{where}: scale must not be 0")
    return ColumnSpec(_column_ref(value["column"], where), scale,
                      _number(value.get("offset", 0.0), where, "offset"), zero)


def _choice(value: object, options: tuple[str, ...], where: str) -> Any:
    if value not in options:
        raise DatasetError(f"{where}: must be one of {list(options)}, got {value!r}")
    return value


def _expand_quaternion(table: dict[str, Any], order: str, where: str) -> dict[str, Any]:
    """quaternion = [c1, c2, c3, c4] (in [pose] quaternion_order) -> qw, qx, qy, qz entries."""
    if "quaternion" not in table:
        return table
    cols = table.pop("quaternion")
    if not isinstance(cols, list) or len(cols) != 4:
        raise DatasetError(f"{where}: needs four columns [c1, c2, c3, c4] in {order} order, got {cols!r}")
    names = ("qw", "qx", "qy", "qz") if order == "wxyz" else ("qx", "qy", "qz", "qw")
    dup = [k for k in names if k in table]
    if dup:
        raise DatasetError(f"{where}: {dup} given both here and on their own; give them once")
    table.update(zip(names, cols, strict=True))
    return table


def parse_profile(text: str, n_tubes: int, source: str = "profile") -> Profile:
    """Profile from TOML text for an N-tube robot; errors name `source`, the line and the key."""
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise DatasetError(f"{source}: not valid TOML: {e}") from None
    where = _Where(source, text)
    unknown = set(d) - SECTIONS
    if unknown:
        raise DatasetError(f"{source}: unknown section(s) {sorted(unknown)}; allowed: {sorted(SECTIONS)}")
    for sec in SECTIONS & set(d):
        if not isinstance(d[sec], Mapping):
            raise DatasetError(f"{where(sec)}: must be a table ([{sec}])")
    file_ = d.get("file", {})
    header = file_.get("header", True)
    if not isinstance(header, bool):
        raise DatasetError(f"{where('file', 'header')}: must be true or false")
    delimiter = file_.get("delimiter", ",")
    check_delimiter(delimiter, where("file", "delimiter"))
    pose = d.get("pose", {})
    unit = _choice(pose.get("unit", "mm"), ("mm", "m"), where("pose", "unit"))
    order = _choice(pose.get("quaternion_order", "wxyz"), ("wxyz", "xyzw"), where("pose", "quaternion_order"))
    orientation = _choice(pose.get("orientation", "tangent"), ORIENTATIONS, where("pose", "orientation"))

    joints = joint_names(n_tubes)
    allowed = [*joints, *POSE_FIELDS, *QUAT_FIELDS]
    cols_raw = d.get("columns")
    if not cols_raw:
        raise DatasetError(f"{source}: needs a [columns] table mapping fields {allowed} to columns")
    columns: dict[str, ColumnSpec] = {}
    cols_raw = _expand_quaternion(dict(cols_raw), order, where("columns", "quaternion"))
    profile_tubes = max((int(k.split("_")[1]) for k in cols_raw if re.fullmatch(r"(alpha|beta)_\d+", str(k))),
                        default=0)
    complete = all(f in cols_raw for f in joint_names(profile_tubes)) if profile_tubes else False
    if complete and profile_tubes != n_tubes:       # a whole K-tube profile with an N-tube robot
        raise DatasetError(f"{where('columns')}: this profile maps the joints of a {profile_tubes}-tube "
                           f"robot (alpha_1..{profile_tubes}, beta_1..{profile_tubes}) but the robot has "
                           f"{n_tubes} tubes; use a {n_tubes}-tube profile with this robot, or the "
                           f"{profile_tubes}-tube robot with this profile")
    for key, value in cols_raw.items():
        w = where("columns", key)
        if key not in allowed:
            raise DatasetError(f"{w}: unknown field {key!r}; fields for a {n_tubes}-tube robot: {allowed}")
        columns[key] = _spec(value, w, beta=key.startswith("beta_"))
        if columns[key].zero is not None and not key.startswith("beta_"):
            raise DatasetError(f"{w}: zero applies to beta columns only")
    needed = [*joints, *POSE_FIELDS] + (list(QUAT_FIELDS) if orientation == "tangent" else [])
    missing = [f for f in needed if f not in columns]
    if missing:
        hint = (" (orientation = \"tangent\" needs qw, qx, qy, qz; use \"marker\" or \"absent\" for "
                "position-only data)" if any(f in QUAT_FIELDS for f in missing) else "")
        raise DatasetError(f"{where('columns')}: missing field(s) {missing}{hint}")
    if orientation != "tangent":
        columns = {k: v for k, v in columns.items() if k not in QUAT_FIELDS}

    reference: dict[str, ColumnSpec] = {}
    if "reference" in d:
        ref_raw = _expand_quaternion(dict(d["reference"]), order, where("reference", "quaternion"))
        for key, value in ref_raw.items():
            w = where("reference", key)
            if key not in REFERENCE_FIELDS:
                raise DatasetError(f"{w}: unknown field {key!r}; a reference body has "
                                   f"{list(REFERENCE_FIELDS)}")
            reference[key] = _spec(value, w, beta=False)
        missing = [f for f in REFERENCE_FIELDS if f not in reference]
        if missing:
            raise DatasetError(f"{where('reference')}: missing field(s) {missing}")

    groups = d.get("groups", {})
    count = groups.get("count", 0)
    if isinstance(count, bool) or not isinstance(count, int) or not 0 <= count <= MAX_GROUP:
        raise DatasetError(f"{where('groups', 'count')}: must be a whole number in 0..{MAX_GROUP} "
                           f"(readings per configuration), got {count!r}")
    unchanged = groups.get("joints_unchanged", False)
    if not isinstance(unchanged, bool):
        raise DatasetError(f"{where('groups', 'joints_unchanged')}: must be true or false")
    if count and unchanged:
        raise DatasetError(f"{where('groups')}: give count or joints_unchanged, not both")

    drop = d.get("drop", {})
    all_zero = drop.get("all_zero", False)
    if not isinstance(all_zero, bool):
        raise DatasetError(f"{where('drop', 'all_zero')}: must be true or false")
    status_raw = drop.get("status", [])
    if isinstance(status_raw, Mapping):
        status_raw = [status_raw]
    status = []
    for rule in status_raw:
        w = where("drop", "status")
        if not isinstance(rule, Mapping) or "column" not in rule or "keep" not in rule:
            raise DatasetError(f"{w}: each rule is {{ column = POSITION|\"name\", keep = [\"value\", ...] }}")
        keep = rule["keep"]
        if isinstance(keep, str):
            keep = [keep]
        if not isinstance(keep, list) or not all(isinstance(k, str) for k in keep):
            raise DatasetError(f"{w}: keep must be a list of strings, got {keep!r}")
        status.append(StatusRule(_column_ref(rule["column"], w), tuple(keep)))
    expect = d.get("expect", {})
    unknown = set(expect) - {"zero", "equal", "hint"}
    if unknown:
        raise DatasetError(f"{where('expect')}: unknown key(s) {sorted(unknown)}; allowed: zero, equal, hint")
    zero_cols = expect.get("zero", [])
    if not isinstance(zero_cols, list):
        raise DatasetError(f"{where('expect', 'zero')}: a list of columns, got {zero_cols!r}")
    equal_raw = expect.get("equal", [])
    if not isinstance(equal_raw, list) or not all(isinstance(e, list) and len(e) == 2 for e in equal_raw):
        raise DatasetError(f"{where('expect', 'equal')}: a list of column pairs [[a, b], ...], got "
                           f"{equal_raw!r}")
    hint = expect.get("hint", "")
    if not isinstance(hint, str):
        raise DatasetError(f"{where('expect', 'hint')}: text, got {hint!r}")
    return Profile(columns=columns, header=header, delimiter=delimiter, position_unit=unit,
                   quaternion_order=order, orientation=orientation, reference=reference,
                   group_count=count, joints_unchanged=unchanged, drop_all_zero=all_zero,
                   status=tuple(status),
                   expect_zero=tuple(_column_ref(c, where("expect", "zero")) for c in zero_cols),
                   expect_equal=tuple((_column_ref(a, where("expect", "equal")),
                                       _column_ref(b, where("expect", "equal"))) for a, b in equal_raw),
                   expect_hint=hint, source=source)


def load_profile(path: str | Path, n_tubes: int) -> Profile:
    """Profile from a TOML file (parse_profile)."""
    p = Path(path)
    if not p.is_file():
        raise DatasetError(f"profile file {p} does not exist")
    try:
        text = p.read_text()
    except UnicodeDecodeError as e:
        raise DatasetError(f"profile file {p} is not text: {e}") from None
    return parse_profile(text, n_tubes, source=str(p))
