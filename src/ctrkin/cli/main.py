"""`ctrkin`: command line entry point. Each sub-command lives in its own module.

    ctrkin solve --robot paper --q 0,0,-15,-5
    ctrkin sweep --robot paper --out out/sweep
    ctrkin --quiet reproduce --scale quick --out out/reproduce

Exit status: 0 done; 1 the input is wrong for the task (ctrkin.errors: invalid joints, a robot that
does not match, missing or bad data and model files, an output that exists without --overwrite or
that ctrkin may not replace; and the system's refusals: no permission, a full disk), with a one-line
message on stderr; 2 the command line is wrong in itself (click's usage errors: an unknown option, a
value that is not a number or outside its range, a missing or conflicting option).
"""

from __future__ import annotations

import contextlib
import errno
import importlib
import os
from collections.abc import Iterator
from typing import Any

import click

from ctrkin.cli.common import QUIET
from ctrkin.errors import CtrkinError
from ctrkin.version import __version__

# name: (module, attribute, the one-line help `ctrkin --help` lists). A sub-command's module (and
# numba, torch, pandas behind it) is imported only when that command runs or shows its own help;
# tests/cli/test_help_examples.py checks each line against the command's docstring.
COMMANDS: dict[str, tuple[str, str, str]] = {
    "calibrate": ("ctrkin.cli.calibrate", "calibrate_cmd",
                  "Fit registration and TCM parameters (precurvature, stiffness ratio, α/β offsets, "
                  "transmission length, marker offset, and μ between the tubes) by bounded least "
                  "squares; print them with standard errors."),
    "collect": ("ctrkin.cli.collect", "collect_cmd",
                "Record a protocol on the virtual robot or on a rig (or write square/triangle IK "
                "targets)."),
    "dataset": ("ctrkin.cli.dataset", "dataset_group",
                "Inspect datasets, import robot logs (CSV) and split datasets."),
    "evaluate": ("ctrkin.cli.evaluate", "evaluate_cmd",
                 "Compare predictors with the measured tips: position (and orientation, where measured) "
                 "errors per part (training, validation, held out, in-sample), per sequence and overall; "
                 "plots of predicted vs measured tips, of error against joints and of the error per "
                 "sequence."),
    "export": ("ctrkin.cli.export", "export_cmd",
               "Export MODEL_DIR (from `ctrkin train`) to an ONNX file (written atomically)."),
    "plan": ("ctrkin.cli.plan", "plan_cmd",
             "Plan a snap-safe joint trajectory through tip targets on the mechanics (and a learned snap "
             "model, --model): writes plan.csv (joints, predicted tip, margins per step, flags), plan.json "
             "(per target) and plan.png."),
    "predict": ("ctrkin.cli.predict", "predict_cmd",
                "Predict every sample of a dataset (--data), the tips of a file of joints (--joints, FK), "
                "or solve IK for a file of target poses (--poses), with MODEL_DIR."),
    "reproduce": ("ctrkin.cli.reproduce", "reproduce_cmd",
                  "Collect data, train the models, run every experiment of the paper, write the report."),
    "robot": ("ctrkin.cli.robot", "robot_group", "Robot description files: a documented template."),
    "show": ("ctrkin.cli.show", "show_cmd",
             "Draw the robot's 3-D shape (tubes with their diameters, the tip's path, snaps marked), or "
             "animate a sweep with its snap."),
    "solve": ("ctrkin.cli.mechanics", "solve_cmd",
              "Solve the TCM at one configuration (point-wise, no history)."),
    "sweep": ("ctrkin.cli.mechanics", "sweep_cmd",
              "Full inner-tube rotation forward and back at several relative translations (paper Fig. "
              "2b), solved by continuation: writes sweep.csv and a plot of T(L) against α0."),
    "train": ("ctrkin.cli.train", "train_cmd",
              "Train a history-aware kinematics model (the task's recommended model by default) and save it "
              "to --out."),
}


class DomainError(click.ClickException):
    """A ctrkin.errors exception on its way to the user: `Error: <message>` on stderr, exit status 1."""

    exit_code = 1


class CtrkinGroup(click.Group):
    """The `ctrkin` group: sub-commands loaded on first use (COMMANDS), and ctrkin.errors exceptions
    turned into one line on stderr and exit status 1 (no traceback), whether ctrkin runs from the
    console script or from click's CliRunner."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(COMMANDS) | set(self.commands))

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands and cmd_name in COMMANDS:
            module, attribute, _ = COMMANDS[cmd_name]
            self.add_command(getattr(importlib.import_module(module), attribute), cmd_name)
        return self.commands.get(cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command list from COMMANDS, without importing the commands."""
        limit = formatter.width - 6 - max(len(name) for name in COMMANDS)
        rows = [(name, click.Command(name, help=COMMANDS[name][2]).get_short_help_str(limit))
                for name in sorted(COMMANDS)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except CtrkinError as e:
            raise DomainError(" ".join(str(e).split())) from e
        except OSError as e:        # the system refused: permission, full disk, read-only, ...
            raise DomainError(_os_message(e)) from e


def _os_message(e: OSError) -> str:
    """One line for an error of the operating system: what, where, and what to do for the common ones."""
    where = " ".join(f"{p}" for p in (e.filename, e.filename2) if p is not None)
    what = e.strerror or type(e).__name__
    hint = {errno.ENOSPC: "; free some space (the previous output, if any, is intact)",
            errno.EFBIG: "; the file would exceed the size limit (the previous output, if any, is intact)",
            errno.EACCES: "; check the permissions", errno.EPERM: "; check the permissions",
            errno.EROFS: "; write somewhere else"}.get(e.errno or 0, "")
    return f"{what}{': ' + where if where else ''}{hint}"


@contextlib.contextmanager
def _environ(name: str, value: str) -> Iterator[None]:
    old = os.environ.get(name)
    os.environ[name] = value
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = old


@click.group(cls=CtrkinGroup, context_settings={"help_option_names": ["-h", "--help"]}, epilog="""\b
Progress is one updating line on a terminal; in a log or pipe, a line at 25/50/75/100 % and at
least one a minute while work goes on. CTRKIN_NO_PROGRESS=1 (or --quiet) turns it off.
Exit status: 0 done; 1 the input is wrong for the task (invalid joints, robot mismatch, missing or
bad data, an existing output without --overwrite or one ctrkin may not replace, no permission, a full
disk), one line on stderr; 2 a usage error (the command line itself: unknown option, a value that is
not a number or outside its range, a missing or conflicting option).

\b
Examples:
  ctrkin solve --q 0,0,-15,-5
  ctrkin --quiet collect --protocol sweeps --out data/sweeps
  CTRKIN_NO_PROGRESS=1 ctrkin reproduce --scale tiny --out out/tiny""")
@click.option("--quiet", "-q", is_flag=True,
              help="No progress and no messages about the work done; results that are only printed "
              "(solve, dataset info, predict to stdout, ...), warnings and errors still are.")
@click.version_option(__version__, prog_name="ctrkin")
@click.pass_context
def cli(ctx: click.Context, quiet: bool) -> None:
    """ctrkin: concentric tube robot kinematics with hysteresis and snapping."""
    if quiet:
        ctx.meta[QUIET] = True
        ctx.with_resource(_environ("CTRKIN_NO_PROGRESS", "1"))


def main() -> None:
    cli.main(prog_name="ctrkin")


if __name__ == "__main__":
    main()
