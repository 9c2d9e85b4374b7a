"""`ctrkin`: command line entry point. Each sub-command lives in its own module.

    ctrkin solve --robot paper --q 0,0,-15,-5
    ctrkin sweep --robot paper --out out/sweep
    ctrkin --quiet reproduce --scale quick --out out/reproduce

Exit status: 0 done; 1 the input is wrong for the task (ctrkin.errors: invalid joints, a robot that
does not match, bad data or model files; an output that exists without --overwrite), with a one-line
message on stderr; 2 the command line is wrong (click's usage errors).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from typing import Any

import click

from ctrkin import __version__
from ctrkin.cli.calibrate import calibrate_cmd
from ctrkin.cli.collect import collect_cmd
from ctrkin.cli.common import QUIET
from ctrkin.cli.dataset import dataset_group
from ctrkin.cli.evaluate import evaluate_cmd
from ctrkin.cli.export import export_cmd
from ctrkin.cli.mechanics import solve_cmd, sweep_cmd
from ctrkin.cli.predict import predict_cmd
from ctrkin.cli.reproduce import reproduce_cmd
from ctrkin.cli.train import train_cmd
from ctrkin.errors import CtrkinError


class DomainError(click.ClickException):
    """A ctrkin.errors exception on its way to the user: `Error: <message>` on stderr, exit status 1."""

    exit_code = 1


class CtrkinGroup(click.Group):
    """A group that turns ctrkin.errors exceptions into one line on stderr and exit status 1 (no
    traceback), whether ctrkin runs from the console script or from click's CliRunner."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except CtrkinError as e:
            raise DomainError(" ".join(str(e).split())) from e


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
Progress is one updating line on a terminal and a few lines (25/50/75/100 %) in a log or pipe;
CTRKIN_NO_PROGRESS=1 (or --quiet) turns it off.
Exit status: 0 done; 1 the input is wrong for the task (invalid joints, robot mismatch, bad data,
an existing output without --overwrite), one line on stderr; 2 a usage error.

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


cli.add_command(solve_cmd)
cli.add_command(sweep_cmd)
cli.add_command(collect_cmd)
cli.add_command(train_cmd)
cli.add_command(export_cmd)
cli.add_command(predict_cmd)
cli.add_command(dataset_group)
cli.add_command(reproduce_cmd)
cli.add_command(calibrate_cmd)
cli.add_command(evaluate_cmd)


def main() -> None:
    cli.main(prog_name="ctrkin")


if __name__ == "__main__":
    main()
