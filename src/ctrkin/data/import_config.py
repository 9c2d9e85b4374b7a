"""How to read a user's robot log (ImportConfig) and the dataset fields its columns map onto
(ctrkin.data.importer reads the log with it)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from ctrkin.data import schema
from ctrkin.data.cleaning import CleaningConfig
from ctrkin.errors import DatasetError

AngleUnit = Literal["deg", "rad"]
LengthUnit = Literal["mm", "m"]
QuaternionOrder = Literal["wxyz", "xyzw"]
LENGTH_TO_MM = {"mm": 1.0, "m": 1000.0}
OPTIONAL_FIELDS = ("sequence_id", "time", "step", "snap")
ORIENTATION_FIELDS = ("q0", "qw", "qx", "qy", "qz", "tx", "ty", "tz")


def _help(text: str) -> dict[str, str]:
    """A field's metadata: its meaning, which is also its `ctrkin dataset import --help` text."""
    return {"help": text}


def fields(n_tubes: int) -> list[str]:
    """Every field a log column can be mapped to, for an N-tube robot."""
    return [*schema.joint_columns(n_tubes), *schema.POSITION_COLUMNS, *ORIENTATION_FIELDS, *OPTIONAL_FIELDS]


# characters that cannot separate fields: line ends and quotes (the CSV syntax itself) and those of
# numbers (a field separator inside "1.5e-3" would cut it)
NOT_DELIMITERS = "\n\r\"0123456789.+-eE\0"


def check_delimiter(delimiter: object, where: str) -> None:
    """A field separator: one character that is not a line end, a quote or part of a number."""
    if not isinstance(delimiter, str) or len(delimiter) != 1 or delimiter in NOT_DELIMITERS:
        raise DatasetError(f"{where} must be one character that is not a line end, a quote or part of "
                           f"a number (e.g. ',', ';', '\\t', ' '), got {delimiter!r}")


@dataclass(frozen=True)
class ImportConfig:
    """How to read a log. mapping: (log column, field) pairs (module docstring); units of the log's
    angles (alpha), joint lengths (beta) and positions; quaternion_columns: four log columns holding
    a full quaternion in `quaternion_order` (shorthand for mapping qw, qx, qy, qz); sequence_gap:
    None (never split), "auto" or a time gap in the log's time unit; drop_invalid_joints /
    drop_incomplete: drop rows with joints outside the robot's limits / with empty or NaN cells
    instead of failing; unwrap: unwrap the alpha columns (for logs that wrap angles to ±180°);
    position_only: the log has no tip orientation (or one that is not the tip tangent, such as a
    marker body's): the dataset keeps a placeholder orientation (base z) and meta["orientation"] =
    "absent", and orientation metrics are skipped."""

    mapping: tuple[tuple[str, str], ...] = field(default=(), metadata=_help(
        "(log column, field) pairs; `ctrkin dataset import --map LOG_COLUMN=FIELD`."))
    angle_unit: AngleUnit = field(default="deg", metadata=_help("Unit of the log's joint angles (alpha)."))
    beta_unit: LengthUnit = field(default="mm", metadata=_help("Unit of the log's joint lengths (beta)."))
    position_unit: LengthUnit = field(default="mm", metadata=_help("Unit of the log's tip positions."))
    quaternion_columns: tuple[str, ...] = field(default=(), metadata=_help(
        "Four log columns holding a full quaternion, in quaternion_order (`--quaternion C1,C2,C3,C4`)."))
    quaternion_order: QuaternionOrder = field(default="wxyz", metadata=_help(
        "Order of the quaternion columns."))
    sequence_gap: float | Literal["auto"] | None = field(default="auto", metadata=_help(
        "Without sequence_id: start a new sequence after a time gap larger than this (log time unit), "
        "'auto' (10x the median time step) or none."))
    drop_invalid_joints: bool = field(default=False, metadata=_help(
        "Drop rows whose joints are outside the robot's limits instead of failing."))
    drop_incomplete: bool = field(default=False, metadata=_help(
        "Drop rows with empty or NaN cells instead of failing."))
    unwrap: bool = field(default=False, metadata=_help("Unwrap alpha (for logs wrapping angles to ±180°)."))
    delimiter: str = field(default=",", metadata=_help("CSV field separator."))
    position_only: bool = field(default=False, metadata=_help(
        "The log has no tip orientation (or not the tip tangent's): orientation metrics are skipped."))
    cleaning: CleaningConfig = field(default_factory=CleaningConfig, metadata=_help(
        "The cleaning rules' settings (ctrkin.data.cleaning)."))

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
        check_delimiter(self.delimiter, "delimiter")
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
                "unwrap": self.unwrap, "delimiter": self.delimiter, "position_only": self.position_only,
                "cleaning": self.cleaning.to_dict()}
