"""`ctrkin plan`: a snap-safe joint trajectory through tip targets, on the mechanics, and with
`--model` also on a learned snap model (a snap-aware FK, lstm_mlp_branch).

    ctrkin plan --targets targets.csv --start-joints 0,0,-20,0 --out out/plan
    ctrkin plan --robot calibrated.toml --targets targets.csv --start-joints 0,0,-20,0 \
        --min-margin 0.3 --out out/plan
    ctrkin plan --model models/fk_branch --targets targets.csv --start-joints 150,0,-20,0 --out out/plan
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any

import click
import numpy as np

from ctrkin.cli.common import emit_json, jsonable, output_folder, output_options, say
from ctrkin.cli.from_config import RANGE, config_options, option_help
from ctrkin.errors import CtrkinError
from ctrkin.util.folders import build_folder

ROBOT_HELP = "Built-in robot name (paper, timclab) or path to a robot TOML file (nominal or calibrated)."


@dataclass(frozen=True)
class PlanCommandConfig:
    """A plan through a file of tip targets (`ctrkin plan`, one option per field)."""

    robot: str = field(default="paper", metadata=option_help(ROBOT_HELP))
    targets: str = field(default="", metadata=option_help(
        "CSV of tip targets: columns x, y, z (mm, robot base frame) and optionally q0, qx, qy (the tip "
        "orientation, 5-DOF quaternion), one row per target, in order."))
    start_joints: tuple[float, ...] = field(default=(), metadata=option_help(
        "The robot's current joints α1..αN (deg), β1..βN (mm), comma-separated; its branch is the "
        "point-wise (least-energy) equilibrium there."))
    tol_mm: float = field(default=1.0, metadata={RANGE: (1e-6, None), **option_help(
        "A target counts as reached within this tip distance (mm).")})
    min_margin: float = field(default=0.25, metadata={RANGE: (0.0, 0.99), **option_help(
        "Least stability margin allowed at any step (1: tubes aligned, 0: a fold, where the robot snaps).")})
    alpha_limits: tuple[float, ...] = field(default=(-720.0, 720.0), metadata=option_help(
        "lo,hi of every α (deg)."))
    beta_limits: tuple[float, ...] = field(default=(-math.inf, 0.0), metadata=option_help(
        "lo,hi of every β (mm), within the robot's own valid translations."))
    allow_snaps: bool = field(default=False, metadata=option_help(
        "Take the offered deliberate snap where a target is not reachable on the current branch."))
    model: str | None = field(default=None, metadata=option_help(
        "A learned FK folder with a branch state (the snap-aware lstm_mlp_branch): streamed along every "
        "route from the start joints, a route on which it predicts a snap is rejected (unless "
        "--allow-snaps) and its margin (inner rotation left before its predicted snap, deg) is reported "
        "per step.", path="folder"))
    learned_min_deg: float = field(default=5.0, metadata={RANGE: (0.0, 179.0), **option_help(
        "With --model: the least inner rotation (deg) left before the model's predicted snap at any step.")})
    learned_jump_mm: float = field(default=2.0, metadata={RANGE: (1e-6, None), **option_help(
        "With --model: a flip of the model's branch state counts as a snap where its predicted tip jumps "
        "by more than this (mm); a flip without a jump is a relabel.")})
    naive: bool = field(default=True, metadata=option_help(
        "Also execute the naive plan (point-wise IK, straight joint lines) and mark its snaps in the "
        "figure."))
    out: str = field(default="out/plan", metadata=option_help(
        "Output folder for plan.csv, plan.json and plan.png.", path="out"))

    def __post_init__(self) -> None:
        if not self.targets:
            raise click.BadParameter("give a CSV of targets", param_hint="--targets")
        for name in ("alpha_limits", "beta_limits"):
            if len(getattr(self, name)) != 2:
                raise click.BadParameter("give two values lo,hi", param_hint="--" + name.replace("_", "-"))


@click.command("plan", epilog="""\b
Examples:
  ctrkin plan --targets targets.csv --start-joints 0,0,-20,0 --out out/plan
  ctrkin plan --targets targets.csv --start-joints 150,0,-20,0 --min-margin 0.3 --out out/plan --json
  ctrkin plan --model models/fk_branch --targets targets.csv --start-joints 150,0,-20,0 --out out/plan""")
@config_options(PlanCommandConfig, required=("targets", "start_joints"))
@output_options
def plan_cmd(overwrite: bool, as_json: bool, **settings: Any) -> None:
    """Plan a snap-safe joint trajectory through tip targets on the mechanics (and a learned snap model,
    --model): writes plan.csv (joints, predicted tip, margins per step, flags), plan.json (per target)
    and plan.png."""
    cfg = PlanCommandConfig(**settings)
    from ctrkin.planning.naive import naive_path
    from ctrkin.planning.planner import PlanConfig, plan_path
    from ctrkin.planning.table import plan_table, read_targets
    from ctrkin.robots import load_robot
    from ctrkin.viz.plan import plot_plan

    out = output_folder(cfg.out, "plan", overwrite,
                        inputs=[cfg.robot, cfg.targets] + ([cfg.model] if cfg.model else []))
    robot = load_robot(cfg.robot)
    learned = None
    if cfg.model is not None:
        from ctrkin.inference import Kinematics
        from ctrkin.planning.learned import LearnedSnapModel

        kin = Kinematics.load(cfg.model)
        kin.check_robot(robot)
        learned = LearnedSnapModel(kin, jump_mm=cfg.learned_jump_mm)
    targets, tangents = read_targets(cfg.targets)
    pcfg = PlanConfig(tol_mm=cfg.tol_mm, min_margin=cfg.min_margin,
                      alpha_limits_deg=(cfg.alpha_limits[0], cfg.alpha_limits[1]),
                      beta_limits_mm=(cfg.beta_limits[0], cfg.beta_limits[1]),
                      allow_snaps=cfg.allow_snaps, learned_min_deg=cfg.learned_min_deg)
    start = np.array(cfg.start_joints, dtype=float)
    plan = plan_path(robot, start, targets, tangents, pcfg, learned)
    naive_tips = naive_snaps = None
    if cfg.naive:
        legs = naive_path(robot, start, targets, tangents, pcfg)
        naive_tips = np.concatenate([leg.tips for leg in legs])
        naive_snaps = np.concatenate([leg.snaps for leg in legs])
    reports = [{**{k: v for k, v in asdict(t).items() if k != "offer"},
                "offer": None if t.offer is None else t.offer.describe()} for t in plan.targets]
    summary = {"robot": robot.name, "targets": len(targets), "reached": plan.n_reached,
               "steps": len(plan.q), "planned_snaps": int(plan.snap.sum()),
               "min_margin": float(plan.margin.min()),
               "naive_snaps": None if naive_snaps is None else int(naive_snaps.sum()),
               "model": cfg.model,
               "learned_snaps": None if plan.learned is None else int(plan.learned.snap.sum()),
               "learned_min_margin_deg": (None if plan.learned is None
                                          else float(plan.learned.margin_deg.min())),
               "config": asdict(pcfg), "per_target": reports}
    with build_folder(out, "plan", CtrkinError, "plan") as build:      # written as one unit
        plan_table(plan, robot.n_tubes).to_csv(build / "plan.csv", index=False)
        (build / "plan.json").write_text(json.dumps(jsonable(summary), indent=2), encoding="utf-8")
        plot_plan(plan.tips, plan.margin, targets, np.array([t.reached for t in plan.targets]),
                  build / "plan.png", naive_tips, naive_snaps, title=f"{robot.name}: snap-safe plan",
                  learned_margin=None if plan.learned is None else plan.learned.margin_deg)
    for t in plan.targets:
        line = (f"target {t.index}: reached ({t.error_mm:.3f} mm, {t.route}, margin ≥ {t.min_margin:.2f})"
                if t.reached else f"target {t.index}: not reachable on the current branch "
                f"(closest {t.error_mm:.2f} mm)")
        say(line + (f"; offer: {t.offer.describe()}" if t.offer is not None and not t.reached else ""))
    if plan.learned is not None:
        say(f"learned snap model ({cfg.model}): {int(plan.learned.snap.sum())} predicted snaps on the plan, "
            f"least margin {plan.learned.margin_deg.min():.1f} deg of inner rotation")
    say(f"{plan.n_reached} of {len(targets)} targets reached, {int(plan.snap.sum())} planned snaps"
        + ("" if naive_snaps is None else f" (the naive plan snaps {int(naive_snaps.sum())} times)"))
    say(f"wrote {out / 'plan.csv'}, {out / 'plan.json'} and {out / 'plan.png'}")
    if as_json:
        emit_json({**summary, "files": {"table": out / "plan.csv", "summary": out / "plan.json",
                                        "figure": out / "plan.png"}})
