"""Benchmark: the fold gate's assumption measured where it fails, beside a form identified from the
history (issue 21, goal 2; docs/learned_kinematics.md: What the learned models assume about the robot).

    python benchmarks/bench_fold_gate.py                                    # the default robot
    python benchmarks/bench_fold_gate.py --excite --robot-seed 2 --set tube_friction=0.69 ...
    python benchmarks/bench_fold_gate.py --data out/reproduce/data          # a reproduction's data

The snap-aware FK's fold gate (ctrkin.families.snap_aware.fold_gate) assumes the robot snaps where
the *nominal* TCM folds, shifted by two fitted numbers: θ± = φ±(β) ± c − κ·m_N. This benchmark builds
the gate exactly as training does (the nominal robot's fold table over the training translations,
c and κ fitted to the training snaps: `families.snap_aware.recipe.fold_gate`) on the paper protocol
at quick scale, without training a network (the gate does not depend on it), and reports

  residuals   each snap's phase (deg of α0, mid-way between the snap row and the one before) minus
              the form's θ±, RMS and largest, on the training snaps (in-sample: the form's misfit)
              and on the held-out sweeps' snaps;
  no fold     snaps at translations where the nominal robot has no fold (|φ±| < MIN_FOLD_DEG): the
              gate cannot switch there;
  gate P/R    the gate's switches (its branch state run along each sweep, as the model runs it)
              against the recorded snaps of the sweeps, matched within ±2 steps: what the form's
              misfit costs before any network; the same on the unseen snap turns.

Beside the fold gate, the play-operator form (ctrkin.families.snap_aware.play: play operators of
the motor angles and of the relative translation along each run, identified on the same training
snaps), and with --excite the same form identified also on training-only turns after slides of one
tube against the other (`excitation`). A history probe (when recording) turns the inner tube at the
largest sweep level after six unrecorded histories (`history_probe`): what moves the snaps.

Data: recorded here on the virtual robot (`--robot`, `--robot-seed`, `--set KEY=VALUE` as
`ctrkin reproduce`, with its protocols and seeds: the same data as its `paper`, `sweeps` and
`snap-turns`), or
read from a reproduction's `data` folder (`--data`: its `paper`, with the saved split, `sweeps` and
`snap-turns`; no probe, no excitation). Prints a table and ends with one JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.data.dataset import Dataset


def snap_residuals(gate: Any, ds: Dataset, rows: np.ndarray | None = None) -> dict[str, Any]:
    """Residuals (deg) of ds's snaps at `rows` (default all) from the gate's θ± (its slide memory
    included, mid-way as the fit takes it), and the snaps in the band where the nominal robot has no
    fold (module docstring)."""
    from ctrkin.families.snap_aware.fold_gate import slide_lags
    from ctrkin.families.snap_aware.labels import phase_deg, snap_events
    from ctrkin.models.motion import recorded_motion
    from ctrkin.models.relay import MIN_FOLD_DEG

    n, q, snap = ds.n_tubes, ds.joints(), ds.frame["snap"].to_numpy()
    keep = np.ones(len(q), bool) if rows is None else np.isin(np.arange(len(q)), rows)
    bounds = ds.sequence_bounds()
    motion, _ = recorded_motion(ds.frame, q, bounds, n)
    alpha0 = q[:, 0] - q[:, n - 1]
    phi = phase_deg(alpha0)
    fwd, bwd = gate.folds(q[:, n:])
    widen = gate.widen(slide_lags(ds, q, bounds, n) if gate.slides else None)   # c, less the slide memory
    if len(widen) == 1:
        widen = np.broadcast_to(widen, len(q))
    else:
        widen = 0.5 * (widen + np.r_[widen[:1], widen[:-1]])
    resid, no_fold = [], 0
    for a, b in bounds:
        for t in snap_events(snap, a, b):
            sign = int(np.sign(alpha0[t] - alpha0[t - 1]))
            if not keep[t] or sign == 0 or abs(phi[t]) >= gate.band_deg:
                continue
            fold = fwd[t] if sign > 0 else bwd[t]
            if abs(fold) < MIN_FOLD_DEG:
                no_fold += 1
                continue
            mid = phi[t] - 0.5 * (alpha0[t] - alpha0[t - 1])
            resid.append(mid - fold - (sign * widen[t] - gate.outer_lag_deg * motion[t]))
    r = np.asarray(resid, float)
    return {"gate_snaps": int(len(r) + no_fold), "gate_no_fold_snaps": no_fold,
            "gate_residual_rms_deg": float(np.sqrt(np.mean(r ** 2))) if len(r) else None,
            "gate_residual_max_deg": float(np.abs(r).max()) if len(r) else None}


def gate_switches(gate: Any, ds: Dataset, states: np.ndarray | None = None) -> dict[str, Any]:
    """The gate's branch-state switches along every sequence of ds (its own relay, or `states` (T,)
    of another form) against the recorded snaps (within ±2 steps, ctrkin.evaluation.snapping's
    matching): precision, recall, counts."""
    from ctrkin.evaluation.snapping import snap_score
    from ctrkin.families.snap_aware.fold_gate import slide_lags
    from ctrkin.families.snap_aware.labels import phase_deg
    from ctrkin.models.motion import recorded_motion, run_continues

    n, q = ds.n_tubes, ds.joints()
    bounds = ds.sequence_bounds()
    if states is None:
        motion, runs = recorded_motion(ds.frame, q, bounds, n)
        ell = slide_lags(ds, q, bounds, n) if gate.slides else None
        states = gate.states(q[:, 0] - q[:, n - 1], q[:, n:], motion, bounds, run_continues(bounds, runs),
                             ell)
    # a switch or a recorded snap as a 20° step of a pseudo-azimuth, which snap_score counts as an event
    # only inside the bistable band: outside it the state follows the sign of φ (one branch), and
    # its flip where α0 passes 0° (φ = ±180°) is no snap
    in_band = np.abs(phase_deg(q[:, 0] - q[:, n - 1])) < gate.band_deg
    switch = np.zeros(len(q))
    snap = ds.frame["snap"].to_numpy().astype(float)
    for a, b in bounds:
        switch[a + 1:b] = np.abs(np.diff(states[a:b])) * in_band[a + 1:b]
        snap[a] = 0.0
    score = snap_score(20.0 * np.cumsum(switch), 20.0 * np.cumsum(snap), bounds).to_dict()
    return {"gate_precision": score["precision"], "gate_recall": score["recall"],
            "gate_switches": int(score["n_predicted"]), "recorded_snaps": int(score["n_reference"])}


def play_form(gate: Any, paper: Dataset, train: np.ndarray, held: dict[str, Dataset],
              extra: Dataset | None = None, tag: str = "pi") -> dict[str, Any]:
    """The play-operator form (ctrkin.families.snap_aware.play) identified on the training snaps (and
    those of `extra`, training-only excitation runs) and scored like the gate on each held-out
    dataset: its parameters, residuals, switches, and the largest slide of one tube against the
    other before the snaps (what excites its slide term); keys `tag`_… and …_`tag`_…."""
    from ctrkin.families.snap_aware import play

    rows = play.snap_rows(gate, paper, train)
    if extra is not None:
        more = play.snap_rows(gate, extra)
        rows = play.SnapRows(*(np.r_[getattr(rows, k), getattr(more, k)] for k in ("sign", "fold", "phase")),
                             play.Lags(*(np.vstack([getattr(rows.lags, k), getattr(more.lags, k)])
                                         for k in ("inner", "outer", "slide"))),
                             np.r_[rows.run, more.run + rows.run.max(initial=0) + 1])
    ident = play.identify(rows)
    out: dict[str, Any] = {"widen_deg": ident.widen_deg, "fold_scale": ident.fold_scale,
                           "inner_weights": ident.inner.round(3).tolist(),
                           "outer_weights": ident.outer.round(3).tolist(),
                           "slide_weights": ident.slide.round(3).tolist(), "ridge": ident.ridge,
                           "cv_runs": len(np.unique(rows.run)),
                           "cv_rms_deg": None if np.isnan(ident.cv_rms_deg) else ident.cv_rms_deg}
    out = {f"{tag}_{k}": v for k, v in out.items()}
    for where, ds, sel in (("train", paper, train), *((k, d, None) for k, d in held.items())):
        r = rows if sel is not None else play.snap_rows(gate, ds)
        A, b = r.design()
        e = A @ ident.x - b
        out[f"{where}_{tag}_residual_rms_deg"] = float(np.sqrt(np.mean(e ** 2))) if len(e) else None
        out[f"{where}_{tag}_residual_max_deg"] = float(np.abs(e).max()) if len(e) else None
        # the slide before each snap, up to the widest play's width (its lag in mm)
        slid = np.abs(r.lags.slide[:, -1]) * play.SLIDE_WIDTHS_MM[-1]
        out[f"{where}_{tag}_slide_lag_max_mm"] = float(slid.max()) if len(e) else None
        if sel is None:
            sc = gate_switches(gate, ds, play.play_states(gate, ident, ds))
            out |= {f"{where}_{tag}_{k}": v for k, v in sc.items()}
    return out


def measure(paper: Dataset, sweeps: Dataset, turns: Dataset | None = None,
            extra: Dataset | None = None) -> dict[str, Any]:
    """The gate built as training builds it on paper's training rows, its residuals and switches
    on the held-out sweeps (and the unseen turns, where given); beside it the play-operator form
    (identified on the training snaps and those of `extra`, where given: `excitation`)."""
    from ctrkin.families.snap_aware.recipe import fold_gate

    train = np.sort(paper.get_split().train)
    t0 = time.perf_counter()
    gate = fold_gate(paper, train)
    out: dict[str, Any] = {"widen_deg": gate.widen_deg, "outer_lag_deg": gate.outer_lag_deg,
                           "gate_seconds": time.perf_counter() - t0}
    held = {"sweeps": sweeps} | ({} if turns is None else {"turns": turns})
    out |= {f"train_{k}": v for k, v in snap_residuals(gate, paper, train).items()}
    for where, ds in held.items():
        out |= {f"{where}_{k}": v for k, v in snap_residuals(gate, ds).items()}
        out |= {f"{where}_{k}": v for k, v in gate_switches(gate, ds).items()}
    out |= play_form(gate, paper, train, held)
    if extra is None:
        return out
    return out | play_form(gate, paper, train, held, extra, "pix") | choose_on_validation(paper, extra, held)


def split_runs(ds: Dataset) -> tuple[Dataset, Dataset]:
    """`ds` (one sequence per run, as the excitation protocol records) in two by run: the even runs
    (identification) and the odd ones (validation)."""
    runs = ds.frame["run"].to_numpy()
    ids = np.unique(runs)
    pick = np.isin(runs, ids[::2])
    return (Dataset(ds.frame[pick].reset_index(drop=True), ds.robot, dict(ds.meta)),
            Dataset(ds.frame[~pick].reset_index(drop=True), ds.robot, dict(ds.meta)))


def choose_on_validation(paper: Dataset, extra: Dataset, held: dict[str, Dataset]) -> dict[str, Any]:
    """The fold-gate form against the play-operator form, both identified as the reproduction now
    trains (the paper protocol's training rows + excitation runs: half the runs here) and judged on
    the other half of the excitation runs (`val`: snaps after slides and mid-turn reversals that no
    held-out experiment repeats): residuals and switches P/R per form on `val` and on each of `held`
    (reported, not used to choose); beside them the fold gate of the paper's training rows alone, and
    the fold gate with the folds' scale g also fitted (`fold_scale`: θ± = g·φ± ± c − κ·m_N).
    Keys `xv_`… (fold gate), …`_pxv_`… (play), …`_pv_`… (fold gate, paper rows), …`_sxv_`… (scaled
    folds)."""
    from ctrkin.evaluation.datasets import with_training_runs
    from ctrkin.families.snap_aware.recipe import fold_gate

    ident, val = split_runs(extra)
    paper.get_split()
    both = with_training_runs(paper, ident)
    train = np.sort(both.get_split().train)
    gate = fold_gate(both, train)
    scaled = fold_gate(both, train, fold_scale=True)
    out: dict[str, Any] = {"xv_widen_deg": gate.widen_deg, "xv_outer_lag_deg": gate.outer_lag_deg,
                           "sxv_widen_deg": scaled.widen_deg, "sxv_outer_lag_deg": scaled.outer_lag_deg,
                           "sxv_fold_scale": scaled.fold_scale,
                           "xv_val_runs": int(val.frame["run"].nunique()),
                           "xv_id_runs": int(ident.frame["run"].nunique())}
    sets = {"val": val, **held}
    paper_gate = fold_gate(paper, np.sort(paper.get_split().train))
    for where, ds in sets.items():
        for tag, g in (("xv", gate), ("pv", paper_gate), ("sxv", scaled)):
            out |= {f"{where}_{tag}_{k}": v for k, v in snap_residuals(g, ds).items()}
            out |= {f"{where}_{tag}_{k}": v for k, v in gate_switches(g, ds).items()}
    out |= play_form(gate, both, train, sets, tag="pxv")
    f1 = {form: _f1(out[f"val_{p}gate_precision"], out[f"val_{p}gate_recall"])
          for form, p in (("fold gate", "xv_"), ("play", "pxv_"), ("fold gate (paper rows)", "pv_"),
                          ("scaled folds", "sxv_"))}
    out["xv_chosen"] = max(f1, key=lambda k: (f1[k], k == "fold gate"))   # a tie keeps the fold gate
    out["xv_val_f1"] = f1
    return out


def _f1(precision: float, recall: float) -> float:
    return 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)


HISTORIES = ("rest", "both tubes translated 4 mm", "inner slid 0.2 mm (d - 0.2 -> d)",
             "inner slid 4 mm (d - 4 -> d)", "outer slid 4 mm (d - 4 -> d)", "a turn at d - 4, then slid")


def excitation(robot: Any, virtual: Any, workers: int, scale: str) -> Dataset:
    """Training-only runs that excite the slide term (--excite): the library's excitation protocol
    (ctrkin.acquisition.excitation: short runs from rest, slides of one tube against the other before
    turns, mid-turn reversals at random angles) at the scale's size, with the reproduction's seed."""
    from ctrkin.acquisition import protocols
    from ctrkin.acquisition.recorder import record
    from ctrkin.evaluation.datasets import SEEDS

    plan = protocols.build("excitation", robot, scale=scale, seed=SEEDS["excitation"])
    return record(plan, virtual, seed=SEEDS["excitation"], workers=workers, progress=False)


def history_probe(robot: Any, virtual: Any, workers: int) -> dict[str, list[float]]:
    """The same inner turn (0 -> 360 -> 0°, outer at rest at α 0, βN 0, at the largest sweep level
    d) after each unrecorded history of HISTORIES, each its own run from rest: the α0 (deg) of its
    snaps. What a form must express that the training rows never show."""
    from ctrkin.acquisition.plan import Plan, Run, Segment, transition
    from ctrkin.acquisition.protocols import PAPER_FULL_LEVELS_MM, config, inner_turn
    from ctrkin.acquisition.ranges import ProtocolRanges
    from ctrkin.acquisition.recorder import record
    from ctrkin.families.snap_aware.labels import snap_events

    n = robot.n_tubes
    d = ProtocolRanges.of(robot).d(PAPER_FULL_LEVELS_MM[-1])
    turn = inner_turn(n, 0.0, 0.0, d)

    def after(q0: np.ndarray, *first: Segment) -> Run:
        hold = Segment(np.repeat(q0[None], 3, axis=0), record=False)
        to_turn = transition(first[-1].q[-1] if first else q0, turn[0], n)
        return Run((hold, *first, to_turn, Segment(turn, level=0)))

    runs = (Run((Segment(turn, level=0),)), after(config(n, 0.0, 0.0, -4.0, d)),
            after(config(n, 0.0, 0.0, 0.0, d - 0.2)), after(config(n, 0.0, 0.0, 0.0, d - 4.0)),
            after(config(n, 0.0, 0.0, -4.0, d - 4.0)),
            after(config(n, 0.0, 0.0, 0.0, d - 4.0), Segment(inner_turn(n, 0.0, 0.0, d - 4.0), record=False)))
    plan = Plan("history-probe", runs, ({"relative_translation_mm": d},), {"d_mm": d})
    ds = record(plan, virtual, seed=0, workers=workers, progress=False)
    q, snap = ds.joints(), ds.frame["snap"].to_numpy()
    out = {}
    for name, (a, b) in zip(HISTORIES, ds.sequence_bounds(), strict=True):
        out[name] = [round(float(q[t, 0] - q[t, n - 1]), 1) for t in snap_events(snap, a, b)]
    return out


def _record(args: argparse.Namespace
            ) -> tuple[Dataset, Dataset, Dataset, dict[str, list[float]], Dataset | None]:
    from ctrkin.acquisition import protocols
    from ctrkin.acquisition.recorder import record
    from ctrkin.cli.from_config import virtual_config
    from ctrkin.evaluation.datasets import SEEDS, _paper_kw
    from ctrkin.evaluation.scales import get_scale
    from ctrkin.robots import load_robot
    from ctrkin.virtual import VirtualRobot

    robot = load_robot(args.robot)
    virtual = VirtualRobot(robot, virtual_config(tuple(args.set)), seed=args.robot_seed)
    scale = get_scale(args.scale)
    kw: dict[str, Any] = {"scale": scale.protocol_scale}
    got = {}
    for name, extra in (("paper", _paper_kw(scale, robot)), ("sweeps", {}), ("snap-turns", {})):
        plan = protocols.build(name, robot, **kw, **extra, seed=SEEDS[name])
        got[name] = record(plan, virtual, seed=SEEDS[name], workers=args.workers, progress=False)
    extra = excitation(robot, virtual, args.workers, scale.protocol_scale) if args.excite else None
    return got["paper"], got["sweeps"], got["snap-turns"], history_probe(robot, virtual, args.workers), extra


def _fmt(v: Any, spec: str = ".2f") -> str:
    return "–" if v is None else format(v, spec)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, help="a reproduction's data folder (paper/, sweeps/ and, where "
                    "there, snap-turns/) to read; no history probe then")
    ap.add_argument("--robot", default="paper", help="built-in robot or TOML file (when recording)")
    ap.add_argument("--robot-seed", type=int, default=0, help="the virtual hardware draw")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a virtual robot effect, as `ctrkin reproduce --set` (repeatable)")
    ap.add_argument("--scale", default="quick", choices=("tiny", "quick", "full"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--excite", action="store_true", help="also record the training-only excitation "
                    "protocol (ctrkin.acquisition.excitation), identify the play form on it too, and choose "
                    "between the fold-gate and the play forms on held-out excitation runs (with --data: "
                    "its excitation/ folder, where there)")
    args = ap.parse_args(argv)
    extra = None
    t0 = time.perf_counter()
    probe: dict[str, list[float]] = {}
    if args.data is not None:
        paper, sweeps = Dataset.load(args.data / "paper"), Dataset.load(args.data / "sweeps")
        turns = Dataset.load(args.data / "snap-turns") if (args.data / "snap-turns").is_dir() else None
        if (args.data / "excitation").is_dir():
            extra = Dataset.load(args.data / "excitation")
        source = str(args.data)
    else:
        paper, sweeps, turns, probe, extra = _record(args)
        source = f"{args.robot} seed {args.robot_seed} {' '.join(args.set) or '(defaults)'} at {args.scale}"
    r = measure(paper, sweeps, turns, extra)
    if extra is not None:
        source += " (play form also on the excitation runs)"
    print(f"fold gate on {source} (load {os.getloadavg()[0]:.1f}, {time.perf_counter() - t0:.0f} s)")
    print(f"  old form θ± = φ± ± c − κ·m_N: c = {r['widen_deg']:.2f} deg, "
          f"kappa = {r['outer_lag_deg']:.2f} deg")
    forms = {"old": "", "play": "pi_"} | ({"play+excite": "pix_"} if "pix_widen_deg" in r else {})
    for name, p in list(forms.items())[1:]:
        print(f"  {name} form θ± = g·φ± ± c + Σw·L(α1) − Σv·L(αN) ∓ Σu·L(d): "
              f"c = {r[p + 'widen_deg']:.2f} deg, "
              f"g = {r[p + 'fold_scale']:.3f}, w = {r[p + 'inner_weights']}, v = {r[p + 'outer_weights']}, "
              f"u = {r[p + 'slide_weights']} (deg when fully wound; ridge {r[p + 'ridge']:g}, "
              f"{r[p + 'cv_runs']} run(s) with snaps, leave-one-run-out RMS {_fmt(r[p + 'cv_rms_deg'])} deg)")
    print(f"  {'form':12s} {'snaps':>7s} {'no fold':>7s} {'residual RMS / max':>19s} "
          f"{'switches vs snaps: P / R':>25s} {'slid before (mm)':>16s}")
    for where in ("train", "sweeps", "turns"):
        if f"{where}_gate_snaps" not in r:
            continue
        for name, p in forms.items():
            g = "gate_" if not p else p
            res = f"{_fmt(r[f'{where}_{g}residual_rms_deg'])} / {_fmt(r[f'{where}_{g}residual_max_deg'])}"
            sw = "(in-sample)"
            if where != "train":
                sw = (f"{r[f'{where}_{p}gate_switches']} vs {r[f'{where}_{p}recorded_snaps']}: "
                      f"{r[f'{where}_{p}gate_precision']:.2f} / {r[f'{where}_{p}gate_recall']:.2f}")
            slid = _fmt(r.get(f"{where}_{p}slide_lag_max_mm"), ".2f") if p else ""
            counts = f"{r[f'{where}_gate_snaps']:3d} {r[f'{where}_gate_no_fold_snaps']:7d}"
            print(f"  {where + ' ' + name:18s} {counts} {res:>19s} {sw:>25s} {slid:>16s}")
    if "xv_chosen" in r:
        print(f"  chosen on validation: identified on the paper training rows + {r['xv_id_runs']} "
              f"excitation runs, judged on {r['xv_val_runs']} others (F1 of the switches within ±2 steps)")
        print(f"  fold gate: c = {r['xv_widen_deg']:.2f} deg, kappa = {r['xv_outer_lag_deg']:.2f} deg; "
              f"play: c = {r['pxv_widen_deg']:.2f} deg, g = {r['pxv_fold_scale']:.3f}, "
              f"u = {r['pxv_slide_weights']}; scaled folds: c = {r['sxv_widen_deg']:.2f} deg, "
              f"kappa = {r['sxv_outer_lag_deg']:.2f} deg, g = {r['sxv_fold_scale']:.3f}")
        for where in ("val", "sweeps", "turns"):
            if f"{where}_xv_gate_snaps" not in r:
                continue
            for name, g, p in (("fold gate", "xv_gate_", "xv_"), ("play", "pxv_", "pxv_"),
                               ("fold gate (paper rows)", "pv_gate_", "pv_"),
                               ("scaled folds", "sxv_gate_", "sxv_")):
                res = f"{_fmt(r[f'{where}_{g}residual_rms_deg'])} / {_fmt(r[f'{where}_{g}residual_max_deg'])}"
                sw = (f"{r[f'{where}_{p}gate_switches']} vs {r[f'{where}_{p}recorded_snaps']}: "
                      f"{r[f'{where}_{p}gate_precision']:.2f} / {r[f'{where}_{p}gate_recall']:.2f}")
                print(f"  {where + ' ' + name:32s} {r[f'{where}_xv_gate_snaps']:3d} "
                      f"{r[f'{where}_xv_gate_no_fold_snaps']:7d} {res:>19s} {sw:>25s}")
        print(f"  chosen: {r['xv_chosen']} (validation F1 {r['xv_val_f1']})")
    if probe:
        print("  history probe: the same inner turn at the largest sweep level after each unrecorded "
              "history, α0 of its snaps (deg)")
        for name, snaps in probe.items():
            print(f"    {name:36s} {snaps}")
    print(json.dumps({"source": source, **r, "history_probe": probe}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
