"""`ctrkin reproduce`: the paper end to end on the virtual robot.

    ctrkin reproduce --scale quick --out out/reproduce      # minutes on two cores (README main job)
    ctrkin reproduce --scale full --out out/full            # the paper's data size and training
    RAY_ADDRESS=auto ctrkin reproduce --scale full --executor ray --out /shared/full   # on a cluster
    ctrkin reproduce --robot my_robot.toml --robot-seed 3 --set gear_backlash_deg=2 --out out/mine

Any robot: the protocols' translations are the paper robot's carried over to the robot's geometry
(docs/protocols.md: Other robots); --set KEY=VALUE sets the virtual robot's effects as in
`ctrkin collect` (docs/virtual_robot.md).

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
  ctrkin reproduce --scale quick --out out/reproduce
  ctrkin reproduce --scale tiny --set noise_mm=0.1 --out out/tiny-noisy""")
@config_options(ReproduceConfig)
@overwrite_option(help="Replace --out if it holds a reproduction of other settings (only a ctrkin "
                  "reproduction folder holding nothing else is ever replaced).")
def reproduce_cmd(overwrite: bool, **options: Any) -> None:
    """Collect data, train the models, run every experiment of the paper, write the report."""
    from ctrkin.evaluation.reproduce import reproduce
    from ctrkin.evaluation.scales import get_scale
    from ctrkin.robots import load_robot
    from ctrkin.training.device import resolve_device

    cfg = ReproduceConfig(**options)
    resolve_device(cfg.device)            # cuda without one: refused before the folder is touched
    output_folder(cfg.out, "reproduction", overwrite, inputs=[cfg.robot], reuse=True)
    results = reproduce(load_robot(cfg.robot), get_scale(cfg.scale), cfg.out, robot_seed=cfg.robot_seed,
                        workers=cfg.workers, log=say, executor=cfg.executor, overwrite=overwrite,
                        virtual=cfg.virtual, device=cfg.device)
    for line in headlines(results.fk, results.ik):
        say(line)


def headlines(fk: dict[str, Any], ik: dict[str, Any]) -> tuple[str, str]:
    """The two lines `reproduce` ends with: the recommended FK and IK models' held-out figures (the
    HEADLINE entries of results.json), each named by its family's label and registry name, beside the
    paper's LSTM-MLP; joint errors with their own units (β in mm, α in deg)."""
    from ctrkin.evaluation.table import HEADLINE, RECOMMENDED, ROWS, TCM_ROW

    def name(entry: dict[str, Any], task: str) -> str:
        model = entry.get("model", RECOMMENDED[task].name)
        label = next((r.label for r in ROWS if r.task == task and r.name == model), model)
        return f"{label} ({model})"

    f, i = fk[HEADLINE], ik[HEADLINE]
    return (f"FK, {name(f, 'fk')}: position {f['position_rmse_mm']:.3f} mm, orientation "
            f"{f['orientation_rmse_deg']:.3f} deg RMSE (the paper's LSTM-MLP: 0.69 mm, 0.16 deg); point-wise "
            f"TCM {fk[TCM_ROW.name]['position_rmse_mm']:.2f} mm",
            f"IK, {name(i, 'ik')}: tip reached {i['tip_error_mm']:.3f} mm; joint RMSE β "
            f"{i['joint_rmse_mm']:.3f} mm, α {i['joint_rmse_deg']:.1f} deg (the paper's LSTM-MLP: β 1.22 mm, "
            "α 2.46 deg; α differs where the IK reaches the tip with another of the robot's solutions)")
