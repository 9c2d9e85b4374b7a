"""`ctrkin collect`: record a protocol on the virtual robot into a dataset folder.

    ctrkin collect --protocol paper --scale quick --out data/paper-quick      # reproduce --scale quick's data
    ctrkin collect --protocol paper --scale full --out data/paper            # the paper's ~208k samples
    ctrkin collect --protocol paper --scale tiny --out data/paper-tiny       # reproduce --scale tiny's data
    ctrkin collect --protocol sweeps --out data/sweeps
    ctrkin collect --protocol sweeps --levels 2,6,10 --robot my_robot.toml --out data/my-sweeps
    ctrkin collect --protocol random-points --n-points 20 --seed 1 --out data/random
    ctrkin collect --protocol arbitrary --out data/arbitrary
    ctrkin collect --protocol excitation --scale quick --seed 8 --out data/excitation   # training only
    ctrkin collect --protocol square --out data/square        # IK targets, not a dataset
    ctrkin collect --rig examples/rigs/paper.toml --protocol paper --scale full --out data/rig-paper

With --rig the protocol runs on the rig the file describes (motors over CANopen and an NDI tracker,
or the virtual robot, or a replayed log; docs/hardware.md): the same dataset format, tracker
readings averaged, safety checks before every move, Ctrl-C stops the motors, and the same command
resumes an interrupted collection.

The robot seed (--robot-seed) draws the virtual hardware (true tubes, offsets, registration); keep it
the same for training and test data of one "robot". --seed draws the measurement noise, glitches
and random configurations. Effect magnitudes can be changed with --set KEY=VALUE (see
docs/virtual_robot.md), e.g. --set friction_deg_per_mm=0 --set noise_mm=0.1.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import click

from ctrkin.acquisition import protocols
from ctrkin.acquisition.plan import Plan
from ctrkin.acquisition.recorder import record
from ctrkin.acquisition.summary import sweep_hysteresis
from ctrkin.acquisition.task_paths import SHAPES, task_path
from ctrkin.cli.common import (
    ROBOT_HELP,
    emit_json,
    output_folder,
    output_options,
    say,
)
from ctrkin.cli.from_config import RANGE, config_options, option_help
from ctrkin.evaluation.scales import Scale
from ctrkin.robots import Robot, load_robot
from ctrkin.virtual import VirtualRobot
from ctrkin.virtual.config import SETTINGS_HELP, VirtualConfig

CHOICES = [*protocols.PROTOCOLS, *SHAPES]
MAX_POINTS = 100_000      # random points or path points: far beyond any protocol, within memory


@dataclass(frozen=True)
class CollectConfig:
    """What `ctrkin collect` records (one option per field; the virtual robot's effect magnitudes
    are VirtualConfig's, set by --set KEY=VALUE; the rig, where there is one, is --rig's file)."""

    protocol: str = field(default="paper", metadata=option_help(
        "What to record: " + ", ".join(CHOICES) + ".", choices=CHOICES))
    scale: Scale = field(default="quick", metadata=option_help(
        "Size of the paper protocol, the training data of `reproduce --scale` of the same name (the "
        "excitation protocol records a fifth of its samples; the other protocols do not depend on it). "
        "full: the paper's, 8 levels x 36 outer angles (207,648 samples); quick: 4 levels x 18 outer "
        "angles (51,912); tiny: 2 levels x 4 outer angles (5,768)."))
    robot: str = field(default="paper", metadata=option_help(ROBOT_HELP))
    seed: int = field(default=0, metadata=option_help("Noise, glitches, random configurations."))
    robot_seed: int = field(default=0, metadata=option_help("The virtual hardware draw."))
    n_points: int | None = field(default=None, metadata={RANGE: (1, MAX_POINTS), **option_help(
        "random-points: number of targets (default 20); square/triangle: number of path points (default "
        "10, as in the paper; at least 4 for a square, 3 for a triangle).")})
    levels: tuple[float, ...] | None = field(default=None, metadata=option_help(
        "paper/sweeps: relative translations d = beta_N - beta_1 (mm), comma-separated (default: the "
        "protocol's, the paper robot's carried over to the robot's curved overlap and reach; "
        "docs/protocols.md: Other robots)."))
    workers: int | None = field(default=None, metadata=option_help("Processes (default: all cores)."))
    rig: str | None = field(default=None, metadata=option_help(
        "Run the protocol on the rig this TOML file describes (docs/hardware.md) instead of the virtual "
        "robot; the robot is the rig's. Running the same command again resumes an interrupted "
        "collection; --overwrite starts over.", path="file"))
    virtual: VirtualConfig = field(default_factory=VirtualConfig, metadata=option_help(
        SETTINGS_HELP, key_values=True, name="--set", metavar="KEY=VALUE"))
    out: str = field(default="", metadata=option_help(
        "Output folder (written as a whole: a failure leaves the previous one; a second collect into it "
        "is refused while one runs).", path="out"))

    def __post_init__(self) -> None:
        if self.protocol not in CHOICES:
            raise click.BadParameter(f"{self.protocol!r} is not one of {', '.join(CHOICES)}",
                                     param_hint="--protocol")
        if self.levels is not None and self.protocol not in ("paper", "sweeps"):
            raise click.BadParameter("--levels applies to the paper and sweeps protocols")
        n = self.n_points
        if n is not None and not 1 <= n <= MAX_POINTS:
            raise click.BadParameter(f"{n} is not in the range 1<=x<={MAX_POINTS}", param_hint="--n-points")
        if self.protocol in SHAPES and n is not None and n < SHAPES[self.protocol]:
            raise click.BadParameter(f"a {self.protocol} needs at least {SHAPES[self.protocol]} points, "
                                     f"got {n}", param_hint="--n-points")
        if n is not None and self.protocol not in (*SHAPES, "random-points"):
            raise click.BadParameter("--n-points applies to random-points, square and triangle",
                                     param_hint="--n-points")

    def plan(self, robot: Robot) -> Plan:
        """The plan of the protocol at its scale (tiny, quick, full) for `robot`, with these options."""
        kw: dict[str, object] = ({"n_points": 20 if self.n_points is None else self.n_points}
                                 if self.protocol == "random-points" else {})
        if self.levels is not None:
            kw["levels"] = self.levels
        return protocols.build(self.protocol, robot, scale=self.scale, seed=self.seed, **kw)


@click.command("collect", epilog="""\b
Examples:
  ctrkin collect --protocol paper --scale tiny --out data/paper-tiny
  ctrkin collect --protocol random-points --n-points 20 --seed 1 --out data/random
  ctrkin collect --protocol sweeps --set noise_mm=0.1 --out data/sweeps-noisy
  ctrkin collect --protocol sweeps --levels 8 --out data/sweeps-8 --json > collect.json
  ctrkin collect --rig examples/rigs/paper.toml --protocol paper --scale full --out data/rig""")
@config_options(CollectConfig, required=("protocol", "out"))
@output_options
def collect_cmd(overwrite: bool, as_json: bool, **options: Any) -> None:
    """Record a protocol on the virtual robot or on a rig (or write square/triangle IK targets)."""
    cfg = CollectConfig(**options)
    out_dir, rig_file = cfg.out, cfg.rig
    protocol, scale, seed, n_points = cfg.protocol, cfg.scale, cfg.seed, cfg.n_points
    if rig_file is not None:
        from ctrkin.cli.collect_rig import collect_on_rig

        ctx = click.get_current_context()
        named = {"robot": "--robot", "robot_seed": "--robot-seed", "virtual": "--set"}
        given = [o for p, o in named.items()
                 if ctx.get_parameter_source(p) == click.core.ParameterSource.COMMANDLINE]
        if given:
            raise click.BadParameter(f"{', '.join(given)}: not used with --rig (the rig file names the "
                                     "robot, and its [virtual] table the virtual robot's seeds and "
                                     "settings)", param_hint="--rig")
        if protocol in SHAPES:
            raise click.BadParameter("square and triangle are IK targets, not a collection; drop --rig",
                                     param_hint="--rig")
        collect_on_rig(rig_file, protocol, cfg.plan, out_dir, overwrite, as_json)
        return
    out = output_folder(out_dir, "task path" if protocol in SHAPES else "dataset", overwrite,
                        inputs=[cfg.robot])
    robot = load_robot(cfg.robot)
    virtual = VirtualRobot(robot, cfg.virtual, seed=cfg.robot_seed)
    if protocol in SHAPES:
        path = task_path(virtual, protocol, n_points=10 if n_points is None else n_points, seed=seed)
        path.save(out)
        say(f"wrote {len(path.poses)} {protocol} targets to {out}")
        if as_json:
            emit_json({"protocol": protocol, "robot": robot.name, "targets": len(path.poses), "out": out})
        return
    plan = cfg.plan(robot)
    t0 = time.perf_counter()
    ds = record(plan, virtual, seed=seed, workers=cfg.workers)
    elapsed = time.perf_counter() - t0
    ds.save(out)
    f = ds.frame
    say(f"{protocol} ({scale}): {len(f)} samples in {f['sequence_id'].nunique()} sequences, "
        f"{int(f['snap'].sum())} snap samples, {int(f['outlier'].sum())} encoder glitches; "
        f"{elapsed:.1f} s ({len(f) / max(elapsed, 1e-9):.0f} samples/s)")
    summary: dict[str, object] = {
        "protocol": protocol, "scale": scale, "robot": robot.name, "seed": seed, "robot_seed": cfg.robot_seed,
        "samples": len(f), "sequences": int(f["sequence_id"].nunique()), "snap_samples": int(f["snap"].sum()),
        "encoder_glitches": int(f["outlier"].sum()), "seconds": elapsed, "out": out}
    if protocol in ("paper", "sweeps"):
        h = sweep_hysteresis(ds)
        summary["hysteresis"] = h.to_dict(orient="records")
        for _, row in h.iterrows():
            say(f"  d = {row['relative_translation_mm']:5.1f} mm: hysteresis mean "
                f"{row['hysteresis_mean_mm']:.2f} mm, max {row['hysteresis_max_mm']:.2f} mm, "
                f"T(L) gap {row['azimuth_gap_max_deg']:.1f} deg, snap samples "
                f"{int(row['snap_samples'])}")
    say(f"wrote {out}")
    if as_json:
        emit_json(summary)
