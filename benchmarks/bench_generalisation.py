"""Benchmark: the learned claims on robots and effect mixes nobody tuned for (issue 21, goals 1 and 4;
docs/reproduction.md: Other robots: the generalisation table).

    python benchmarks/bench_generalisation.py --out out/generalisation             # every robot, quick
    python benchmarks/bench_generalisation.py --robots default-top three-tube --out out/gen
    python benchmarks/bench_generalisation.py --scale tiny --robots default-top --out /tmp/gen
    python benchmarks/bench_generalisation.py --jobs 4 --workers 4 --out out/gen   # robots side by side

Each robot runs the pipeline a new user runs, `ctrkin reproduce --scale S --robot R.toml
--robot-seed K --set ...` (in a child process, into OUT/<robot>, its log OUT/<robot>.log; a rerun
reuses what a finished stage left there, as reproduce does), then the recommended FK model is driven
along mid-turn reversals recorded on the same virtual robot (`reversals`, below). The robots
(`ROBOTS`): the paper robot with every effect at the top of its published range (the virtual
robot's defaults, docs/virtual_robot.md); a second two-tube design (other
diameters and curvatures, another hardware seed); a three-tube robot, with the top-of-range
effects and with every effect at its central value; the paper robot's worst hardware seed with
friction and backlash at the top of their ranges and the rest at their central values (the defaults
before issue 20). The others carry the top-of-range effects.

Prints one row per robot with the goal-1 figures of issue 21 and the wall time, then one JSON line of
every figure. Columns (held-out data of the reproduction; position RMSE in mm unless said):
  FK true     the recommended FK against the noise-free truth (held-out paper sequences)
  FK          the same against the measurement; TCM / cal  the nominal / calibrated point-wise TCM
              against the measurement, and the ratios TCM ÷ FK and cal ÷ FK (goals ≥ 5 and ≥ 2)
  sweeps P/R  snap precision / recall within ±2 steps on the sweeps, the worse of the two rotation
              directions; turns P/R the same on the snap turns (outer angles never trained); mag
              the larger of the two snap-magnitude errors (deg)
  rev         FK against the truth along mid-turn reversals (`reversals`)
  small       FK against the truth along small back-and-forth moves of the outer tube, the inner tube
              and d (`small_moves`; per kind in the JSON line), judged against the FK goal (≤ 0.5)
  IK          follow IK on held-out sequences, tip reached by driving the robot; rand  random poses
              reached within 1 mm (of 20); sq / tri  square and triangle, tip via the robot
  IK floor    the recorded joints of the same held-out sequences driven as the IK's are (each from rest
              at its first row; benchmarks/bench_ik_floor.py): what an IK that answered the
              recording's own joints would get (the JSON line also has its first 100 steps and the rest)
  reach sq/tri  how far the square's / triangle's targets are from poses the robot can take: the
              position RMSE of the best pose fit on the true robot without friction (position plus
              10 mm per radian of tangent; bench_ik_floor.path_reach; the JSON line also has the fit's
              tangent miss and what matching the position alone costs in tangent). The targets'
              orientations are interpolated between the corners (Fig. 12), so an edge's pose need not
              be reachable: an IK that matches the pose misses the position by this before friction
  gate res/max (no fold)  the fold gate's assumption (`gate_residuals`): RMS / largest residual (deg)
              of the training snaps from the nominal folds shifted by the fitted offsets, and the
              snaps where the nominal robot has no fold, of all snaps in the band (the JSON line
              also has them on the held-out sweeps: sweeps_gate_*)
Goals (issue 21, goal 1): FK true ≤ 0.5, TCM ÷ FK ≥ 5, cal ÷ FK ≥ 2, P/R ≥ 0.9, mag ≤ 5°, rev ≤ 0.5,
IK ≤ 1.0, rand ≥ 18/20, sq and tri ≤ 1.5 mm; a figure that misses its goal is marked `*`.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.acquisition.plan import Plan, Run, Segment
from ctrkin.acquisition.protocols import config
from ctrkin.acquisition.ranges import ProtocolRanges
from ctrkin.acquisition.recorder import record
from ctrkin.data.dataset import Dataset
from ctrkin.evaluation.datasets import registered_truth
from ctrkin.metrics import position_error
from ctrkin.robots import load_robot
from ctrkin.robots.robot import Robot
from ctrkin.robots.tube import Tube
from ctrkin.virtual import VirtualConfig, VirtualRobot
from ctrkin.virtual.config import CENTRAL

sys.path.insert(0, str(Path(__file__).resolve().parent))   # the benchmark beside this one
from bench_fold_gate import snap_residuals

# every effect at the top of its published range: the virtual robot's defaults since issue 20 (given
# explicitly, so that the rows keep their meaning if the defaults move again)
TOP = {"precurvature_error": 0.2, "stiffness_error": 0.2, "tube_friction": 0.69, "gear_backlash_deg": 2.0,
       "leadscrew_backlash_mm": 0.1, "registration_deg": 5.0, "em_distortion_mm": 1.64, "noise_mm": 0.4,
       "sensor_offset_mm": 6.5}
# friction and backlash at the top of their ranges, everything else at the central values (CENTRAL: the
# defaults before issue 20)
FRICTION_BACKLASH = {**CENTRAL, "tube_friction": 0.69, "gear_backlash_deg": 2.0, "leadscrew_backlash_mm": 0.1}


def _tube(od: float, idd: float, straight: float, curved: float, radius: float) -> Tube:
    return Tube(od=od, id=idd, straight_length=straight, curved_length=curved, curvature=1.0 / radius,
                youngs_modulus=58.0, poisson_ratio=0.33)


def design_b() -> Robot:
    """A second two-tube design: thicker tubes with tighter, longer curves than the paper robot's
    (radii 22 / 20 mm over 18 / 17 mm), so the curved overlap that snaps is shorter."""
    return Robot(tubes=(_tube(0.45, 0.25, 55.0, 18.0, 22.0), _tube(0.7, 0.5, 38.0, 17.0, 20.0)),
                 name="design-b")


def three_tube() -> Robot:
    """The paper's inner tube inside two paper-like outer tubes (the three-tube robot of
    tests/evaluation/test_reproduce_other_robots.py): L1 − L2 = 15.5 mm."""
    return Robot(tubes=(_tube(0.4, 0.2, 57.0, 15.0, 27.0), _tube(0.56, 0.45, 42.0, 14.5, 24.0),
                        _tube(0.8, 0.66, 30.0, 14.5, 24.0)), name="three-tube")


@dataclass(frozen=True)
class Case:
    """One robot or effect mix: `robot` a built-in name or a function giving the Robot, the hardware
    seed, the `--set` effects."""

    robot: Any
    seed: int
    settings: dict[str, Any]
    what: str


ROBOTS: dict[str, Case] = {
    "default-top": Case("paper", 0, TOP, "paper robot, every effect at the top of its range"),
    "design-b": Case(design_b, 3, TOP, "second two-tube design, hardware seed 3, top of ranges"),
    "three-tube": Case(three_tube, 1, TOP, "three tubes, hardware seed 1, top of ranges"),
    "three-tube-central": Case(three_tube, 1, CENTRAL,
                               "three tubes, hardware seed 1, every effect at its central value"),
    "friction-backlash": Case("paper", 2, FRICTION_BACKLASH,
                              "paper robot seed 2, friction and backlash at the top, rest central"),
}

# mid-turn reversals: the inner tube turns 0 → 250 → 110 → 330 → 60° (absolute, 1° steps), reversing
# inside and outside the bistable band about α0 = 180°, at outer angles the paper protocol never
# records, at the paper robot's d = 12 mm carried over to the robot (issue 21's first measurement)
REVERSAL_TURNS_DEG = (0.0, 250.0, 110.0, 330.0, 60.0)
REVERSAL_OUTER = ((35.0, -1.25), (155.0, -3.75), (275.0, -2.5))
REVERSAL_D_MM = 12.0
REVERSAL_SEED = 7


def reversals_plan(robot: Robot) -> Plan:
    """One run per outer pose (αN, βN), each one recorded sequence of the inner tube's reversing turn."""
    ranges = ProtocolRanges.of(robot)
    d = ranges.d(REVERSAL_D_MM)
    legs = [np.arange(a, b, 1.0 if b > a else -1.0) for a, b in itertools.pairwise(REVERSAL_TURNS_DEG)]
    a1 = np.r_[np.concatenate(legs), REVERSAL_TURNS_DEG[-1]]
    runs = tuple(Run((Segment(config(robot.n_tubes, a1, ao, ranges.beta_outer(bo), d), level=0),))
                 for ao, bo in REVERSAL_OUTER)
    return Plan("reversals", runs, ({"relative_translation_mm": d},),
                {"turns_deg": list(REVERSAL_TURNS_DEG), "outer": [list(o) for o in REVERSAL_OUTER],
                 "d_mm": d})


def reversal_data(robot: Robot, virtual: VirtualRobot) -> tuple[Dataset, np.ndarray, np.ndarray]:
    """The mid-turn reversals recorded on a virtual robot of the nominal `robot`: the dataset (one
    run per outer pose, from rest), its noise-free tracker view of the truth (T, 6) and the (T,) rows
    to score (not glitches)."""
    ds = record(reversals_plan(robot), virtual, seed=REVERSAL_SEED, workers=1, progress=False)
    return ds, registered_truth(ds, virtual), ~ds.frame["outlier"].to_numpy()


def reversals(robot: Robot, case: Case, fk_folder: Path) -> dict[str, float]:
    """FK along mid-turn reversals: position RMSE / max (mm) of the recommended FK against the
    noise-free truth, on the reproduction's virtual robot (same hardware seed and effects)."""
    from ctrkin.inference import Kinematics

    virtual = VirtualRobot(robot, VirtualConfig(**case.settings), seed=case.seed)
    ds, truth, keep = reversal_data(robot, virtual)
    fk = Kinematics.load(fk_folder)
    pred = np.asarray(fk.predict(ds), float)
    e = position_error(pred[keep], truth[keep])
    return {"reversal_rmse_true_mm": float(np.sqrt(np.mean(e ** 2))), "reversal_max_true_mm": float(e.max()),
            "reversal_samples": int(keep.sum())}


# small moves, as a controller makes them near a target (issue 21: the play-lag inputs' narrow operators
# are taken up part of the way there, which the training protocols' 1° and 0.1 mm steps of long moves
# never do): at each outer pose of the reversals, with α0 = 60° (outside the bistable band) and the
# reversals' d, the outer tube with the inner one (α0 fixed), the inner tube alone, and d, each back and
# forth 0 → SMALL_ANGLE_DEG → 0 → SMALL_ANGLE_DEG in SMALL_STEP_DEG steps (d: SMALL_D_MM in SMALL_STEP_MM)
SMALL_ANGLE_DEG, SMALL_STEP_DEG = 6.0, 0.5
SMALL_D_MM, SMALL_STEP_MM = 0.3, 0.02
SMALL_A0_DEG = 60.0
SMALL_SEED = 11
SMALL_KINDS = ("outer", "inner", "d")


def _back_and_forth(size: float, step: float) -> np.ndarray:
    up = np.arange(0.0, size + step / 2, step)
    return np.r_[up, up[::-1][1:], up[1:]]


def small_moves_plan(robot: Robot) -> tuple[Plan, list[str]]:
    """One run per outer pose and kind (SMALL_KINDS, module comment); the kind of each run."""
    ranges = ProtocolRanges.of(robot)
    d = ranges.d(REVERSAL_D_MM)
    w, dd = _back_and_forth(SMALL_ANGLE_DEG, SMALL_STEP_DEG), _back_and_forth(SMALL_D_MM, SMALL_STEP_MM)
    runs, kinds = [], []
    for ao, bo in REVERSAL_OUTER:
        b = ranges.beta_outer(bo)
        paths = {"outer": config(robot.n_tubes, ao + SMALL_A0_DEG + w, ao + w, b, d),
                 "inner": config(robot.n_tubes, ao + SMALL_A0_DEG + w, np.full(len(w), ao), b, d),
                 "d": config(robot.n_tubes, np.full(len(dd), ao + SMALL_A0_DEG), np.full(len(dd), ao), b,
                             d - ranges.scale * dd)}
        for kind in SMALL_KINDS:
            runs.append(Run((Segment(paths[kind], level=0),)))
            kinds.append(kind)
    return Plan("small-moves", tuple(runs), ({"relative_translation_mm": d},), {"kinds": kinds}), kinds


def small_moves(robot: Robot, case: Case, fk_folder: Path) -> dict[str, float]:
    """FK along small moves (module comment): position RMSE (mm) of the recommended FK against the
    noise-free truth per kind (`small_<kind>_rmse_true_mm`) and over all (`small_rmse_true_mm`)."""
    from ctrkin.inference import Kinematics

    virtual = VirtualRobot(robot, VirtualConfig(**case.settings), seed=case.seed)
    plan, kinds = small_moves_plan(robot)
    ds = record(plan, virtual, seed=SMALL_SEED, workers=1, progress=False)
    truth, keep = registered_truth(ds, virtual), ~ds.frame["outlier"].to_numpy()
    e = position_error(np.asarray(Kinematics.load(fk_folder).predict(ds), float), truth)
    kind_of = np.empty(len(e), object)
    for (a, b), kind in zip(ds.sequence_bounds(), kinds, strict=True):
        kind_of[a:b] = kind
    out = {f"small_{k}_rmse_true_mm": float(np.sqrt(np.mean(e[keep & (kind_of == k)] ** 2)))
           for k in SMALL_KINDS}
    return out | {"small_rmse_true_mm": float(np.sqrt(np.mean(e[keep] ** 2)))}


def gate_residuals(fk_folder: Path, data_folder: Path) -> dict[str, Any]:
    """How far the robot's snaps are from the fold gate's assumed form (docs/learned_kinematics.md:
    What the learned models assume about the robot; benchmarks/bench_fold_gate.py): the residuals
    (deg of α0) of every snap of a dataset in the bistable band from θ± = φ±(β) ± c − κ·m_N with the
    model's fitted c and κ, and the snaps where the nominal robot has no fold."""
    from ctrkin.data.dataset import Dataset
    from ctrkin.families.snap_aware.fold_gate import FoldGate

    gate = FoldGate.load(fk_folder)
    return {**snap_residuals(gate, Dataset.load(data_folder)),
            "gate_widen_deg": gate.widen_deg, "gate_outer_lag_deg": gate.outer_lag_deg}


def ik_floor(data_folder: Path) -> dict[str, float]:
    """The held-out IK experiment's floor (`IK floor`, module docstring) on a reproduction's data;
    none for data not recorded on the virtual robot (nothing to drive)."""
    from bench_ik_floor import recorded  # (it imports this module through bench_fk_memory)
    from ctrkin.virtual.truth import virtual_from_meta

    ds = Dataset.load(data_folder)
    if "virtual_robot" not in ds.meta or ds.split is None:
        return {}
    floor = recorded(virtual_from_meta(ds), ds)
    return {f"ik_floor_{k.removeprefix('recorded_')}": v for k, v in floor.items()}


def path_reach_figures(data_folder: Path) -> dict[str, float]:
    """`reach sq/tri` (module docstring) on a reproduction's virtual robot; none for data not recorded
    on the virtual robot."""
    from bench_ik_floor import path_reaches
    from ctrkin.virtual.truth import virtual_from_meta

    ds = Dataset.load(data_folder)
    return path_reaches(virtual_from_meta(ds)) if "virtual_robot" in ds.meta else {}


def _held_out(residuals: dict[str, Any]) -> dict[str, Any]:
    """gate_residuals on the held-out sweeps, under sweeps_* (the fitted offsets only once)."""
    fitted = ("gate_widen_deg", "gate_outer_lag_deg")
    return {f"sweeps_{k}": v for k, v in residuals.items() if k not in fitted}


def _robot(case: Case) -> Robot:
    return load_robot(case.robot) if isinstance(case.robot, str) else case.robot()


def run_case(name: str, case: Case, scale: str, out: Path, workers: int, device: str,
             reuse: bool = False) -> dict[str, Any]:
    """`ctrkin reproduce` on one case in a child process, then the reversals and the fold gate's
    residuals; its figures. reuse: read a finished reproduction's results.json in OUT/<robot>
    instead of running it (wall_s is then its `seconds.total`)."""
    robot = _robot(case)
    robot_file = out / f"{name}.toml"
    if reuse and (out / name / "results.json").is_file():
        return _figures(name, case, robot, out, None)
    robot.to_toml(robot_file)
    cmd = [sys.executable, "-m", "ctrkin.cli.main", "--quiet", "reproduce", "--scale", scale, "--robot",
           str(robot_file), "--robot-seed", str(case.seed), "--workers", str(workers), "--device", device,
           "--out", str(out / name)]
    for k, v in case.settings.items():
        cmd += ["--set", f"{k}={v}"]
    t0 = time.perf_counter()
    with open(out / f"{name}.log", "w") as log:
        rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, check=False).returncode
    if rc != 0:
        return {"robot": name, "error": f"reproduce exited {rc} (see {out / name}.log)",
                "wall_s": time.perf_counter() - t0}
    return _figures(name, case, robot, out, time.perf_counter() - t0)


def _figures(name: str, case: Case, robot: Robot, out: Path, wall_s: float | None) -> dict[str, Any]:
    res = json.loads((out / name / "results.json").read_text())
    row = {"robot": name, "what": case.what, "seed": case.seed, "n_tubes": robot.n_tubes, **figures_of(res)}
    fk_folder = out / name / res["recommended"]["fk"]
    for extra in (lambda: reversals(robot, case, fk_folder), lambda: small_moves(robot, case, fk_folder),
                  lambda: gate_residuals(fk_folder, out / name / "data" / "paper"),
                  lambda: ik_floor(out / name / "data" / "paper"),
                  lambda: path_reach_figures(out / name / "data" / "paper"),
                  lambda: _held_out(gate_residuals(fk_folder, out / name / "data" / "sweeps"))):
        try:
            row |= extra()
        except Exception as exc:  # a figure that cannot be computed is reported, the rest kept
            row.setdefault("errors", []).append(f"{type(exc).__name__}: {exc}")
    return {**row, "wall_s": res["seconds"]["total"] if wall_s is None else wall_s,
            "reproduce_s": res["seconds"]["total"]}


def _worst(report: dict[str, Any], key: str) -> float | None:
    """The worse of the two rotation directions (lowest precision or recall); a direction without
    a snap (its score undefined, null in results.json) does not count."""
    vals = [float(report[d][key]) for d in ("forward", "backward") if report[d].get(key) is not None]
    return min(vals) if vals else None


def _largest(report: dict[str, Any], key: str) -> float | None:
    vals = [report[d][key] for d in ("forward", "backward") if report[d].get(key) is not None]
    return max(vals) if vals else None


def figures_of(res: dict[str, Any]) -> dict[str, Any]:
    """The goal-1 figures of one results.json (recommended models; docs/reproduction.md)."""
    fk, ik, ex, snap = res["fk"], res["ik"], res["experiments"], res["snapping"]
    model = snap["model"]
    sweeps, turns = snap[model], snap["snap_turns"][model]
    mags = [m for m in (_largest(sweeps, "magnitude_error_deg"), _largest(turns, "magnitude_error_deg"))
            if m is not None]
    fk_m = fk["lstm_mlp"]["position_rmse_mm"]
    cal = fk.get("tcm_calibrated", {}).get("position_rmse_mm")     # absent in results before issue 20
    return {
        "fk_true_mm": fk["lstm_mlp"]["position_rmse_true_mm"],
        "fk_mm": fk_m,
        "tcm_mm": fk["tcm"]["position_rmse_mm"],
        "tcm_calibrated_mm": cal,
        "tcm_ratio": fk["tcm"]["position_rmse_mm"] / fk_m,
        "tcm_calibrated_ratio": None if cal is None else cal / fk_m,
        "sweeps_precision": _worst(sweeps, "precision"), "sweeps_recall": _worst(sweeps, "recall"),
        "sweeps_snaps": int(sweeps["n_reference"]),
        "turns_precision": _worst(turns, "precision"), "turns_recall": _worst(turns, "recall"),
        "turns_snaps": int(turns["n_reference"]),
        "snap_magnitude_deg": max(mags) if mags else None,
        "ik_tip_mm": ik["lstm_mlp"]["tip_error_mm"],
        "ik_random_within_1mm": ex["ik_random"]["lstm_mlp"]["within_1mm_via_robot"],
        "ik_random_points": ex["ik_random"]["lstm_mlp"]["n_points"],
        "ik_square_mm": ex["ik_square"]["position_rmse_mm"],
        "ik_triangle_mm": ex["ik_triangle"]["position_rmse_mm"],
    }


# (key, goal test) per column of the table
GOALS = {"fk_true_mm": lambda v: v <= 0.5, "tcm_ratio": lambda v: v >= 5,
         "tcm_calibrated_ratio": lambda v: v >= 2,
         "sweeps_precision": lambda v: v >= 0.9, "sweeps_recall": lambda v: v >= 0.9,
         "turns_precision": lambda v: v >= 0.9, "turns_recall": lambda v: v >= 0.9,
         "snap_magnitude_deg": lambda v: v <= 5, "reversal_rmse_true_mm": lambda v: v <= 0.5,
         "small_rmse_true_mm": lambda v: v <= 0.5,
         "ik_tip_mm": lambda v: v <= 1.0, "ik_random_within_1mm": lambda v: v >= 18,
         "ik_square_mm": lambda v: v <= 1.5, "ik_triangle_mm": lambda v: v <= 1.5}


def _cell(row: dict[str, Any], key: str, fmt: str) -> str:
    v = row.get(key)
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    miss = key in GOALS and not GOALS[key](v)
    return format(v, fmt) + ("*" if miss else "")


HEADER = ("robot", "FK true", "FK", "TCM (×)", "cal (×)", "sweeps P/R", "turns P/R", "mag", "rev", "small",
          "IK", "IK floor", "rand", "sq", "tri", "reach sq/tri", "gate res/max (no fold)", "wall s")


def table_row(row: dict[str, Any]) -> list[str]:
    if "error" in row:      # reproduce failed
        return [row["robot"], row["error"], *[""] * (len(HEADER) - 3), f"{row['wall_s']:.0f}"]
    return [row["robot"], _cell(row, "fk_true_mm", ".2f"), _cell(row, "fk_mm", ".2f"),
            f"{_cell(row, 'tcm_mm', '.2f')} ({_cell(row, 'tcm_ratio', '.1f')})",
            f"{_cell(row, 'tcm_calibrated_mm', '.2f')} ({_cell(row, 'tcm_calibrated_ratio', '.1f')})",
            f"{_cell(row, 'sweeps_precision', '.2f')}/{_cell(row, 'sweeps_recall', '.2f')} "
            f"({row['sweeps_snaps']})",
            f"{_cell(row, 'turns_precision', '.2f')}/{_cell(row, 'turns_recall', '.2f')} "
            f"({row['turns_snaps']})",
            _cell(row, "snap_magnitude_deg", ".1f"), _cell(row, "reversal_rmse_true_mm", ".2f"),
            _cell(row, "small_rmse_true_mm", ".2f"), _cell(row, "ik_tip_mm", ".2f"),
            _cell(row, "ik_floor_mm", ".2f"),
            f"{_cell(row, 'ik_random_within_1mm', 'd')}/{row['ik_random_points']}",
            _cell(row, "ik_square_mm", ".2f"), _cell(row, "ik_triangle_mm", ".2f"),
            f"{_cell(row, 'ik_square_reach_mm', '.2f')}/{_cell(row, 'ik_triangle_reach_mm', '.2f')}",
            f"{_cell(row, 'gate_residual_rms_deg', '.1f')}/{_cell(row, 'gate_residual_max_deg', '.1f')} "
            f"({row.get('gate_no_fold_snaps', '–')} of {row.get('gate_snaps', '–')})", f"{row['wall_s']:.0f}"]


def print_table(rows: list[dict[str, Any]]) -> None:
    cells = [list(HEADER)] + [table_row(r) for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(HEADER))]
    for c in cells:
        print("  ".join(v.ljust(w) for v, w in zip(c, widths, strict=True)), flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", nargs="+", choices=list(ROBOTS), default=list(ROBOTS),
                    help="the robots and effect mixes to run (default all)")
    ap.add_argument("--scale", default="quick", choices=("tiny", "quick", "full"),
                    help="the reproduction's scale (default quick)")
    ap.add_argument("--out", required=True, type=Path,
                    help="a new or empty folder (one reproduction folder per robot inside)")
    ap.add_argument("--overwrite", action="store_true",
                    help="write into --out although it is not empty (reproductions there are reused)")
    ap.add_argument("--reuse", action="store_true",
                    help="read the figures of reproductions already finished in --out (with --overwrite)")
    ap.add_argument("--workers", type=int, default=2, help="recording and training workers per robot")
    ap.add_argument("--jobs", type=int, default=1, help="robots run side by side (default 1)")
    ap.add_argument("--device", default="auto", choices=("auto", "cpu", "cuda"),
                    help="training device, as reproduce's --device")
    args = ap.parse_args(argv)
    out: Path = args.out
    if out.exists() and (not out.is_dir() or any(out.iterdir())) and not args.overwrite:
        print(f"{out} exists and is not empty; pass --overwrite to write into it (or choose another --out)",
              file=sys.stderr)
        return 1
    out.mkdir(parents=True, exist_ok=True)
    print(f"bench_generalisation: {', '.join(args.robots)} at scale {args.scale}, {args.jobs} at a time, "
          f"load {os.getloadavg()[0]:.1f}", flush=True)
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futures = [pool.submit(run_case, n, ROBOTS[n], args.scale, out, args.workers, args.device, args.reuse)
                   for n in args.robots]
        for f in as_completed(futures):          # each row on disk as soon as its robot is done
            with (out / "rows.jsonl").open("a") as rows_file:
                rows_file.write(json.dumps(f.result()) + "\n")
        rows = [f.result() for f in futures]
    print_table(rows)
    print(f"wall {time.perf_counter() - t0:.0f} s, load {os.getloadavg()[0]:.1f}", flush=True)
    print(json.dumps({"scale": args.scale, "rows": rows}))
    return 0 if all("error" not in r for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
