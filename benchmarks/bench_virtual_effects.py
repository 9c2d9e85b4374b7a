"""Benchmark: how far the nominal TCM is from the virtual paper robot, with every effect and with
each effect alone (issue 20, goals 2 and 3; docs/virtual_robot.md: What the defaults give).

    python benchmarks/bench_virtual_effects.py                  # defaults and each effect alone
    python benchmarks/bench_virtual_effects.py --seeds 0 1 2 3 4 --only defaults
    python benchmarks/bench_virtual_effects.py --only defaults --set tube_friction=0.5

For each configuration, one virtual robot per seed records the quick paper protocol (the training
data), the 20 random points and the arbitrary path of `ctrkin reproduce`; the paper's TCM baseline
(the nominal robot, point-wise, no history) is registered to the tracker on the training rows, as
`ctrkin reproduce` does (evaluation/tcm_baseline.py, Kabsch on up to 2,000 rows), and scored
against the measurement on the random points' targets and along the arbitrary path (encoder
glitches left out). Prints a table (RMSE and max in mm, per experiment; medians over seeds when
there are several) and ends with one JSON line of the figures.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np

from ctrkin.acquisition import protocols
from ctrkin.acquisition.recorder import record
from ctrkin.evaluation.tcm_baseline import TCMBaseline
from ctrkin.metrics import position_error
from ctrkin.robots import paper_robot
from ctrkin.virtual import VirtualConfig, VirtualRobot

# the effects of docs/virtual_robot.md, each the VirtualConfig fields it switches on
EFFECTS = {
    "precurvature error": ("precurvature_error",),
    "stiffness error": ("stiffness_error",),
    "residual curvature": ("residual_curvature",),
    "encoder zero offset": ("alpha_zero_error_deg",),
    "precurvature along the arc": ("precurvature_variation",),
    "precurvature out of plane": ("precurvature_plane_deg",),
    "friction between the tubes": ("tube_friction",),
    "clearance": ("clearance",),
    "gear backlash": ("gear_backlash_deg",),
    "bearing friction": ("friction_deg",),
    "lead-screw backlash": ("leadscrew_backlash_mm",),
    "registration error": ("registration_mm", "registration_deg"),
    "EM field distortion": ("em_distortion_mm", "em_distortion_length_mm"),
    "sensor offset": ("sensor_offset_mm",),
    "tracker noise": ("noise_mm", "noise_deg", "readings_per_sample"),
    "encoder glitches": ("glitch_rate", "glitch_deg", "glitch_mm"),
}


def alone(fields: tuple[str, ...]) -> VirtualConfig:
    """The ideal robot with `fields` at their defaults."""
    d = VirtualConfig()
    return dataclasses.replace(VirtualConfig().ideal(), **{f: getattr(d, f) for f in fields})


def score(config: VirtualConfig, seed: int, workers: int) -> dict[str, float]:
    robot = paper_robot()
    virtual = VirtualRobot(robot, config, seed=seed)
    train = record(protocols.build("paper", robot, scale="quick", seed=0), virtual, seed=0,
                   workers=workers, progress=False)
    rows = train.get_split().train
    tcm = TCMBaseline(robot)
    tcm.fit_registration(train.joints()[rows], train.poses()[rows], max_points=2000)
    out: dict[str, float] = {}
    for name, kw, seed_noise in (("random_points", {"n_points": 20}, 2), ("arbitrary", {}, 3)):
        ds = record(protocols.build(name.replace("_", "-"), robot, scale="quick", seed=seed_noise, **kw),
                    virtual, seed=seed_noise, workers=workers, progress=False)
        keep = ~ds.frame["outlier"].to_numpy()
        if "is_target" in ds.frame and name == "random_points":
            keep &= ds.frame["is_target"].to_numpy()
        idx = np.nonzero(keep)[0]
        e = position_error(tcm.predict(ds.joints()[idx], desc="TCM"), ds.poses()[idx])
        out[f"{name}_rmse_mm"] = float(np.sqrt(np.mean(e ** 2)))
        out[f"{name}_max_mm"] = float(e.max())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--only", choices=["defaults", "all"], default="all")
    ap.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE",
                    help="change a default (VirtualConfig field) of the 'defaults' row")
    args = ap.parse_args()
    changed = {k: type(getattr(VirtualConfig(), k))(v)
               for k, v in (item.split("=", 1) for item in args.settings)}
    label = "defaults" + "".join(f" {k}={v}" for k, v in changed.items())
    configs = {label: VirtualConfig(**changed)}
    if args.only == "all":
        configs["ideal (no effect)"] = VirtualConfig().ideal()
        configs |= {name: alone(fields) for name, fields in EFFECTS.items()}
    keys = ("random_points_rmse_mm", "random_points_max_mm", "arbitrary_rmse_mm", "arbitrary_max_mm")
    print(f"nominal TCM vs measured, registration fitted on the quick paper protocol; seeds {args.seeds}")
    print(f"{'configuration':32s} {'random RMSE':>11s} {'max':>6s} {'arbitrary RMSE':>14s} {'max':>6s}  s")
    summary: dict[str, dict[str, float]] = {}
    for name, cfg in configs.items():
        t0 = time.perf_counter()
        runs = [score(cfg, s, args.workers) for s in args.seeds]
        med = {k: float(np.median([r[k] for r in runs])) for k in keys}
        summary[name] = med | {f"{k}_seeds": [r[k] for r in runs] for k in keys}  # type: ignore[misc]
        print(f"{name:32s} {med[keys[0]]:11.2f} {med[keys[1]]:6.2f} {med[keys[2]]:14.2f} "
              f"{med[keys[3]]:6.2f}  {time.perf_counter() - t0:.0f}")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
