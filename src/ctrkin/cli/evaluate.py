"""`ctrkin evaluate`: how good is a predictor on an imported dataset?

    ctrkin evaluate --data data/optitrack --predictor tcm --out out/eval_tcm
    ctrkin evaluate --data data/optitrack --predictor robots/optitrack_cal.toml --out out/eval_cal
    ctrkin evaluate --data data/optitrack --predictor out/fk_model --out out/eval_fk
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Any

import click

from ctrkin.cli.common import InputPath, emit_json, output_folder, output_options, say
from ctrkin.data.dataset import Dataset
from ctrkin.errors import CtrkinError
from ctrkin.evaluation.real import evaluate
from ctrkin.util.folders import build_folder


@click.command("evaluate", epilog="""\b
Examples:
  ctrkin evaluate --data data/optitrack --predictor tcm --out out/eval_tcm
  ctrkin evaluate --data data/optitrack --predictor robots/optitrack_cal.toml --out out/eval_cal
  ctrkin evaluate --data data/optitrack --predictor models/fk_optitrack --out out/eval_fk
  ctrkin evaluate --data data/optitrack --predictor tcm --json > eval_tcm.json""")
@click.option("--data", "data_dir", required=True, type=InputPath(file_okay=False),
              help="Dataset folder.")
@click.option("--predictor", "predictors", required=True, multiple=True,
              help="tcm (nominal robot of the dataset, registration fitted here), a robot file "
                   "(.toml, calibrated or not) or a trained FK model folder. Repeatable.")
@click.option("--out", "out_dir", default=None, type=click.Path(),
              help="Folder for results.json and plots (one sub-folder per predictor when several); "
              "written as a whole (with --overwrite it replaces an earlier evaluation folder).")
@output_options
def evaluate_cmd(data_dir: str, predictors: tuple[str, ...], out_dir: str | None, overwrite: bool,
                 as_json: bool) -> None:
    """Compare predictors with the measured tips: position (and orientation, where measured) errors
    overall and per sequence; plots of predicted vs measured tips and of error against joints."""
    if out_dir is not None:
        output_folder(out_dir, "evaluation", overwrite, inputs=[data_dir, *predictors])
    ds = Dataset.load(data_dir)
    # without --out (and without --json) the printed table is the result
    show = click.echo if out_dir is None and not as_json else say
    results = []
    # written beside --out, swapped in when every predictor is done
    with (contextlib.nullcontext(None) if out_dir is None
          else build_folder(out_dir, "evaluation", CtrkinError, "evaluate")) as build:
        for k, spec in enumerate(predictors):
            out = None if build is None else (build if len(predictors) == 1 else build / str(k))
            res = evaluate(ds, spec, out)
            results.append({"predictor": spec, **res,
                            "out": None if out_dir is None else
                            (out_dir if len(predictors) == 1 else f"{out_dir}/{k}")})
            _print(spec, res, show)
    if out_dir is not None:
        for r in results:
            say(f"wrote {r['out']}/results.json, tips.png, error_vs_joints.png")
    if as_json:
        emit_json({"data": data_dir, "predictors": results})


def _print(spec: str, res: dict[str, Any], show: Callable[[str], None]) -> None:
    """One predictor's figures, and a warning (stderr) for joints outside a model's training range."""
    o = res["overall"]
    show(f"{spec}: {o['samples']} samples, position mean {o['position_mean_mm']:.3f} mm, "
         f"RMSE {o['position_rmse_mm']:.3f} mm, max {o['position_max_mm']:.3f} mm"
         + (f", orientation mean {o['orientation_mean_deg']:.2f} deg"
            if "orientation_mean_deg" in o else ", orientation: not measured"))
    if "registration" in res:
        show(f"  registration: {res['registration']}")
    show(f"  {'sequence':32s} {'samples':>7s} {'mean mm':>8s} {'rmse mm':>8s}")
    for name, s in res["per_sequence"].items():
        show(f"  {name:32s} {s['samples']:7d} {s['position_mean_mm']:8.3f} "
             f"{s['position_rmse_mm']:8.3f}")
    if res.get("out_of_range_samples"):
        click.echo(f"  WARNING: {res['out_of_range_samples']} samples have joints outside the model's "
                   "training range (beyond the margin); their predictions are extrapolations:", err=True)
        for name, j in res["out_of_range"].items():
            if j["count"]:
                click.echo(f"    {name}: {j['count']} samples outside [{j['lo']:.4g}, {j['hi']:.4g}] "
                           f"± {j['margin']:.3g}", err=True)
