"""Options and parsing shared by the sub-commands, and the one rule for existing output.

Output rule (one meaning of `--overwrite` for every command): a command never replaces an existing
output file, or a folder that is not empty, unless it is given `--overwrite`; and even then only a
ctrkin output of the same kind that holds nothing ctrkin did not write, never an input of the command,
`/`, a home folder, the working folder or a folder above it (ctrkin.util.ownership). A replaced folder
is replaced as a whole (built aside, swapped in). `--force` is kept, hidden, as a deprecated alias
where it existed. `ctrkin train` and `ctrkin reproduce` continue their own run in --out instead (same
settings); that is not replacing.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, TypeVar

import click

from ctrkin.errors import OutputError
from ctrkin.util.folders import folder_lock
from ctrkin.util.ownership import check_file_replaceable, check_not_input, check_replaceable, protected_reason

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


ROBOT_HELP = "Built-in robot name (paper, timclab) or path to a robot TOML file."


class OutputExistsError(click.ClickException):
    """--out names something that exists and --overwrite was not given (exit status 1)."""

    exit_code = 1


class InputError(click.ClickException):
    """A path argument that names nothing, or the wrong thing (exit status 1, like every input that is
    wrong for the task; 2 is kept for a command line that is wrong in itself)."""

    exit_code = 1


class InputPath(click.Path):
    """click.Path(exists=True) whose failures exit 1 (InputError) instead of click's 2."""

    def __init__(self, **kw: Any) -> None:
        super().__init__(exists=True, **kw)

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        try:
            return super().convert(value, param, ctx)
        except click.BadParameter as e:
            raise InputError(e.format_message()) from None


OVERWRITE_HELP = ("Replace the output if it is a ctrkin output of the same kind holding nothing else "
                  "(never an input, your files, a home folder or the working folder).")


def overwrite_option(force_alias: bool = False, help: str = OVERWRITE_HELP) -> Callable[[F], F]:
    """`--overwrite` (and, with force_alias, the hidden deprecated `--force`) as one `overwrite` flag."""
    flag = click.option("--overwrite", is_flag=True, help=help)
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


def _hold(cm: Any) -> None:
    """Keep context manager `cm` entered until the running command ends (outside a command: enter
    and leave it at once, for the checks it makes)."""
    ctx = click.get_current_context(silent=True)
    if ctx is not None:
        ctx.with_resource(cm)
    else:
        with cm:
            pass


def output_folder(path: str | Path, kind: str, overwrite: bool, inputs: Iterable[str | Path | None] = (),
                  reuse: bool = False) -> Path:
    """The output rule for a folder (ctrkin.util.ownership), checked before any work is done:

    never `/`, a home folder, the working folder or one above it, nor an input of the command (or a
    folder inside or around one); the folder's writer lock is taken and held until the command ends
    (a second writer is refused at once; leftovers of killed runs are cleaned). An existing folder
    that is not empty must be a ctrkin output of `kind` holding nothing else, and is replaced only
    with `overwrite` (OutputExistsError otherwise), or, with `reuse`, continued by the command (train
    resumes, reproduce reuses its stages)."""
    p = Path(path)
    reason = protected_reason(p)
    if reason is not None:
        raise OutputError(f"--out {p} is {reason}: ctrkin never writes an output there; name a new "
                          "sub-folder")
    check_not_input(p, inputs, OutputError)
    _hold(folder_lock(p, OutputError, "write"))
    if os.path.lexists(p) and not (p.is_dir() and not p.is_symlink() and not any(p.iterdir())):
        check_replaceable(p, kind, OutputError)
        if not (overwrite or reuse):
            raise OutputExistsError(f"{p} exists; pass --overwrite to replace it (or choose another --out)")
    return p


def output_file(path: str | Path, kind: str, overwrite: bool,
                inputs: Iterable[str | Path | None] = ()) -> Path:
    """The output rule for a file: a new file, or an existing ctrkin file of `kind` (ctrkin.util.
    ownership.FILE_KINDS) replaced with `overwrite`; never a folder, a link or an input."""
    p = Path(path)
    check_not_input(p, inputs, OutputError)
    if os.path.lexists(p):
        check_file_replaceable(p, kind, OutputError)
        if not overwrite:
            raise OutputExistsError(f"{p} exists; pass --overwrite to replace it (or choose another --out)")
    return p


def parse_floats(text: str, what: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(" ", "").split(",") if v != ""]
    except ValueError:
        raise click.BadParameter(f"{what} must be comma-separated numbers, got {text!r}") from None
