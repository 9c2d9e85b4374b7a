"""Benchmark: how far the nominal TCM is from the virtual paper robot, with every effect and with
each effect alone (issue 20, goals 2 and 3; docs/virtual_robot.md: What the defaults give).

    python benchmarks/bench_virtual_effects.py                  # defaults and each effect alone
    python benchmarks/bench_virtual_effects.py --seeds 0 1 2 3 4 --only defaults
    python benchmarks/bench_virtual_effects.py --only defaults --set tube_friction=0.5
    python benchmarks/bench_virtual_effects.py --only defaults --calibrated   # + calibrated TCM rows
    python benchmarks/bench_virtual_effects.py --central        # the same at the central values

For each configuration, one virtual robot per seed records the paper protocol at d = 4, 12, 20 mm
and four outer angles (8,652 samples, the training data), the 20 random points and the arbitrary
path of `ctrkin reproduce`; the paper's TCM baseline (the nominal robot, point-wise, no history) is
registered to the tracker on the training rows, as `ctrkin reproduce` does
(evaluation/tcm_baseline.py, Kabsch on up to 2,000 rows), and scored against the measurement on the
random points' targets and along the arbitrary path (encoder glitches left out). With --calibrated,
the defaults row also gets the calibrated physics baseline of `ctrkin reproduce` (issue 20, goal 4):
`ctrkin calibrate` on the training rows at the quick scale's budget (evaluation/reproduce.py: every
group and μ), scored point-wise (`tcm_calibrated`) and followed along each sequence with the
friction state carried (`tcm_calibrated_continued`), with its time per point / step. Prints a table
(RMSE and max in mm, per experiment; medians over seeds when there are several) and ends with one
JSON line of the figures. The defaults are every effect at the top of its published range
(VirtualConfig, sources in docs/virtual_robot.md); --central starts from the central values instead
(`VirtualConfig().central()`, the defaults before): the base row, and each effect alone at its
value there.
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


# the training recording: 3 levels × 4 outer angles × 721 = 8,652 samples, pinned (the quick scale's
# size changes between versions)
TRAIN = {"levels": (4.0, 12.0, 20.0), "outer_step_deg": 90.0}


def alone(base: VirtualConfig, fields: tuple[str, ...]) -> VirtualConfig:
    """The ideal robot with `fields` at their values in `base`."""
    return dataclasses.replace(base.ideal(), **{f: getattr(base, f) for f in fields})


def _errors(pred: np.ndarray, measured: np.ndarray) -> tuple[float, float]:
    e = position_error(pred, measured)
    return float(np.sqrt(np.nanmean(e ** 2))), float(np.nanmax(e))


def score(config: VirtualConfig, seed: int, workers: int, calibrated: bool = False) -> dict[str, float]:
    robot = paper_robot()
    virtual = VirtualRobot(robot, config, seed=seed)
    train = record(protocols.build("paper", robot, scale="quick", seed=0, **TRAIN), virtual, seed=0,
                   workers=workers, progress=False)
    rows = train.get_split().train
    tcm = TCMBaseline(robot)
    tcm.fit_registration(train.joints()[rows], train.poses()[rows], max_points=2000)
    cal = None
    out: dict[str, float] = {}
    if calibrated:   # as evaluation/reproduce.py's _tcm_calibrated at the quick scale
        from ctrkin.calibration import calibrate  # (here: the benchmark also runs on older trees)
        from ctrkin.calibration.params import FRICTION, GROUPS
        from ctrkin.evaluation.reproduce import CALIBRATION_BUDGET
        n_rows, nfev, samples = CALIBRATION_BUDGET["quick"]
        fit_rows = np.sort(np.random.default_rng(0).choice(rows, min(n_rows, len(rows)), replace=False))
        t0 = time.perf_counter()
        res = calibrate(train, robot, (*GROUPS, FRICTION), rows=fit_rows, max_nfev=nfev,
                        friction_samples=samples)
        cal = res.model
        out |= {"calibration_s": time.perf_counter() - t0, "calibrated_mu": cal.robot.friction}
    for name, kw, seed_noise in (("random_points", {"n_points": 20}, 2), ("arbitrary", {}, 3)):
        ds = record(protocols.build(name.replace("_", "-"), robot, scale="quick", seed=seed_noise, **kw),
                    virtual, seed=seed_noise, workers=workers, progress=False)
        keep = ~ds.frame["outlier"].to_numpy()
        if "is_target" in ds.frame and name == "random_points":
            keep &= ds.frame["is_target"].to_numpy()
        idx = np.nonzero(keep)[0]
        measured = ds.poses()[idx]
        out[f"{name}_rmse_mm"], out[f"{name}_max_mm"] = _errors(
            tcm.predict(ds.joints()[idx], desc="TCM"), measured)
        if cal is None:
            continue
        t0 = time.perf_counter()
        point = cal.predict(ds.joints()[idx])
        t1 = time.perf_counter()
        cont = cal.predict_continued(ds.joints(), ds.sequence_bounds())
        t2 = time.perf_counter()
        out[f"{name}_cal_rmse_mm"], out[f"{name}_cal_max_mm"] = _errors(point, measured)
        out[f"{name}_cal_cont_rmse_mm"], out[f"{name}_cal_cont_max_mm"] = _errors(cont[idx], measured)
        out[f"{name}_cal_us_per_point"] = (t1 - t0) / len(idx) * 1e6
        out[f"{name}_cal_cont_us_per_step"] = (t2 - t1) / len(ds.frame) * 1e6
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--only", choices=["defaults", "all"], default="all",
                    help="all: defaults, ideal and each effect alone")
    ap.add_argument("--central", action="store_true",
                    help="start from the central values (VirtualConfig().central()) instead of the "
                    "defaults (the top of each published range)")
    ap.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE",
                    help="change a default (VirtualConfig field) of the 'defaults' row")
    ap.add_argument("--calibrated", action="store_true",
                    help="also calibrate the TCM on the defaults row's training data (goal 4)")
    args = ap.parse_args()
    changed = {k: type(getattr(VirtualConfig(), k))(v)
               for k, v in (item.split("=", 1) for item in args.settings)}
    base = VirtualConfig().central() if args.central else VirtualConfig()
    label = ("central values" if args.central else "defaults") + "".join(
        f" {k}={v}" for k, v in changed.items())
    configs = {label: dataclasses.replace(base, **changed)}
    if args.only == "all":
        configs["ideal (no effect)"] = base.ideal()
        configs |= {name: alone(base, fields) for name, fields in EFFECTS.items()}
    keys = ("random_points_rmse_mm", "random_points_max_mm", "arbitrary_rmse_mm", "arbitrary_max_mm")
    print("nominal TCM vs measured, registration fitted on the paper protocol (8,652 samples); "
          f"seeds {args.seeds}")
    print(f"{'configuration':32s} {'random RMSE':>11s} {'max':>6s} {'arbitrary RMSE':>14s} {'max':>6s}  s")
    summary: dict[str, dict[str, float]] = {}
    for name, cfg in configs.items():
        t0 = time.perf_counter()
        runs = [score(cfg, s, args.workers, args.calibrated and name == label) for s in args.seeds]
        med = {k: float(np.median([r[k] for r in runs])) for k in runs[0]}
        summary[name] = med | {f"{k}_seeds": [r[k] for r in runs] for k in keys}  # type: ignore[misc]
        print(f"{name:32s} {med[keys[0]]:11.2f} {med[keys[1]]:6.2f} {med[keys[2]]:14.2f} "
              f"{med[keys[3]]:6.2f}  {time.perf_counter() - t0:.0f}")
        for row, pre in (("  calibrated TCM, point-wise", "cal"),
                         ("  calibrated TCM, continued", "cal_cont")):
            if f"random_points_{pre}_rmse_mm" in med:
                print(f"{row:32s} {med[f'random_points_{pre}_rmse_mm']:11.2f} "
                      f"{med[f'random_points_{pre}_max_mm']:6.2f} {med[f'arbitrary_{pre}_rmse_mm']:14.2f} "
                      f"{med[f'arbitrary_{pre}_max_mm']:6.2f}")
        if "calibrated_mu" in med:
            print(f"  calibration {med['calibration_s']:.0f} s, fitted μ {med['calibrated_mu']:.3f}; "
                  f"{med['arbitrary_cal_us_per_point']:.0f} µs per point (point-wise), "
                  f"{med['arbitrary_cal_cont_us_per_step']:.0f} µs per step (continued, arbitrary path)")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
