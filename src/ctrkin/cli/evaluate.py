"""`ctrkin evaluate`: how good is a predictor on an imported dataset?

    ctrkin evaluate --data data/optitrack --predictor tcm --out out/eval_tcm
    ctrkin evaluate --data data/optitrack --predictor robots/optitrack_cal.toml --out out/eval_cal
    ctrkin evaluate --data data/optitrack --predictor out/fk_model --out out/eval_fk
    ctrkin evaluate --data data/optitrack --predictor robots/optitrack_cal.toml --loso

Figures are given per part, each labelled with what the predictor knew of its rows: a learned
model's training, validation and held-out (test) rows (its own split), a calibration's in-sample
rows; --loso adds leave-one-sequence-out figures (each sequence predicted by a refit on the others).
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import click

from ctrkin.cli.common import emit_json, output_folder, output_options, say
from ctrkin.cli.from_config import config_options, option_help
from ctrkin.data.dataset import Dataset
from ctrkin.errors import CtrkinError
from ctrkin.evaluation.real import evaluate, loso, predictor_name
from ctrkin.util.folders import build_folder


def folder_names(predictors: tuple[str, ...]) -> list[str]:
    """One sub-folder name per predictor: its own name, numbered only where two share one."""
    names = [predictor_name(p) for p in predictors]
    return [n if names.count(n) == 1 else f"{n}-{k + 1}" for k, n in enumerate(names)]


@dataclass(frozen=True, kw_only=True)
class EvaluateConfig:
    """What `ctrkin evaluate` compares (one option per field)."""

    data: str = field(metadata=option_help("Dataset folder.", path="folder"))
    predictor: tuple[str, ...] = field(metadata=option_help(
        "tcm (nominal robot of the dataset, registration fitted here), a robot file (.toml, calibrated or "
        "not) or a trained FK model folder. Repeatable.", repeat=True))
    out: str | None = field(default=None, metadata=option_help(
        "Folder for results.json and plots (one sub-folder per predictor, named after it, when several); "
        "written as a whole (with --overwrite it replaces an earlier evaluation folder).", path="out"))
    loso: bool = field(default=False, metadata=option_help(
        "Also leave-one-sequence-out: each sequence predicted by the predictor refitted to the other "
        "sequences (a calibration's groups, or a model retrained with its own settings).", flag=True))
    loso_epochs: int | None = field(default=None, metadata=option_help(
        "With --loso and a learned model: cap its epochs per fold (default: its own)."))


@click.command("evaluate", epilog="""\b
Examples:
  ctrkin evaluate --data data/optitrack --predictor tcm --out out/eval_tcm
  ctrkin evaluate --data data/optitrack --predictor robots/optitrack_cal.toml --out out/eval_cal
  ctrkin evaluate --data data/optitrack --predictor models/fk_optitrack --out out/eval_fk
  ctrkin evaluate --data data/optitrack --predictor robots/optitrack_cal.toml --loso
  ctrkin evaluate --data data/optitrack --predictor tcm --json > eval_tcm.json""")
@config_options(EvaluateConfig)
@output_options
def evaluate_cmd(overwrite: bool, as_json: bool, **settings: Any) -> None:
    """Compare predictors with the measured tips: position (and orientation, where measured) errors
    per part (training, validation, held out, in-sample), per sequence and overall; plots of predicted
    vs measured tips, of error against joints and of the error per sequence."""
    cfg = EvaluateConfig(**settings)
    data_dir, predictors, out_dir = cfg.data, cfg.predictor, cfg.out
    if out_dir is not None:
        output_folder(out_dir, "evaluation", overwrite, inputs=[data_dir, *predictors])
    ds = Dataset.load(data_dir)
    ds.meta.setdefault("path", data_dir)
    # without --out (and without --json) the printed table is the result
    show = click.echo if out_dir is None and not as_json else say
    results = []
    subs = folder_names(predictors)
    # written beside --out, swapped in when every predictor is done
    with (contextlib.nullcontext(None) if out_dir is None
          else build_folder(out_dir, "evaluation", CtrkinError, "evaluate")) as build:
        for spec, sub in zip(predictors, subs, strict=True):
            out = None if build is None else (build if len(predictors) == 1 else build / sub)
            res = evaluate(ds, spec, out)
            if cfg.loso:
                with tempfile.TemporaryDirectory() as work:
                    res["loso"] = loso(ds, spec, Path(work), cfg.loso_epochs)
            results.append({"predictor": spec, **res,
                            "out": None if out_dir is None else
                            (out_dir if len(predictors) == 1 else f"{out_dir}/{sub}")})
            _print(spec, res, show)
    if out_dir is not None:
        for r in results:
            say(f"wrote {r['out']}/results.json, {', '.join(r['figures'])}")
    if as_json:
        emit_json({"data": data_dir, "predictors": results})


def _row(label: str, s: dict[str, Any]) -> str:
    return (f"  {label:36s} {s['samples']:7d} {s['position_mean_mm']:8.3f} {s['position_rmse_mm']:8.3f} "
            f"{s['position_max_mm']:8.3f}")


def _print(spec: str, res: dict[str, Any], show: Callable[[str], None]) -> None:
    """One predictor's figures by part and by sequence; warnings (stderr) for joints outside a
    model's training range and for joints the held-out rows move that training never moved."""
    o = res["overall"]
    show(f"{spec}: {o['samples']} samples; parts: {res['parts_source']}"
         + ("" if "orientation_mean_deg" in o else "; orientation: not measured"))
    if "registration" in res:
        show(f"  registration: {res['registration']}")
    head = f"  {'':36s} {'samples':>7s} {'mean mm':>8s} {'rmse mm':>8s} {'max mm':>8s}"
    show(head.replace("  " + " " * 36, f"  {'part':36s}", 1))
    for part, s in res["per_part"].items():
        show(_row(part, s))
    show(_row("all rows (mixes the parts above)" if len(res["per_part"]) > 1 else "all rows", o))
    show(head.replace("  " + " " * 36, f"  {'sequence':36s}", 1))
    for name, s in res["per_sequence"].items():
        show(_row(name, s) + f"  {'+'.join(s['parts'])}")
    if "loso" in res:
        lo = res["loso"]
        show(f"  leave-one-sequence-out (held out): {lo['mean_mm']:.3f} mm mean over {lo['samples']} "
             f"samples; {lo['how']}")
        for name, e in lo["per_sequence"].items():
            show(f"    {name:34s} {e:8.3f} mm")
        for w in lo.get("warnings", []):
            click.echo(f"  warning: {w}", err=True)
    for w in res.get("warnings", []):
        click.echo(f"  warning: {w}", err=True)
    if res.get("out_of_range_samples"):
        click.echo(f"  WARNING: {res['out_of_range_samples']} samples have joints outside the model's "
                   "training range (beyond the margin); their predictions are extrapolations:", err=True)
        for name, j in res["out_of_range"].items():
            if j["count"]:
                unit = "deg" if name.startswith("alpha") else "mm"
                pad = f" ± {j['margin']:.3g}" if j["margin"] else ""   # a sin/cos arc holds its margin
                click.echo(f"    {name}: {j['count']} samples outside [{j['lo']:.4g}, {j['hi']:.4g}]{pad} "
                           f"{unit} (trained range)", err=True)
