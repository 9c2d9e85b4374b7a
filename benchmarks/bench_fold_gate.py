"""Benchmark: the fold gate's assumption measured where it fails (issue 21, goal 2;
docs/learned_kinematics.md: What the learned models assume about the robot).

    python benchmarks/bench_fold_gate.py                                    # the old default robot
    python benchmarks/bench_fold_gate.py --set tube_friction=0.69 --set precurvature_error=0.2 ...
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
              misfit costs before any network.

Data: recorded here on the virtual robot (`--robot`, `--robot-seed`, `--set KEY=VALUE` as
`ctrkin reproduce`, with its protocols and seeds: the same data as its `paper` and `sweeps`), or
read from a reproduction's `data` folder (`--data`: its `paper`, with the saved split, and
`sweeps`). Prints a table and ends with one JSON line.
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
    """Residuals (deg) of ds's snaps at `rows` (default all) from the gate's θ±, and the snaps in
    the band where the nominal robot has no fold (module docstring)."""
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
            resid.append(mid - fold - (sign * gate.widen_deg - gate.outer_lag_deg * motion[t]))
    r = np.asarray(resid, float)
    return {"gate_snaps": int(len(r) + no_fold), "gate_no_fold_snaps": no_fold,
            "gate_residual_rms_deg": float(np.sqrt(np.mean(r ** 2))) if len(r) else None,
            "gate_residual_max_deg": float(np.abs(r).max()) if len(r) else None}


def gate_switches(gate: Any, ds: Dataset) -> dict[str, Any]:
    """The gate's branch-state switches along every sequence of ds against its recorded snaps
    (within ±2 steps, ctrkin.evaluation.snapping's matching): precision, recall, counts."""
    from ctrkin.evaluation.snapping import snap_score
    from ctrkin.families.snap_aware.labels import phase_deg
    from ctrkin.models.motion import recorded_motion, run_continues

    n, q = ds.n_tubes, ds.joints()
    bounds = ds.sequence_bounds()
    motion, runs = recorded_motion(ds.frame, q, bounds, n)
    states = gate.states(q[:, 0] - q[:, n - 1], q[:, n:], motion, bounds, run_continues(bounds, runs))
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


def measure(paper: Dataset, sweeps: Dataset) -> dict[str, Any]:
    """The gate built as training builds it on paper's training rows; its residuals and switches."""
    from ctrkin.families.snap_aware.recipe import fold_gate

    train = np.sort(paper.get_split().train)
    t0 = time.perf_counter()
    gate = fold_gate(paper, train)
    out: dict[str, Any] = {"widen_deg": gate.widen_deg, "outer_lag_deg": gate.outer_lag_deg,
                           "gate_seconds": time.perf_counter() - t0}
    out |= {f"train_{k}": v for k, v in snap_residuals(gate, paper, train).items()}
    out |= {f"sweeps_{k}": v for k, v in snap_residuals(gate, sweeps).items()}
    out |= {f"sweeps_{k}": v for k, v in gate_switches(gate, sweeps).items()}
    return out


def _record(args: argparse.Namespace) -> tuple[Dataset, Dataset]:
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
    paper_kw: dict[str, Any] = {**kw, "seed": SEEDS["paper"], **_paper_kw(scale, robot)}
    paper_plan = protocols.build("paper", robot, **paper_kw)
    paper = record(paper_plan, virtual, seed=SEEDS["paper"], workers=args.workers, progress=False)
    sweeps_plan = protocols.build("sweeps", robot, **kw, seed=SEEDS["sweeps"])
    sweeps = record(sweeps_plan, virtual, seed=SEEDS["sweeps"], workers=args.workers, progress=False)
    return paper, sweeps


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, help="a reproduction's data folder (paper/ and sweeps/) to read")
    ap.add_argument("--robot", default="paper", help="built-in robot or TOML file (when recording)")
    ap.add_argument("--robot-seed", type=int, default=0, help="the virtual hardware draw")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a virtual robot effect, as `ctrkin reproduce --set` (repeatable)")
    ap.add_argument("--scale", default="quick", choices=("tiny", "quick", "full"))
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    if args.data is not None:
        paper, sweeps = Dataset.load(args.data / "paper"), Dataset.load(args.data / "sweeps")
        source = str(args.data)
    else:
        paper, sweeps = _record(args)
        source = f"{args.robot} seed {args.robot_seed} {' '.join(args.set) or '(defaults)'} at {args.scale}"
    r = measure(paper, sweeps)
    print(f"fold gate on {source} (load {os.getloadavg()[0]:.1f}, {time.perf_counter() - t0:.0f} s)")
    print(f"  fitted c = {r['widen_deg']:.2f} deg, kappa = {r['outer_lag_deg']:.2f} deg")
    for where in ("train", "sweeps"):
        rms, mx = r[f"{where}_gate_residual_rms_deg"], r[f"{where}_gate_residual_max_deg"]
        print(f"  {where:6s} snaps {r[f'{where}_gate_snaps']:4d}, no nominal fold "
              f"{r[f'{where}_gate_no_fold_snaps']:3d}, residual RMS / max "
              f"{'–' if rms is None else f'{rms:.2f}'} / {'–' if mx is None else f'{mx:.2f}'} deg")
    print(f"  sweeps gate switches {r['sweeps_gate_switches']} vs recorded snaps "
          f"{r['sweeps_recorded_snaps']}: "
          f"P {r['sweeps_gate_precision']:.2f} / R {r['sweeps_gate_recall']:.2f} (±2 steps)")
    print(json.dumps({"source": source, **r}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
