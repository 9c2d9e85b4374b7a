"""Options and parsing shared by the sub-commands, and the one rule for existing output.

Output rule: a command never replaces an existing output file, or a folder that is not empty, unless
it is given `--overwrite` (`--force` is kept, hidden, as a deprecated alias where it existed).
`ctrkin train` and `ctrkin reproduce` resume their own run in --out instead (same settings); that is
not replacing.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

F = TypeVar("F", bound=Callable[..., Any])

QUIET = "ctrkin.quiet"   # ctx.meta key set by `ctrkin --quiet`
JSON_OUT = "ctrkin.json"  # ctx.meta key set by a command's --json: stdout holds only the JSON object


def _meta(key: str) -> bool:
    ctx = click.get_current_context(silent=True)
    return bool(ctx is not None and ctx.meta.get(key))


def quiet() -> bool:
    """Whether `ctrkin --quiet` was given (False outside a click command)."""
    return _meta(QUIET)


def say(message: str, err: bool = False) -> None:
    """A message about the work done (what was written, timings, summaries); silent with --quiet, on
    stderr with --json. Results that are only printed, warnings and errors use click.echo."""
    if not quiet():
        click.echo(message, err=err or _meta(JSON_OUT))


def _set_json(ctx: click.Context, _param: click.Parameter, value: bool) -> bool:
    if value:
        ctx.meta[JSON_OUT] = True
    return value


json_option = click.option(
    "--json", "as_json", is_flag=True, callback=_set_json,
    help="Print one JSON object with the summary figures and the paths written on stdout (nothing "
    "else goes there; messages and progress go to stderr).")


def jsonable(x: Any) -> Any:
    """x with numpy scalars and arrays as Python numbers and lists, paths as strings, and NaN and inf
    as null (they are not JSON)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if hasattr(x, "tolist"):                     # numpy scalars and arrays
        return jsonable(x.tolist())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, Path):
        return str(x)
    return x


def emit_json(obj: Any) -> None:
    """The result of a command given --json: one JSON object on stdout."""
    click.echo(json.dumps(jsonable(obj), indent=2))


def log_line(message: str) -> None:
    """A log line of a long run on stderr: with --quiet only its warnings."""
    if message.startswith("warning") or not quiet():
        click.echo(message, err=True)


robot_option = click.option(
    "--robot", "robot_spec", default="paper", show_default=True,
    help="Built-in robot name (paper, timclab) or path to a robot TOML file.")


class OutputExistsError(click.ClickException):
    """--out names something that exists and --overwrite was not given (exit status 1)."""

    exit_code = 1


def overwrite_option(force_alias: bool = False) -> Callable[[F], F]:
    """`--overwrite` (and, with force_alias, the hidden deprecated `--force`) as one `overwrite` flag."""
    flag = click.option("--overwrite", is_flag=True,
                        help="Replace the output if it exists (otherwise an existing output is refused).")
    if not force_alias:
        return flag

    def _force(ctx: click.Context, _param: click.Parameter, value: bool) -> bool:
        if value:
            click.echo("warning: --force is deprecated; use --overwrite", err=True)
        return value

    force = click.option("--force", "force", is_flag=True, hidden=True, expose_value=True, callback=_force,
                         help="Deprecated alias of --overwrite.")

    def decorate(f: F) -> F:
        return flag(force(f))

    return decorate


def output_options(f: F) -> F:
    """`--overwrite` and `--json`: the options of a command that writes an output and reports it."""
    return overwrite_option()(json_option(f))


def check_output(path: str | Path, overwrite: bool) -> Path:
    """The output rule: refuse (OutputExistsError) an existing file or non-empty folder `path` unless
    `overwrite`. Call it after the arguments are checked and before any work is done."""
    p = Path(path)
    if overwrite or not p.exists():
        return p
    if p.is_dir() and not any(p.iterdir()):
        return p
    raise OutputExistsError(f"{p} exists; pass --overwrite to replace it (or choose another --out)")


def parse_floats(text: str, what: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(" ", "").split(",") if v != ""]
    except ValueError:
        raise click.BadParameter(f"{what} must be comma-separated numbers, got {text!r}") from None
