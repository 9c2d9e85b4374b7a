"""`ctrkin reproduce`: the paper end to end on the virtual robot.

    ctrkin reproduce --scale quick --out out/reproduce      # minutes on two cores (README main job)
    ctrkin reproduce --scale full --out out/full            # the paper's data size and training
    RAY_ADDRESS=auto ctrkin reproduce --scale full --executor ray --out /shared/full   # on a cluster

Writes OUT/report.md (tables with the paper's numbers beside ours, figures), OUT/results.json, and
keeps the data (OUT/data) and models (OUT/models) so that a rerun reuses them.
"""

from __future__ import annotations

import click

from ctrkin.cli.common import output_folder, overwrite_option, robot_option, say
from ctrkin.evaluation.scales import SCALES, get_scale
from ctrkin.robots import load_robot


@click.command("reproduce", epilog="""\b
Examples:
  ctrkin reproduce --scale tiny --out out/tiny
  ctrkin reproduce --scale quick --out out/reproduce""")
@click.option(
    "--scale",
    type=click.Choice(sorted(SCALES)),
    default="quick",
    show_default=True,
    help="quick: ~12 min on 2 cores; full: the paper's protocol (~208k samples), batch 1024 with "
    "early stopping (the paper: batch 32, up to 500 epochs), ~30 min on 2 cores; tiny: a smoke test "
    "of every step.",
)
@robot_option
@click.option("--robot-seed", default=0, show_default=True, help="The virtual hardware draw.")
@click.option("--workers", default=2, show_default=True,
              help="Models trained in parallel (one thread each); with --executor ray and no RAY_ADDRESS, "
              "the CPUs of the local Ray instance.")
@click.option("--executor", type=click.Choice(["local", "ray"]), default="local", show_default=True,
              help="local: spawned processes; ray: one Ray task per training, on the cluster at "
              "RAY_ADDRESS or a local instance (pip install 'ctrkin[ray]').")
@click.option(
    "--out",
    "out_dir",
    default="out/reproduce",
    show_default=True,
    type=click.Path(),
    help="Output folder. A rerun with the same settings reuses its data and models; one with other "
    "settings is refused unless --overwrite.",
)
@overwrite_option(help="Replace --out if it holds a reproduction of other settings (only a ctrkin "
                  "reproduction folder holding nothing else is ever replaced).")
def reproduce_cmd(scale: str, robot_spec: str, robot_seed: int, workers: int, executor: str,
                  out_dir: str, overwrite: bool) -> None:
    """Collect data, train the models, run every experiment of the paper, write the report."""
    from ctrkin.evaluation.reproduce import reproduce

    output_folder(out_dir, "reproduction", overwrite, inputs=[robot_spec], reuse=True)
    results = reproduce(
        load_robot(robot_spec),
        get_scale(scale),
        out_dir,
        robot_seed=robot_seed,
        workers=workers,
        log=say,
        executor=executor,
        overwrite=overwrite,
    )
    fk, ik = results.fk, results.ik["lstm_mlp"]
    say(
        f"FK LSTM-MLP: {fk['lstm_mlp']['position_rmse_mm']:.3f} mm / "
        f"{fk['lstm_mlp']['orientation_rmse_deg']:.3f} deg (paper 0.69 mm / 0.16 deg); "
        f"TCM: {fk['tcm']['position_rmse_mm']:.2f} mm"
    )
    say(
        f"IK LSTM-MLP: {ik['joint_rmse_mm']:.3f} mm / {ik['joint_rmse_deg']:.3f} deg "
        f"(paper 1.22 mm / 2.46 deg); tip reached {ik['tip_error_mm']:.3f} mm"
    )
