"""`ctrkin`: command line entry point. Each sub-command lives in its own module.

    ctrkin solve --robot paper --q 0,0,-15,-5
    ctrkin sweep --robot paper --out out/sweep
    ctrkin reproduce --scale quick --out out/reproduce
"""

from __future__ import annotations

import sys

import click

from ctrkin import __version__
from ctrkin.cli.calibrate import calibrate_cmd
from ctrkin.cli.collect import collect_cmd
from ctrkin.cli.dataset import dataset_group
from ctrkin.cli.evaluate import evaluate_cmd
from ctrkin.cli.export import export_cmd
from ctrkin.cli.mechanics import solve_cmd, sweep_cmd
from ctrkin.cli.predict import predict_cmd
from ctrkin.cli.reproduce import reproduce_cmd
from ctrkin.cli.train import train_cmd
from ctrkin.errors import CtrkinError


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="ctrkin")
def cli() -> None:
    """ctrkin: concentric tube robot kinematics with hysteresis and snapping."""


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
    try:
        cli(standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        sys.exit(1)
    except click.ClickException as e:
        e.show()
        sys.exit(e.exit_code)
    except CtrkinError as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(2)


if __name__ == "__main__":
    main()
