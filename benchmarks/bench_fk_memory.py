"""Benchmark: how much memory (input buffer IB, epochs) the recommended FK needs (issue 21, goal 1's
FK; docs/learned_kinematics.md: Memory of the recommended FK).

    python benchmarks/bench_fk_memory.py --data out/reproduce/data/paper --out /tmp/fkmem
    python benchmarks/bench_fk_memory.py --data ... --out ... --arms ib2,ib4,ib8,ib2e160
    python benchmarks/bench_fk_memory.py --repro out/gen/default-top --out ...  # + FK experiments
    python benchmarks/bench_fk_memory.py --collect /tmp/nowarp --set em_distortion_mm=0 --out ... \
        --arms ib2,ib2p          # the reproduction's data recorded first, on the default robot with --set

Every arm (but `…m`) is the snap-aware FK (`lstm_mlp_branch`) trained exactly as `ctrkin reproduce` trains it
(ctrkin.evaluation.training_runs.plan_runs at `--scale`: the same split, seed, batch, learning rate
and cosine schedule, one torch thread) through ctrkin.training.train, with only the input buffer
and, for an arm `ibNeE`, the epoch budget changed. Each arm's model folder is `--out/<arm>`: a
rerun reuses (or resumes) it. An arm `ibN…p` adds the play-lag inputs (TrainConfig.play_lags,
ctrkin.models.play_lags), `ibN…t` learns the residual of the calibrated TCM (TrainConfig.tcm_prior,
ctrkin.models.tcm_prior), `…r` learns in the tracker frame instead of the outer tube's (TrainConfig.
target_frame), `…m` is the paper's LSTM-MLP (no branch heads, no fold gate) with the same inputs, angle
encoding, linear output and recipe, in the tracker frame, `…g` fits the fold gate's scale of the
folds (TrainConfig.fold_scale), `…o` writes branch 1's head as branch 0's plus an offset head (option
`heads=offset`, ctrkin.families.snap_aware.net), and `…sK` trains with seed K. The test
columns are reported, never used to choose.

Columns: epochs run and the best one, position RMSE vs the virtual robot's true pose on the training
/ validation / test rows (mm; the model's own metrics.json, whose training decodes the branch with
the learned gate), test RMSE vs the measurement, validation and test RMSE as `Kinematics.predict`
gives them (`val p.`, `test p.`: the fold gate, what a user gets; the arm to adopt is the lowest
`val p.`), the RMS error of the validation rows' snap jumps (`jump`: the position change over
the ±2 steps around each recorded snap, predicted against true; what val p. is for the position,
this is for the snaps), what a wrong branch state costs where one branch exists (`wrong s`: the
median distance between the two branches' positions on the validation rows with |φ| > 120°),
training seconds, the median streaming step (Kinematics.step, one thread, µs, along a
held-out sequence), and the load average while the arm trained. With `--repro` (a reproduction
folder: its data/paper is the training data) also the reproduction's FK experiments on each arm's
model, as `ctrkin reproduce` and benchmarks/bench_generalisation.py score them against the truth:
snap precision / recall within ±2 steps on the held-out sweeps and on the snap turns (the worse of
the two rotation directions, ctrkin.evaluation.snapping; for each true snap, its offset to the
nearest predicted one, the tip's position change over its step and its distance from the
tracker's z axis: T(L) of a tip near the axis turns fast without a jump; and at each snap the
simulator flagged, the predicted and true position changes over its step ± 2 steps and the true
T(L) turn: a jump along the radius turns T(L) little), and the position RMSE
along mid-turn
reversals recorded on the same virtual robot (bench_generalisation.reversals) and along its small
back-and-forth moves (bench_generalisation.small_moves). Ends with one JSON
line of the figures.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ctrkin.data.dataset import Dataset
from ctrkin.evaluation.datasets import registered_truth
from ctrkin.evaluation.scales import get_scale
from ctrkin.evaluation.snapping import (
    azimuth_series,
    glitch_window,
    rotation_direction,
    snap_event_rows,
    snap_report,
)
from ctrkin.evaluation.table import FK_BRANCH
from ctrkin.evaluation.training_runs import plan_runs
from ctrkin.families.snap_aware.labels import phase_deg, snap_events
from ctrkin.inference import Kinematics
from ctrkin.training.config import TrainConfig
from ctrkin.training.data import data_signature, split_rows, split_signature
from ctrkin.training.engine import setup_differences, train

sys.path.insert(0, str(Path(__file__).resolve().parent))   # the benchmark beside this one
from bench_generalisation import ROBOTS, Case, reversals, small_moves

# ib8: IB 8 at the scale's epochs; ib2e160: 160 epochs; ib2p: IB 2 with the play-lag inputs;
# ib2pq: and equivariant inputs with a position field; ib2pt: the residual of the calibrated TCM
# (TrainConfig.tcm_prior); ib2ptr: in the tracker frame (the family's default is the outer tube's);
# ib2ptm: the paper's LSTM-MLP (lstm_mlp: no branch heads, no fold gate) in the tracker frame with the
# same inputs, encoding, output and recipe; ib2pg: the fold gate with its folds' scale g
# (TrainConfig.fold_scale; the recommended FK's since 2026-12-07 too: an arm without g keeps g = 1);
# ib2pto: the offset head form (a shared head plus a branch offset);
# ib2pf: the tracker's position field learned with the network (TrainConfig.joint_field; the
# recommended FK's since 2026-12-07: an arm without f has none);
# ib2ps1: training seed 1
ARM = re.compile(r"^ib(\d+)(?:e(\d+))?(p?)(q?)(t?)(r?)(m?)(g?)(o?)(f?)(?:s(\d+))?$")


def arm_config(scale: str, arm: str) -> TrainConfig:
    """The reproduction's snap-aware FK configuration at `scale` with the arm's IB (and epochs, and
    the play-lag inputs)."""
    m = ARM.match(arm)
    if m is None:
        raise ValueError(f"arm {arm!r} is not ibN[eE][p][q][t][r][m][g][o][f][sK] (e.g. ib8, ib2p, ib2ptr)")
    base = next(r.config for r in plan_runs(get_scale(scale)) if r.name == FK_BRANCH)
    cfg = replace(base, ib=int(m.group(1)), threads=1, device="cpu", play_lags=m.group(3) == "p",
                  joint_field=m.group(10) == "f", fold_scale=bool(m.group(8)))
    if m.group(4):
        cfg = replace(cfg, equivariant=True)
    if m.group(5):
        cfg = replace(cfg, tcm_prior=True)
    if m.group(6):
        cfg = replace(cfg, target_frame="tracker")
    if m.group(7):
        cfg = replace(cfg, model="lstm_mlp", options={"structure": cfg.options["structure"]},
                      target_frame="tracker")
    if m.group(9):
        cfg = replace(cfg, options={**cfg.options, "heads": "offset"})
    if m.group(11) is not None:
        cfg = replace(cfg, seed=int(m.group(11)))
    if m.group(2) is not None:
        epochs = int(m.group(2))
        cfg = replace(cfg, max_epochs=epochs, patience=max(cfg.patience, epochs))
    return cfg


def step_cost_us(kin: Kinematics, joints: np.ndarray, repeats: int = 3) -> float:
    """Median µs of Kinematics.step over `joints` (T, 2N), streamed `repeats` times from a reset."""
    torch.set_num_threads(1)
    times: list[float] = []
    clock = time.perf_counter_ns
    for _ in range(repeats):
        kin.reset()
        for q in joints:
            t0 = clock()
            kin.step(q)
            times.append((clock() - t0) / 1e3)
    return float(np.median(times[len(joints):]))      # the first pass warms the compiled step


def predicted_rmse(kin: Kinematics, ds: Dataset) -> dict[str, float]:
    """Position RMSE vs truth (mm) on the validation and test rows as `Kinematics.predict` gives them
    (the fold gate where the folder has one: what a user gets), beside the model's own metrics
    (its training's figures decode the branch with the learned gate)."""
    pred, truth = np.asarray(kin.predict(ds)), registered_truth(ds)
    err = np.linalg.norm(pred[:, :3] - truth[:, :3], axis=1)
    sp = ds.get_split()
    out: dict[str, Any] = {f"{part}_predict": float(np.sqrt(np.mean(err[getattr(sp, part)] ** 2)))
                           for part in ("val", "test")}
    jumps = snap_jump_errors(pred, truth, ds, sp.val)
    out["val_jump_mm"] = float(np.sqrt(np.mean(jumps ** 2))) if len(jumps) else None
    out["val_jumps"] = len(jumps)
    return out


JUMP_REACH = 2          # steps each side of a snap: the ±2-step tolerance of the snap scores


def snap_jump_errors(pred: np.ndarray, truth: np.ndarray, ds: Dataset, rows: np.ndarray) -> np.ndarray:
    """At each snap of the sequences holding `rows` (the dataset's snap flags, labels.snap_events):
    |Δp_pred − Δp_true| (mm), Δp the position change from JUMP_REACH + 1 rows before the snap's
    first row to JUMP_REACH rows after it. A snap predicted in time (within JUMP_REACH steps) and of
    the right size scores the ordinary motion's error over those steps; a late, early, short or
    missing one the jump's error. The validation rows' snaps judge the snaps as val p. judges the
    position (the sweeps and snap turns are test experiments)."""
    snap = ds.frame["snap"].to_numpy()
    chosen = np.zeros(len(snap), dtype=bool)
    chosen[rows] = True
    errs = []
    for a, b in ds.sequence_bounds():
        if not chosen[a]:
            continue
        for t in snap_events(snap, a, b):
            lo, hi = t - 1 - JUMP_REACH, t + JUMP_REACH
            if lo >= a and hi < b:
                errs.append(np.linalg.norm((pred[hi, :3] - pred[lo, :3]) - (truth[hi, :3] - truth[lo, :3])))
    return np.array(errs)


OUTSIDE_BAND_DEG = 120.0   # |φ| beyond the bistable band (labels.BAND_DEG = 90° and a margin): one branch


def wrong_state_cost(kin: Kinematics, ds: Dataset) -> float | None:
    """Median distance (mm) between the two branches' positions on the validation rows well outside
    the bistable band (|φ| > OUTSIDE_BAND_DEG), where one branch alone exists: what a wrong branch
    state (a gate set wrongly, a sequence started in the other state) costs there. None for a model
    without a branch state."""
    if "branch_states" not in kin.predictor.accepts.get("predict", frozenset()):
        return None
    n = len(ds.frame)
    p0, p1 = (np.asarray(kin.predict(ds, branch_states=np.full(n, s)))[:, :3] for s in (0.0, 1.0))
    q = ds.joints()
    val = ds.get_split().val
    far = val[np.abs(phase_deg(q[val, 0] - q[val, ds.n_tubes - 1])) > OUTSIDE_BAND_DEG]
    return float(np.median(np.linalg.norm(p1[far] - p0[far], axis=1))) if len(far) else None


EVENT_REACH = 20        # steps: a true snap's nearest predicted one further away counts as none


def event_offsets(pred: np.ndarray, true: np.ndarray, bounds: list[tuple[int, int]]) -> list[int | None]:
    """For each true snap event (rows `true`), the signed steps to the nearest predicted one in the
    same sequence (negative: predicted early), None where none is within EVENT_REACH."""
    seq = np.searchsorted([a for a, _ in bounds], np.r_[pred, true], side="right")
    ps, ts = seq[:len(pred)], seq[len(pred):]
    out: list[int | None] = []
    for e, s in zip(true, ts, strict=True):
        near = pred[(ps == s) & (np.abs(pred - e) <= EVENT_REACH)]
        out.append(None if len(near) == 0 else int(near[np.argmin(np.abs(near - e))] - e))
    return out


def snap_scores(kin: Kinematics, ds: Dataset) -> dict[str, Any]:
    """Snap precision / recall of the model's T(L) against the truth's along ds, the worse of the two
    directions (as ctrkin.evaluation.experiments_fk scores the sweeps and snap turns), the number of
    true snap events, and each true event's offset to the nearest predicted one (event_offsets)."""
    b, joints, n = ds.sequence_bounds(), ds.joints(), ds.n_tubes
    pred, truth = np.asarray(kin.predict(ds), float), registered_truth(ds)
    az_pred = azimuth_series(pred, joints, n, b)
    az_true = azimuth_series(truth, joints, n, b)
    keep = ~glitch_window(ds.frame["outlier"].to_numpy(), b)
    rep = snap_report(az_pred, az_true, b, rotation_direction(joints, n, b), keep)

    def worst(key: str, pick: Any) -> float | None:          # a direction without a snap does not count
        vals = [rep[d][key] for d in ("forward", "backward") if not math.isnan(rep[d][key])]
        return pick(vals) if vals else None

    true_events = snap_event_rows(az_true, b)
    true_events = true_events[keep[true_events]]
    offsets = event_offsets(snap_event_rows(az_pred, b), true_events, b)
    last = len(truth) - 1

    def jump(p: np.ndarray, t: int, reach: int = 0) -> float:  # position change over step t ± reach (mm)
        return float(np.linalg.norm(p[min(t + 1 + reach, last), :3] - p[max(t - 1 - reach, 0), :3]))

    # what each true event is: a jump of the tip, or T(L) turning fast as the tip passes near the axis;
    # and at each snap the simulator flagged (a fold crossed): the predicted and true position changes
    # over its step ± JUMP_REACH (a jump in time counts), and how far the true T(L) turned over the step
    # (a jump along the radius turns it little, and the 10° rule does not see it)
    flagged = np.concatenate([snap_events(ds.frame["snap"].to_numpy(), a, c) for a, c in b]) if b else []
    return {"precision": worst("precision", min), "recall": worst("recall", min),
            "magnitude_deg": worst("magnitude_error_deg", max), "snaps": int(rep["n_reference"]),
            "offsets": offsets, "event_jumps_mm": [jump(truth, t) for t in true_events],
            "event_radii_mm": [float(np.hypot(*truth[t, :2])) for t in true_events],
            "flagged_pred_jumps_mm": [jump(pred, t, JUMP_REACH) for t in flagged],
            "flagged_true_jumps_mm": [jump(truth, t, JUMP_REACH) for t in flagged],
            "flagged_true_turn_deg": [float(abs(az_true[min(t + 1, last)] - az_true[t - 1]))
                                      for t in flagged]}


def experiments(kin: Kinematics, folder: Path, repro: Path, case: str | Case) -> dict[str, Any]:
    """The FK experiments of the module docstring on the model in `folder`; case: the robot the
    reversals and small moves are recorded on (a ROBOTS name, or the robot --collect recorded)."""
    out: dict[str, Any] = {}
    for name in ("sweeps", "snap-turns"):
        out[name] = snap_scores(kin, Dataset.load(repro / "data" / name))
    c = ROBOTS[case] if isinstance(case, str) else case
    out["reversals"] = reversals(kin.robot, c, folder)
    out["small"] = small_moves(kin.robot, c, folder)
    return out


def finished(ds: Dataset, cfg: TrainConfig, folder: Path) -> bool:
    """Whether `folder` holds a finished model of `cfg` on this data and split (then an arm reads its
    metrics instead of resuming it: a resume re-tabulates the fold gate and re-evaluates)."""
    if not (folder / "metrics.json").is_file():
        return False
    saved = json.loads((folder / "config.json").read_text())
    _, rows = split_rows(ds, cfg)
    return not setup_differences(saved["train"], saved["data"].get("signature"),
                                 saved["data"].get("split_signature"), cfg, data_signature(ds),
                                 split_signature(rows), ignore=("threads", "device"))


def run_arm(ds: Dataset, scale: str, arm: str, out: Path, stream: np.ndarray, repro: Path | None = None,
            case: str | Case = "default-top") -> dict[str, Any]:
    cfg = arm_config(scale, arm)
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    reused = finished(ds, cfg, out / arm)
    if not reused:
        train(ds, cfg, out / arm, progress=False, log=None)
    wall = time.perf_counter() - t0
    kin = Kinematics.load(out / arm)
    m = kin.metrics
    row: dict[str, Any] = {"ib": cfg.ib, "max_epochs": m["training"]["max_epochs"],
                           "epochs": m["training"]["epochs"], "best_epoch": m["training"]["best_epoch"],
                           "verdict": m["training"]["fit"]["verdict"],
                           "train_seconds": m["training"]["seconds"], "wall_seconds": wall, "reused": reused,
                           "load": (load0 + os.getloadavg()[0]) / 2}
    for part in ("train", "val", "test"):
        row[part] = m[part]["vs_true"]["position_mm_rmse"]
        row[f"{part}_measured"] = m[part]["vs_measured"]["position_mm_rmse"]
    row |= predicted_rmse(kin, ds)
    row["wrong_state_mm"] = wrong_state_cost(kin, ds)
    row["step_us"] = step_cost_us(kin, stream)
    if repro is not None:
        row |= experiments(kin, out / arm, repro, case)
    return row


def collect_repro(folder: Path, scale: str, settings: list[str]) -> tuple[Path, Case]:
    """`folder` holding a reproduction's data (data/paper with its split, data/paper+excitation, the
    sweeps and snap turns), recorded as `ctrkin reproduce --scale S --set ...` records them, and that
    robot as a Case (the reversals and small moves are recorded on it too)."""
    from ctrkin.cli.from_config import virtual_config
    from ctrkin.evaluation.datasets import collect_training_data
    from ctrkin.robots import paper_robot

    virtual = virtual_config(settings)
    collect_training_data(paper_robot(), get_scale(scale), folder / "data", 0, virtual, progress=False)
    return folder, Case("paper", 0, asdict(virtual), f"the paper robot, --set {' '.join(settings)}")


def _offsets(offsets: list[int | None]) -> str:
    return ", ".join("–" if o is None else f"{o:+d}" for o in offsets) or "–"


def _mms(values: list[float]) -> str:
    return ", ".join(f"{v:.1f}" for v in values) or "–"


def _f(x: float | None) -> str:
    return "–" if x is None else f"{x:.2f}"


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=None, help="a reproduction's paper dataset folder "
                    "(its split.json is the split), e.g. out/reproduce/data/paper (default: --repro's "
                    "data/paper+excitation, what reproduce trains the recommended FK on, or its data/paper)")
    ap.add_argument("--repro", type=Path, default=None, help="a reproduction folder: its paper data, and "
                    "the FK experiments on its sweeps and snap turns and along reversals")
    ap.add_argument("--collect", type=Path, default=None, help="record the reproduction's data at --scale "
                    "on the paper robot (hardware seed 0, the virtual robot's defaults with --set) into "
                    "COLLECT/data, as `ctrkin reproduce` does (reused when there), and use it as --repro")
    ap.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE",
                    help="a virtual robot effect for --collect (VirtualConfig's fields, as `ctrkin collect`)")
    ap.add_argument("--case", default="default-top", choices=sorted(ROBOTS), help="the robot and effects "
                    "of --repro (bench_generalisation.ROBOTS), for the reversals and small moves (with "
                    "--collect: the robot it records, --set included)")
    ap.add_argument("--out", type=Path, required=True, help="folder of the arms' model folders")
    ap.add_argument("--arms", default="ib2,ib4,ib8", help="comma-separated arms "
                    "ibN[eE][p][q][t][r][m][g][o][f][sK] (the module comment above ARM), e.g. "
                    "ib2p,ib2pt,ib2ptr")
    ap.add_argument("--scale", default="quick", help="the reproduction scale whose recipe the arms use")
    args = ap.parse_args(argv)
    arms = [a.strip() for a in args.arms.split(",") if a.strip()]
    bad = [a for a in arms if ARM.match(a) is None]
    if bad:
        ap.error(f"arms {bad} are not ibN[eE][p][q][t][r][m][g][o][f][sK] (e.g. ib8, ib2e160, ib2p, ib2ptr)")
    case: str | Case = args.case
    if args.collect is not None:
        args.repro, case = collect_repro(args.collect, args.scale, args.settings)
    if args.data is None and args.repro is None:
        ap.error("give --data or --repro")
    training = args.repro / "data" / "paper+excitation" if args.repro is not None else None
    data = (args.data if args.data is not None else         # what reproduce trains the recommended FK on
            training if training is not None and training.is_dir() else args.repro / "data" / "paper")
    ds = Dataset.load(data)
    if ds.split is None or not ds.has_truth:
        ap.error(f"{data} needs a split.json and true pose columns (a virtual robot's reproduction "
                 "data)")
    test_seq = ds.frame["sequence_id"].to_numpy()[ds.get_split().test]
    first = ds.frame["sequence_id"].to_numpy() == test_seq[0]
    stream = ds.joints()[first][:2000]
    print(f"snap-aware FK memory on {data} ({len(ds.frame)} rows), the {args.scale} reproduction's "
          f"recipe; streaming step timed along {len(stream)} held-out steps", flush=True)
    print(f"{'arm':9s} {'epochs':>6s} {'best':>5s} {'train':>6s} {'val':>6s} {'test':>6s} {'test m.':>7s} "
          f"{'val p.':>6s} {'test p.':>7s} {'jump':>5s} {'wrong s':>7s} {'s':>6s} {'step µs':>7s} "
          f"{'load':>5s}   "
          "(position RMSE vs truth, mm; p.: as predict gives them; jump: RMS error of the validation "
          "snaps' jumps, mm; wrong s: what a wrong state costs outside the band, mm)", flush=True)
    rows: dict[str, Any] = {}
    for arm in arms:
        r = rows[arm] = run_arm(ds, args.scale, arm, args.out, stream, args.repro, case)
        print(f"{arm:9s} {r['epochs']:6d} {r['best_epoch']:5d} {r['train']:6.3f} {r['val']:6.3f} "
              f"{r['test']:6.3f} {r['test_measured']:7.3f} {r['val_predict']:6.3f} {r['test_predict']:7.3f} "
              f"{_f(r['val_jump_mm']):>5s} {_f(r['wrong_state_mm']):>7s} {r['train_seconds']:6.0f} "
              f"{r['step_us']:7.1f} "
              f"{r['load']:5.1f}   {r['verdict']}", flush=True)
        if args.repro is not None:
            sw, tu, rv, sm = r["sweeps"], r["snap-turns"], r["reversals"], r["small"]
            print(f"{'':9s} sweeps P/R {_f(sw['precision'])}/{_f(sw['recall'])} ({sw['snaps']} snaps), "
                  f"snap turns P/R {_f(tu['precision'])}/{_f(tu['recall'])} ({tu['snaps']}), magnitude "
                  f"{_f(sw['magnitude_deg'])}/{_f(tu['magnitude_deg'])}°, reversals "
                  f"{rv['reversal_rmse_true_mm']:.2f} mm RMSE ({rv['reversal_max_true_mm']:.1f} max), small "
                  f"moves {sm['small_rmse_true_mm']:.2f} mm (outer {sm['small_outer_rmse_true_mm']:.2f}, "
                  f"inner {sm['small_inner_rmse_true_mm']:.2f}, d {sm['small_d_rmse_true_mm']:.2f}); "
                  f"true snaps predicted at (steps) / their jumps (mm) at (mm off the z axis): sweeps "
                  f"{_offsets(sw['offsets'])} / {_mms(sw['event_jumps_mm'])} at "
                  f"{_mms(sw['event_radii_mm'])}, turns {_offsets(tu['offsets'])} / "
                  f"{_mms(tu['event_jumps_mm'])} at {_mms(tu['event_radii_mm'])}; at the flagged snaps, "
                  f"predicted / true jumps (mm) and the true T(L) turn (°): sweeps "
                  f"{_mms(sw['flagged_pred_jumps_mm'])} / {_mms(sw['flagged_true_jumps_mm'])}, "
                  f"{_mms(sw['flagged_true_turn_deg'])}, turns {_mms(tu['flagged_pred_jumps_mm'])} / "
                  f"{_mms(tu['flagged_true_jumps_mm'])}, {_mms(tu['flagged_true_turn_deg'])}", flush=True)
    best = min(rows, key=lambda a: rows[a]["val_predict"])
    print(f"lowest validation RMSE as predict gives it: {best} ({rows[best]['val_predict']:.3f} mm)")
    report = {"data": str(data), "scale": args.scale, "arms": rows, "chosen_by_val": best}
    print(json.dumps(report, default=float))
    return report


if __name__ == "__main__":
    main()
