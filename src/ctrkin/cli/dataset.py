"""`ctrkin dataset`: inspect datasets, import your own robot logs, make splits.

    ctrkin dataset info data/sweeps
    ctrkin dataset info data/sweeps --json

    # a log in radians and metres, a full quaternion in x, y, z, w order, five readings per sample
    ctrkin dataset import robot_log.csv --robot paper --out data/mylog \\
        --map enc_rot_inner=alpha_1 --map enc_rot_outer=alpha_2 \\
        --map enc_lin_inner=beta_1 --map enc_lin_outer=beta_2 \\
        --map px=x --map py=y --map pz=z --map stamp=time --map run=sequence_id \\
        --quaternion ox,oy,oz,ow --quat-order xyzw --units rad,m

    # logs in a lab's own format, described once by an import profile (docs/real_robot.md)
    ctrkin dataset import logs/*.csv --profile examples/profiles/comet_optitrack.toml \
        --robot examples/robots/comet_nylon_optitrack.toml --out data/optitrack

    ctrkin dataset split data/mylog --kind random --seed 0 --fractions 0.7,0.15,0.15
    ctrkin dataset split data/optitrack --test 19_05_23-13_08_2-tubes_rotate   # test sequence by name
    ctrkin dataset split data/optitrack --test 19_05_23-13_08_2-tubes_rotate --val-rows 0.15 --overwrite
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Literal, cast

import click
from rich.console import Console
from rich.table import Table

from ctrkin.cli.common import ROBOT_HELP, output_folder, overwrite_option, quiet, say
from ctrkin.cli.from_config import config_options, option, option_help
from ctrkin.data.cleaning import CleaningConfig
from ctrkin.data.dataset import Dataset
from ctrkin.data.importer import ImportConfig, import_csv
from ctrkin.data.splits import (
    Split,
    random_split,
    split_by_sequence,
    split_warnings,
    split_with_test,
    split_with_test_val_rows,
)
from ctrkin.data.summary import summarize
from ctrkin.robots import load_robot


@click.group("dataset", epilog="""\b
Examples:
  ctrkin dataset info data/paper
  ctrkin dataset split data/paper --kind random --seed 0""")
def dataset_group() -> None:
    """Inspect datasets, import robot logs (CSV) and split datasets."""


# --- info ------------------------------------------------------------------------------------------
def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, dict):
        return ", ".join(f"{k}={_fmt(x)}" for k, x in v.items())
    if isinstance(v, list):
        if len(v) > 8:
            return f"[{len(v)} values]"
        return "; ".join(_fmt(x) for x in v) if v else "-"
    return "-" if v is None else str(v)


def print_summary(s: dict[str, Any], title: str) -> None:
    console = Console(width=110)
    head = Table(title=title, show_header=False, title_justify="left")
    head.add_column("key", style="bold")
    head.add_column("value")
    r = s["robot"]
    head.add_row("robot", f"{r['name']} ({r['n_tubes']} tubes, {r['transmission']}, {r['fingerprint']})")
    head.add_row("protocol", _fmt(s["protocol"]))
    if s.get("protocol_params"):
        head.add_row("parameters", _fmt(s["protocol_params"]))
    head.add_row("seed", _fmt(s["seed"]))
    head.add_row("samples", str(s["samples"]))
    head.add_row("sequences", f"{s['sequences']} (length {_fmt(s['sequence_length'])})")
    head.add_row("snaps", str(s["snaps"]))
    head.add_row("outliers flagged", str(s["outliers_flagged"]))
    head.add_row("true poses", "yes" if s["has_truth"] else "no")
    for key in ("noise", "cleaning"):
        entry = s.get(key)
        if isinstance(entry, dict):
            for k, v in entry.items():
                head.add_row(f"{key}: {k}", _fmt(v))
        elif entry is not None:
            head.add_row(key, _fmt(entry))
    split = s["split"]
    head.add_row("split", "none saved (by sequence 70:15:15 on first use)" if split is None else _fmt(split))
    head.add_row("format", f"version {s['format_version']} (ctrkin {_fmt(s['ctrkin_version'])})")
    console.print(head)
    ranges = Table(title="columns", title_justify="left")
    for name in ("column", "unit", "min", "max", "mean"):
        ranges.add_column(name, justify="left" if name in ("column", "unit") else "right")
    for c, v in s["ranges"].items():
        ranges.add_row(c, v["unit"], f"{v['min']:.4g}", f"{v['max']:.4g}", f"{v['mean']:.4g}")
    console.print(ranges)


@dataclass(frozen=True, kw_only=True)
class InfoConfig:
    """What `ctrkin dataset info` summarises, and how (the argument and one option per field)."""

    folder: str = field(metadata=option_help("A dataset folder.", path="folder", argument=True))
    json: bool = field(default=False, metadata=option_help("Print the summary as JSON.", flag=True))


@dataset_group.command("info", epilog="""\b
Examples:
  ctrkin dataset info data/paper --json""")
@config_options(InfoConfig)
def info_cmd(**settings: Any) -> None:
    """Summary of the dataset in FOLDER: samples, sequences, ranges, snaps, cleaning, noise, split."""
    cfg = InfoConfig(**settings)
    s = summarize(Dataset.load(cfg.folder))
    if cfg.json:
        click.echo(json.dumps(s, indent=2))
    else:
        print_summary(s, title=str(cfg.folder))


# --- import ----------------------------------------------------------------------------------------
def parse_map(items: tuple[str, ...]) -> tuple[tuple[str, str], ...]:
    """("a=alpha_1", "b=beta_1,c=x") -> (("a", "alpha_1"), ("b", "beta_1"), ("c", "x"))."""
    pairs = []
    for item in items:
        for part in item.split(","):
            if not part.strip():
                continue
            col, sep, fld = part.partition("=")
            if not sep or not col.strip() or not fld.strip():
                raise click.BadParameter(f"expected LOG_COLUMN=FIELD, got {part!r}", param_hint="--map")
            pairs.append((col.strip(), fld.strip()))
    return tuple(pairs)


def parse_units(items: tuple[str, ...]) -> dict[str, str]:
    """Units of the log: tokens deg|rad (angles), mm|m (all lengths), or angles=, beta=, position=."""
    out: dict[str, str] = {}
    for item in items:
        for tok in (t.strip() for t in item.split(",")):
            key, sep, val = tok.partition("=")
            if not tok:
                continue
            if not sep:
                key, val = ("angles", tok) if tok in ("deg", "rad") else ("lengths", tok)
            if key in ("angles", "alpha") and val in ("deg", "rad"):
                out["angle_unit"] = val
            elif key == "lengths" and val in ("mm", "m"):
                out["beta_unit"] = out["position_unit"] = val
            elif key == "beta" and val in ("mm", "m"):
                out["beta_unit"] = val
            elif key == "position" and val in ("mm", "m"):
                out["position_unit"] = val
            else:
                raise click.BadParameter(
                    f"{tok!r}: use deg|rad, mm|m, or angles=deg|rad, beta=mm|m, position=mm|m",
                    param_hint="--units")
    return out


def parse_gap(text: str) -> float | str | None:
    if text in ("auto", "none"):
        return None if text == "none" else "auto"
    try:
        return float(text)
    except ValueError:
        raise click.BadParameter(f"auto, none or a time gap in the log's unit, got {text!r}",
                                 param_hint="--sequence-gap") from None


def parse_columns(text: str) -> tuple[str, ...]:
    """"ox, oy,oz,ow" -> ("ox", "oy", "oz", "ow")."""
    return tuple(c.strip() for c in text.split(",")) if text else ()


@dataclass(frozen=True, kw_only=True)
class ImportCommand:
    """What `ctrkin dataset import` reads and writes, and the options it reads into ImportConfig in a
    form of its own (the argument and one option per field, around ImportConfig's)."""

    log_files: tuple[str, ...] = option("Robot logs (CSV).", argument=True, repeat=True, path="file")
    robot: str = option(ROBOT_HELP, "paper")
    profile: str | None = option(
        "Import profile (TOML: columns by position or name, scales, travel zero, groups, drops, reference "
        "body, orientation). With a profile, several files make one dataset, one sequence per file, and "
        "--map/--units/--quaternion are not used.", None, path="file")
    out: str = option("Dataset folder to write.", path="out")
    mapping: tuple[tuple[str, str], ...] = option(
        "Map a log column to a field (alpha_1.., beta_1.., x, y, z, q0, qw, qx, qy, qz, tx, ty, tz, "
        "sequence_id, time, step, snap). Repeatable or comma-separated. Columns already named like a "
        "field need no mapping.", (), parse=parse_map, repeat=True, name="--map",
        metavar="LOG_COLUMN=FIELD")
    units: dict[str, str] | None = field(default=None, metadata=option_help(
        "Units of the log in one option, e.g. 'rad,m' or 'angles=rad,beta=mm,position=m' (over "
        "--angle-unit, --beta-unit, --position-unit).", parse=parse_units, repeat=True, metavar="UNITS"))
    quaternion_columns: tuple[str, ...] = option(
        "Four log columns holding a full quaternion, in --quat-order.", (), parse=parse_columns,
        name="--quaternion", metavar="C1,C2,C3,C4")
    sequence_gap: float | str | None = option(
        "Without sequence_id: start a new sequence after a time gap larger than this (log time unit), "
        "'auto' (10x the median time step) or 'none'.", "auto", parse=parse_gap)
    keep_outliers: bool = option("Keep outliers, flagged outlier = True, instead of dropping them (the "
                                 "paper dropped them).", False, flag=True)
    no_average: bool = option("Do not average repeated readings of one sample.", False, flag=True)

    def config(self, settings: dict[str, Any]) -> ImportConfig:
        """The ImportConfig of these options and ImportConfig's own (`settings`)."""
        return ImportConfig(
            mapping=self.mapping, quaternion_columns=self.quaternion_columns,
            sequence_gap=cast(Any, self.sequence_gap),
            cleaning=CleaningConfig(average_repeats=not self.no_average,
                                    outliers="flag" if self.keep_outliers else "drop"),
            **{**settings, **(self.units or {})})


# The command line differs from ImportConfig only here: older option names; mapping,
# quaternion_columns, sequence_gap, the units and cleaning are ImportCommand's options.
IMPORT_ALIASES = {"quaternion_order": ("--quat-order",), "drop_invalid_joints": ("--drop-invalid",)}
IMPORT_OWN = ("mapping", "quaternion_columns", "sequence_gap", "cleaning")
IMPORT_COMMAND = tuple(f.name for f in fields(ImportCommand))


@dataset_group.command("import", epilog="""\b
Examples:
  ctrkin dataset import robot_log.csv --robot paper --units rad,m --out data/mylog
  ctrkin dataset import logs/*.csv --profile examples/profiles/comet_optitrack.toml \\
      --robot examples/robots/comet_nylon_optitrack.toml --out data/optitrack""")
@config_options(ImportCommand, exclude=("keep_outliers", "no_average"))
@config_options(ImportConfig, aliases=IMPORT_ALIASES, exclude=IMPORT_OWN)
@config_options(ImportCommand, only=("keep_outliers", "no_average"))
@overwrite_option(force_alias=True)
def import_cmd(overwrite: bool, force: bool, **settings: Any) -> None:
    """Import robot logs LOG_FILES (CSV, one row a tracker reading) into one cleaned dataset: repeated
    readings averaged, encoder glitches and pose outliers removed, snaps detected (see docs/data.md,
    and docs/real_robot.md for import profiles). Without --profile, one file."""
    command = ImportCommand(**{name: settings.pop(name) for name in IMPORT_COMMAND})
    log_files, profile_file = command.log_files, command.profile
    if profile_file is None and len(log_files) != 1:
        raise click.UsageError("several log files need --profile (one sequence per file); without a "
                               "profile import one file")
    out = output_folder(command.out, "dataset", overwrite or force,
                        inputs=[*log_files, profile_file, command.robot])
    robot = load_robot(command.robot)
    cfg = command.config(settings)
    if profile_file is not None:
        from ctrkin.data.profile import load_profile
        from ctrkin.data.profile_import import import_with_profile

        ds = import_with_profile(list(log_files), load_profile(profile_file, robot.n_tubes), robot, cfg)
    else:
        ds = import_csv(log_files[0], robot, cfg)
    ds.save(out)
    names = ", ".join(Path(f).name for f in log_files)
    if not quiet():
        print_summary(summarize(ds), title=f"imported {names} -> {out}")
    for w in ds.meta["cleaning"]["warnings"]:
        click.echo(f"warning: {w}", err=True)


# --- split -----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SplitConfig:
    """How `ctrkin dataset split` splits a dataset (the argument and one option per field)."""

    folder: str = field(metadata=option_help("A dataset folder.", path="folder", argument=True))
    kind: Literal["sequence", "random"] = field(default="sequence", metadata=option_help(
        "sequence: whole sequences per part (no leakage through the input buffer); random: the paper's "
        "per-sample shuffle."))
    seed: int = field(default=0, metadata=option_help("Seed of the shuffle."))
    fractions: tuple[float, ...] = field(default=(0.7, 0.15, 0.15), metadata=option_help(
        "Train, validation, test fractions."))
    test: tuple[str, ...] | None = field(default=None, metadata=option_help(
        "Sequences for the test part, by name (file stem for imported logs) or index, comma-separated; "
        "the rest is split into train and validation by --fractions."))
    val_rows: float | None = field(default=None, metadata=option_help(
        "With --test: validation is this fraction of the other sequences' rows, drawn at random, instead "
        "of whole sequences (with few sequences a whole one is spent on validation); the split of "
        "benchmarks/bench_realdata.py is --val-rows 0.15."))

    def __post_init__(self) -> None:
        if len(self.fractions) != 3:
            raise click.BadParameter(f"three fractions needed, got {list(self.fractions)}",
                                     param_hint="--fractions")
        if self.val_rows is not None and self.test is None:
            raise click.BadParameter("--val-rows needs --test (the held-out sequences)",
                                     param_hint="--val-rows")

    def describe(self) -> str:
        """The kind of split, as `ctrkin dataset split` reports it."""
        if self.test is not None and self.val_rows is not None:
            return f"test {','.join(self.test)}, validation {self.val_rows:.0%} of the other rows"
        return self.kind

    def make(self, ds: Dataset) -> Split:
        """The split of `ds` (DatasetError: fractions that do not sum to 1, unknown test sequences)."""
        frac = (self.fractions[0], self.fractions[1], self.fractions[2])
        sid = ds.frame["sequence_id"].to_numpy()
        if self.test is not None:
            labels = [str(v) for v in ds.meta.get("sequence_labels") or []]
            if self.val_rows is not None:
                return split_with_test_val_rows(sid, labels, list(self.test), self.val_rows, seed=self.seed)
            return split_with_test(sid, labels, list(self.test), frac, seed=self.seed)
        if self.kind == "sequence":
            return split_by_sequence(sid, frac, seed=self.seed)
        return random_split(len(ds.frame), frac, seed=self.seed)


@dataset_group.command("split", epilog="""\b
Examples:
  ctrkin dataset split data/paper --fractions 0.8,0.1,0.1 --seed 2
  ctrkin dataset split data/optitrack --test 19_05_23-13_08_2-tubes_rotate
  ctrkin dataset split data/optitrack --test 19_05_23-13_08_2-tubes_rotate --val-rows 0.15 --overwrite""")
@config_options(SplitConfig)
@overwrite_option(help="Replace a split.json that FOLDER already has (otherwise a different saved split "
                  "is refused: models trained on it would no longer match).")
def split_cmd(overwrite: bool, **settings: Any) -> None:
    """Make a train/validation/test split of the dataset in FOLDER and save it as split.json. Warns
    when the parts are far from the requested fractions (few, unequal sequences)."""
    cfg = SplitConfig(**settings)
    folder = cfg.folder
    ds = Dataset.load(folder)
    split = cfg.make(ds)
    ds.save_split(folder, split, overwrite=overwrite)
    sizes = split.sizes()
    say(f"{folder}: {cfg.describe()} split, seed {cfg.seed}: train {sizes['train']}, val {sizes['val']}, "
        f"test {sizes['test']} samples -> {Path(folder) / 'split.json'}")
    f = cfg.fractions
    frac = split.fractions if cfg.val_rows is not None else (f[0], f[1], f[2])
    for w in split_warnings(split, frac):
        click.echo(f"warning: {w}", err=True)
