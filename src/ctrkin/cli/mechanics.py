"""`ctrkin solve` and `ctrkin sweep`: the TCM from the command line.

    ctrkin solve --robot paper --q 0,0,-15,-5 --json
    ctrkin sweep --robot paper --translations 4,8,12,16,20 --out out/sweep
    ctrkin sweep --robot paper --friction 0.2 --clearance 1 --out out/sweep-friction
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from typing import Any

import click
import numpy as np
import pandas as pd

from ctrkin.acquisition.trajectories import PAPER_LEVELS_MM, rotation_sweep
from ctrkin.cli.common import ROBOT_HELP, emit_json, output_folder, output_options, say
from ctrkin.cli.from_config import RANGE, config_options, option_help
from ctrkin.errors import CtrkinError
from ctrkin.geometry import POSE_COLUMNS, tip_azimuth
from ctrkin.mechanics import Equilibrium, follow, solve
from ctrkin.robots import load_robot
from ctrkin.util.folders import build_folder
from ctrkin.util.progress import progress_bar

MIN_STEP_DEG = 1e-3      # a sweep of 720 / step steps per level: at most 720,000


@dataclass(frozen=True)
class SolveConfig:
    """One point-wise TCM solve (`ctrkin solve`, one option per field)."""

    robot: str = field(default="paper", metadata=option_help(ROBOT_HELP))
    q: tuple[float, ...] = field(default=(), metadata=option_help(
        "Joints α1..αN (deg), β1..βN (mm), comma-separated, e.g. 0,0,-15,-5."))
    backbone: bool = field(default=False, metadata=option_help(
        "Also give the backbone: s (mm), points (mm) and each tube's twist ψ (deg) along it (in the JSON "
        "with --json, else as a table)."))


@dataclass(frozen=True)
class SweepConfig:
    """Full inner-tube rotations followed by continuation (`ctrkin sweep`, one option per field)."""

    robot: str = field(default="paper", metadata=option_help(ROBOT_HELP))
    translations: tuple[float, ...] = field(default=tuple(float(v) for v in PAPER_LEVELS_MM),
                                            metadata=option_help("Relative translations d = β_N − β_1 (mm)."))
    outer_beta: float = field(default=0.0, metadata=option_help("β of the other tubes (mm)."))
    outer_alpha: float = field(default=0.0, metadata=option_help("α of the other tubes (deg)."))
    step_deg: float = field(default=1.0, metadata={RANGE: (MIN_STEP_DEG, 360.0),
                                                   **option_help("Rotation step (deg).")})
    friction: float | None = field(default=None, metadata={RANGE: (0.0, 2.0), **option_help(
        "Coulomb coefficient μ between the tubes (docs/mechanics.md: Friction and clearance); default: "
        "the robot file's (0 for the built-in robots). With μ > 0 the plot also marks the frictionless "
        "folds (circles).")})
    clearance: float | None = field(default=None, metadata={RANGE: (0.0, 10.0), **option_help(
        "Share of the tubes' radial gap the inner tube may tilt in at an outer tube's tip (1: all of "
        "it); default: the robot file's (0).")})
    out: str = field(default="out/sweep", metadata=option_help(
        "Output folder for sweep.csv and sweep.png.", path="out"))

    def __post_init__(self) -> None:
        if not self.translations:
            raise click.BadParameter("give at least one relative translation (mm)",
                                     param_hint="--translations")
        if not MIN_STEP_DEG <= self.step_deg <= 360.0:
            raise click.BadParameter(f"{self.step_deg} is not in the range {MIN_STEP_DEG}<=x<=360.0",
                                     param_hint="--step")


@click.command("solve", epilog="""\b
Examples:
  ctrkin solve --q 0,0,-15,-5
  ctrkin solve --robot paper --q 90,0,-20,0 --json
  ctrkin solve --q 180,0,-20,0 --json --backbone > eq.json""")
@config_options(SolveConfig, required=("q",))
@click.option("--json", "as_json", is_flag=True, help="Print the result as one JSON object.")
def solve_cmd(as_json: bool, **settings: Any) -> None:
    """Solve the TCM at one configuration (point-wise, no history)."""
    cfg = SolveConfig(**settings)
    backbone = cfg.backbone
    robot = load_robot(cfg.robot)
    q = list(cfg.q)
    eq = solve(robot, np.array(q))
    azimuth = azimuth_deg(eq.tip_position, q[robot.n_tubes - 1])
    if as_json:
        d = {**eq.to_dict(), "T_L_deg": azimuth}
        if backbone:
            d["backbone"] = backbone_dict(eq)
        click.echo(json.dumps(d, indent=2))
        return
    pose = eq.tip_pose
    click.echo(f"robot {robot.name}: q = {q}")
    click.echo(f"tip position (mm): {pose[0]:.4f} {pose[1]:.4f} {pose[2]:.4f}")
    click.echo(f"tip quaternion (q0, qx, qy): {pose[3]:.6f} {pose[4]:.6f} {pose[5]:.6f}")
    click.echo(f"T(L), tip azimuth from the outer tube's base rotation (deg): {azimuth:.3f}")
    click.echo(f"converged: {eq.converged}  stable: {eq.stable}  stability det J: "
               f"{eq.stability:.4f}  energy: {eq.energy:.4g} N·mm")
    if backbone:
        cols = ["s_mm", "x_mm", "y_mm", "z_mm"] + [f"psi_{i + 1}_deg" for i in range(robot.n_tubes)]
        rows = np.column_stack([eq.s, eq.backbone, eq.twist])
        click.echo(pd.DataFrame(rows, columns=cols).to_csv(index=False, float_format="%.6g"), nl=False)


def azimuth_deg(tip_position: np.ndarray, outer_alpha_deg: float) -> float:
    """T(L) (deg) of one tip position (3,) mm, wrapped to (−180, 180] (one configuration has no
    history to unwrap along)."""
    a = float(tip_azimuth(tip_position, outer_alpha_deg))
    return 180.0 - (180.0 - a) % 360.0


def backbone_dict(eq: Equilibrium) -> dict[str, object]:
    """The backbone of an equilibrium for JSON: s (K,) mm, points (K, 3) mm, twist ψ (K, N) deg
    (null where a tube has ended)."""
    return {"s_mm": eq.s.tolist(), "points_mm": eq.backbone.tolist(),
            "twist_deg": [[float(v) if np.isfinite(v) else None for v in row] for row in eq.twist]}


@click.command("sweep", epilog="""\b
Examples:
  ctrkin sweep --out out/sweep
  ctrkin sweep --translations 4,20 --step 2 --out out/sweep-coarse
  ctrkin sweep --translations 8,16 --step 5 --out out/sweep-json --json > sweep.json
  ctrkin sweep --friction 0.2 --clearance 1 --out out/sweep-friction""")
@config_options(SweepConfig, aliases={"step_deg": ("--step",)})
@output_options
def sweep_cmd(overwrite: bool, as_json: bool, **settings: Any) -> None:
    """Full inner-tube rotation forward and back at several relative translations (paper
    Fig. 2b), solved by continuation: writes sweep.csv and a plot of T(L) against α0."""
    cfg = SweepConfig(**settings)
    outer_beta, outer_alpha, step_deg = cfg.outer_beta, cfg.outer_alpha, cfg.step_deg
    from ctrkin.viz.sweep import plot_sweeps

    levels = list(cfg.translations)
    out = output_folder(cfg.out, "sweep", overwrite, inputs=[cfg.robot])
    robot = load_robot(cfg.robot)
    robot = dataclasses.replace(robot, friction=robot.friction if cfg.friction is None else cfg.friction,
                                clearance=robot.clearance if cfg.clearance is None else cfg.clearance)
    free = dataclasses.replace(robot, friction=0.0) if robot.friction > 0 else None
    n = robot.n_tubes
    frames, curves = [], []
    paths = [rotation_sweep(n, d, outer_beta, outer_alpha, step_deg) for d in levels]
    with progress_bar(total=sum(len(p) for p in paths), desc="sweeps") as bar:
        for d, Q in zip(levels, paths, strict=True):
            robot.check_joints(Q)
            tr = follow(robot, Q, progress=lambda _t: bar.update(1))
            ref = follow(free, Q).snaps if free is not None else np.zeros(len(Q), bool)
            half = (len(Q) - 1) // 2
            forward = np.arange(len(Q)) <= half
            alpha0 = Q[:, 0] - Q[:, n - 1]
            frames.append(pd.DataFrame({
                "relative_translation": d, "step": np.arange(len(Q)),
                **{c: Q[:, k] for k, c in enumerate(robot.joint_names())},
                "alpha0": alpha0, "forward": forward,
                **{c: tr.tip_poses[:, k] for k, c in enumerate(POSE_COLUMNS)},
                "T_L": tr.azimuth, "snap": tr.snaps, "stable": tr.stable,
                **({"snap_frictionless": ref} if free is not None else {})}))
            curves.append({"label": f"d = {d:g} mm", "alpha0": alpha0, "azimuth": tr.azimuth,
                           "snaps": tr.snaps, "forward": forward,
                           **({"folds_frictionless": ref} if free is not None else {})})
    table = pd.concat(frames, ignore_index=True)
    extra = f", μ = {robot.friction:g}" if robot.friction else ""
    extra += f", clearance {robot.clearance:g}" if robot.clearance else ""
    with build_folder(out, "sweep", CtrkinError, "sweep") as build:     # written as one unit
        table.to_csv(build / "sweep.csv", index=False)
        plot_sweeps(curves, build / "sweep.png",
                    title=f"{robot.name}{extra}: T(L) over full inner rotations")
    summary = []
    for d, f in zip(levels, frames, strict=True):
        snaps = f.loc[f["snap"], "alpha_1"].tolist()
        row: dict[str, object] = {"relative_translation_mm": d, "steps": len(f), "snaps": len(snaps),
                                  "snap_alpha_1_deg": snaps,
                                  "T_L_range_deg": [f["T_L"].min(), f["T_L"].max()]}
        note = ""
        if free is not None:
            ref_snaps = f.loc[f["snap_frictionless"], "alpha_1"].tolist()
            row["snap_alpha_1_deg_frictionless"] = ref_snaps
            note = f" (frictionless: {ref_snaps if ref_snaps else 'none'})"
        say(f"d = {d:5.1f} mm: snaps at α1 = {snaps if snaps else 'none'}{note}")
        summary.append(row)
    say(f"wrote {out / 'sweep.csv'} and {out / 'sweep.png'}")
    if as_json:
        emit_json({"robot": robot.name, "friction": robot.friction, "clearance": robot.clearance,
                   "step_deg": step_deg, "levels": summary,
                   "files": {"table": out / "sweep.csv", "plot": out / "sweep.png"}})
