"""`ctrkin calibrate`: fit the tracker registration and the TCM parameters of your robot to a dataset.

    ctrkin dataset import logs/*.csv --profile examples/profiles/comet_optitrack.toml \\
        --robot examples/robots/comet_nylon_optitrack.toml --out data/optitrack
    ctrkin calibrate --data data/optitrack --robot examples/robots/comet_nylon_optitrack.toml \\
        --out robots/optitrack_cal.toml --loso
    ctrkin evaluate --data data/optitrack --predictor robots/optitrack_cal.toml --out out/eval_cal
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, cast

import click
import tomli_w

from ctrkin.calibration import calibrate, leave_one_sequence_out
from ctrkin.calibration.model import drop_none
from ctrkin.calibration.params import ALL_GROUPS, default_groups
from ctrkin.cli.common import emit_json, output_file, output_options, say
from ctrkin.cli.from_config import config_options, option_help
from ctrkin.data.dataset import Dataset
from ctrkin.robots import load_robot
from ctrkin.util.files import atomic_write_text


@dataclass(frozen=True, kw_only=True)
class CalibrateConfig:
    """What `ctrkin calibrate` fits (one option per field)."""

    data: str = field(metadata=option_help("Dataset folder (ctrkin dataset import).", path="folder"))
    robot: str | None = field(default=None, metadata=option_help(
        "Nominal robot (name or TOML file); default: the dataset's robot."))
    out: str = field(metadata=option_help(
        "Calibrated robot file to write (a normal robot file plus a [calibration] table).", path="out"))
    fit: str | None = field(default=None, metadata=option_help(
        f"Parameter groups to fit, comma-separated, from {','.join(ALL_GROUPS)}; default: all but "
        "bending_stiffness (per tube a scale of E, relative to the outermost tube: tubes whose E differs) "
        "and friction (μ between the tubes, fitted on the continued TCM), friction included when the robot "
        "file has friction > 0."))
    loso: bool = field(default=False, metadata=option_help(
        "Also report leave-one-sequence-out error (one refit per sequence).", flag=True))
    max_evaluations: int = field(default=60, metadata=option_help("Least-squares evaluations.",
                                                                  range=(1, 100_000)))
    no_prior: bool = field(default=False, metadata=option_help(
        "Fit without the prior about the nominal values (ctrkin.calibration.params.PRIOR_SIGMA).", flag=True))
    prior_scales: str = field(default="1", metadata=option_help(
        "With --loso: candidate multipliers of every prior σ, comma-separated (e.g. 0.5,1,2); with several, "
        "each fold picks one by a nested leave-one-sequence-out on its training sequences (needs >= 3 "
        "sequences)."))

    def scales(self) -> tuple[float, ...]:
        """--prior-scales as numbers (a usage error unless positive numbers separated by commas)."""
        try:
            scales = tuple(float(v) for v in self.prior_scales.split(",") if v.strip())
        except ValueError:
            raise click.BadParameter(f"numbers separated by commas, e.g. 0.5,1,2; got {self.prior_scales!r}",
                                     param_hint="--prior-scales") from None
        if not scales or not all(v > 0 for v in scales):
            raise click.BadParameter(f"positive numbers, e.g. 0.5,1,2; got {self.prior_scales!r}",
                                     param_hint="--prior-scales")
        return scales


@click.command("calibrate", epilog="""\b
Examples:
  ctrkin calibrate --data data/optitrack --robot examples/robots/comet_nylon_optitrack.toml \\
      --out robots/optitrack_cal.toml --loso --prior-scales 0.5,1,2
  ctrkin calibrate --data data/optitrack --out robots/optitrack_cal.toml --json > calibration.json""")
@config_options(CalibrateConfig)
@output_options
def calibrate_cmd(overwrite: bool, as_json: bool, **settings: Any) -> None:
    """Fit registration and TCM parameters (precurvature, stiffness ratio, α/β offsets, transmission
    length, marker offset, and μ between the tubes) by bounded least squares; print them with
    standard errors."""
    cfg = CalibrateConfig(**settings)
    scales = cfg.scales()
    data_dir, out_file, loso, prior = cfg.data, cfg.out, cfg.loso, not cfg.no_prior
    output_file(out_file, "robot description", overwrite, inputs=[data_dir, cfg.robot])
    ds = Dataset.load(data_dir)
    robot = load_robot(cfg.robot) if cfg.robot else ds.robot
    groups = (default_groups(robot) if cfg.fit is None
              else tuple(g.strip() for g in cfg.fit.split(",") if g.strip()))
    res = calibrate(ds, robot, groups, max_nfev=cfg.max_evaluations, prior=prior)
    if loso:
        res.loso = leave_one_sequence_out(ds, robot, groups, max_nfev=cfg.max_evaluations, prior=prior,
                                          prior_scales=scales)
    d = res.model.robot.to_dict()
    d["name"] = f"{robot.name}-calibrated"
    d["calibration"] = {**res.model.to_dict(), "dataset": str(data_dir),
                        "data_sha256": ds.meta.get("data_sha256"), "prior": prior,
                        "fit": json.loads(json.dumps(res.to_dict(), default=float, allow_nan=True)
                                          .replace("NaN", "null"))}
    atomic_write_text(out_file, tomli_w.dumps(cast(dict[str, Any], drop_none(d))))
    say(f"{'parameter':24s} {'unit':5s} {'nominal':>10s} {'fitted':>10s} {'± std':>9s}")
    for row in res.table():
        flag = "  (at bound)" if row["at_bound"] else ""
        say(f"{row['name']:24s} {row['unit']:5s} {row['nominal']:10.4g} {row['value']:10.4g} "
            f"{row['std']:9.2g}{flag}")
    say(f"samples {res.n_samples}: nominal TCM (fitted registration) {res.nominal_mean_mm:.3f} mm, "
        f"calibrated {res.mean_mm:.3f} mm mean tip distance (in-sample)")
    if res.friction:
        fr = res.friction
        say(f"friction μ = {fr['friction_mu']:.3f} ± {fr['std']:.2g} on the continued TCM "
            f"({fr['samples']} samples of whole sequences): RMS {fr['rms_mm']:.3f} mm, "
            f"{fr['rms_frictionless_mm']:.3f} mm with μ = 0")
    if loso:
        per = ", ".join(f"{k} {v:.3f}" for k, v in res.loso["per_sequence"].items())
        say(f"leave-one-sequence-out: {res.loso['mean_mm']:.3f} mm ({per})")
        if len(scales) > 1:
            chosen = ", ".join(f"{k} {v:g}" for k, v in res.loso["prior_scale"].items())
            say(f"prior scale chosen by nested leave-one-sequence-out: {chosen}")
    say(f"wrote {out_file}")
    if as_json:
        emit_json({"out": out_file, "robot": robot.name, "samples": res.n_samples,
                   "nominal_mean_mm": res.nominal_mean_mm, "calibrated_mean_mm": res.mean_mm,
                   "parameters": res.table(), "friction": res.friction,
                   **({"loso": res.loso} if loso else {})})

