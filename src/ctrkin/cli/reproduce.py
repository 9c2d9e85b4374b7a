"""`ctrkin reproduce`: the paper end to end on the virtual robot.

    ctrkin reproduce --scale quick --out out/reproduce      # minutes on two cores (README main job)
    ctrkin reproduce --scale full --out out/full            # the paper's data size and training
    RAY_ADDRESS=auto ctrkin reproduce --scale full --executor ray --out /shared/full   # on a cluster

Writes OUT/report.md (tables with the paper's numbers beside ours, figures), OUT/results.json, and
keeps the data (OUT/data) and models (OUT/models) so that a rerun reuses them.
"""

from __future__ import annotations

from typing import Any

import click

from ctrkin.cli.common import output_folder, overwrite_option, say
from ctrkin.cli.from_config import config_options
from ctrkin.evaluation.scales import ReproduceConfig


@click.command("reproduce", epilog="""\b
Examples:
  ctrkin reproduce --scale tiny --out out/tiny
  ctrkin reproduce --scale quick --out out/reproduce""")
@config_options(ReproduceConfig, exclude=("out",))
@click.option("--out", "out", default="out/reproduce", show_default=True, type=click.Path(),
              help=ReproduceConfig.__dataclass_fields__["out"].metadata["help"])
@overwrite_option(help="Replace --out if it holds a reproduction of other settings (only a ctrkin "
                  "reproduction folder holding nothing else is ever replaced).")
def reproduce_cmd(overwrite: bool, **settings: Any) -> None:
    """Collect data, train the models, run every experiment of the paper, write the report."""
    from ctrkin.evaluation.reproduce import reproduce
    from ctrkin.evaluation.scales import get_scale
    from ctrkin.evaluation.table import HEADLINE, TCM_ROW
    from ctrkin.robots import load_robot
    from ctrkin.training.device import resolve_device

    cfg = ReproduceConfig(**settings)
    resolve_device(cfg.device)            # cuda without one: refused before the folder is touched
    output_folder(cfg.out, "reproduction", overwrite, inputs=[cfg.robot], reuse=True)
    results = reproduce(load_robot(cfg.robot), get_scale(cfg.scale), cfg.out, robot_seed=cfg.robot_seed,
                        workers=cfg.workers, log=say, executor=cfg.executor, overwrite=overwrite,
                        device=cfg.device)
    fk, ik = results.fk, results.ik[HEADLINE]
    say(
        f"FK LSTM-MLP: {fk[HEADLINE]['position_rmse_mm']:.3f} mm / "
        f"{fk[HEADLINE]['orientation_rmse_deg']:.3f} deg (paper 0.69 mm / 0.16 deg); "
        f"TCM: {fk[TCM_ROW.name]['position_rmse_mm']:.2f} mm"
    )
    say(
        f"IK LSTM-MLP: {ik['joint_rmse_mm']:.3f} mm / {ik['joint_rmse_deg']:.3f} deg "
        f"(paper 1.22 mm / 2.46 deg); tip reached {ik['tip_error_mm']:.3f} mm"
    )
