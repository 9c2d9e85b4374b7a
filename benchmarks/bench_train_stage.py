"""Where the wall time of a reproduction's "train models" stage goes (issue 26, goal 3): every run of
`plan_runs(scale)` trained as `train_all` trains it (the same jobs, `training_jobs`, the same local
executor, one torch thread per worker), each job wrapped to record its worker and the phases of
`_train_run`:

- load: `Dataset.load` and `with_fewer_sequences`;
- setup: `train` up to its first epoch (the folder lock, split, features, network, optimiser);
- epochs: the epoch loop (`_Run.epochs`: the steps, the validation pass, checkpoints), whose own
  figure is also in the model's metrics.json (`training.seconds`, `training.cpu_seconds`);
- finish: the rest of `train` (the recipe's evaluation, the fold gate or the workspace, saving,
  curves, the swap);

then per worker its start-up before its first job, the gaps between its jobs and its idle tail
after its last one until the stage ends, the jobs' CPU seconds inside and outside the epoch loops
(CPU time, less exposed to other jobs on the machine than wall time), and the stage's finishing time
simulated from the jobs' CPU seconds for the plan's order and for longest-first.

    python benchmarks/bench_train_stage.py --data OUT/data --workers 2 --out /tmp/stage
    python benchmarks/bench_train_stage.py --data OUT/data --out /tmp/stage2 --reference /tmp/stage/models

--data: a reproduction's data folder (`paper`, and `paper+excitation` for the recommended models);
--out: a new folder (the models go to OUT/models); --reference: a models folder to compare with,
model by model: the weights, metrics.json without its timing fields, history.csv without its
seconds (the same seeds must give the same bits); --runs: only these runs. Ends with one JSON line.
"""

from __future__ import annotations

import argparse
import csv
import heapq
import itertools
import json
import os
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from unittest import mock

import torch

from ctrkin.evaluation.executors import run_jobs
from ctrkin.evaluation.scales import get_scale
from ctrkin.evaluation.training_runs import _train_run, plan_runs, training_jobs
from ctrkin.training import engine

PHASES = ("load", "setup", "epochs", "finish")
TIMING_KEYS = {"seconds", "cpu_seconds", "samples_per_s", "samples_per_cpu_s"}   # metrics.json's clocks


def _clock() -> tuple[float, float]:
    """(monotonic wall s, this process's CPU s); the monotonic clock is shared by the processes."""
    return time.monotonic(), time.process_time()


@contextmanager
def _marked(method: str, marks: dict[str, tuple[float, float]]) -> Iterator[None]:
    """Record the clocks at the start and end of engine._Run.<method> (marks[method + ":0" / ":1"])."""
    original = getattr(engine._Run, method)

    def wrapped(self: Any, *args: Any, **kwargs: Any) -> Any:
        marks[f"{method}:0"] = _clock()
        try:
            return original(self, *args, **kwargs)
        finally:
            marks[f"{method}:1"] = _clock()

    with mock.patch.object(engine._Run, method, wrapped):
        yield


def timed_job(log_dir: str, data_dir: str, n_sequences: int | None, cfg: dict[str, Any], out: str) -> None:
    """`_train_run(data_dir, n_sequences, cfg, out)` in a worker, its phases written to
    log_dir/<run>.json: wall and CPU seconds of each phase, the worker's pid, start and end."""
    marks: dict[str, tuple[float, float]] = {"start": _clock()}
    loaded: list[tuple[float, float]] = []
    original_train = engine.train

    def train(*args: Any, **kwargs: Any) -> Any:           # the data is loaded when train is called
        loaded.append(_clock())
        return original_train(*args, **kwargs)

    with _marked("epochs", marks), mock.patch("ctrkin.evaluation.training_runs.train", train):
        _train_run(data_dir, n_sequences, cfg, out)
    marks["end"] = _clock()
    marks["loaded"] = loaded[0]
    bounds = {"load": ("start", "loaded"), "setup": ("loaded", "epochs:0"),
              "epochs": ("epochs:0", "epochs:1"), "finish": ("epochs:1", "end")}
    rec: dict[str, Any] = {"name": Path(out).name, "pid": os.getpid(), "start": marks["start"][0],
                           "end": marks["end"][0]}
    for phase, (a, b) in bounds.items():
        rec[phase] = {"wall": marks[b][0] - marks[a][0], "cpu": marks[b][1] - marks[a][1]}
    training = json.loads((Path(out) / "metrics.json").read_text())["training"]
    rec["metrics_seconds"], rec["metrics_cpu_seconds"] = training["seconds"], training["cpu_seconds"]
    (Path(log_dir) / f"{rec['name']}.json").write_text(json.dumps(rec))


def worker_idle(records: Sequence[dict[str, Any]], t0: float, t1: float) -> dict[int, dict[str, float]]:
    """Per worker (pid): start-up (t0 to its first job), gaps between its jobs, tail (its last job's
    end to t1) and busy seconds; t0, t1: the stage's start and the end of its last job."""
    out: dict[int, dict[str, float]] = {}
    for pid in sorted({r["pid"] for r in records}):
        mine = sorted((r for r in records if r["pid"] == pid), key=lambda r: r["start"])
        gaps = sum(b["start"] - a["end"] for a, b in itertools.pairwise(mine))
        out[pid] = {"startup": mine[0]["start"] - t0, "gaps": gaps, "tail": t1 - mine[-1]["end"],
                    "busy": sum(r["end"] - r["start"] for r in mine), "jobs": len(mine)}
    return out


def list_schedule(seconds: Sequence[float], workers: int) -> tuple[float, float]:
    """(finish, spread): when the last of jobs of these durations ends, handed in this order to the
    first free of `workers` (as the local executor's pool hands them out), and how long before that
    the first worker ran out of jobs."""
    free = [0.0] * workers
    for s in seconds:
        heapq.heappush(free, heapq.heappop(free) + s)
    return max(free), max(free) - min(free)


def _without_timing(d: Any) -> Any:
    if isinstance(d, dict):
        return {k: _without_timing(v) for k, v in d.items() if k not in TIMING_KEYS}
    if isinstance(d, list):
        return [_without_timing(v) for v in d]
    return d


def _history(folder: Path) -> list[dict[str, str]]:
    with open(folder / "history.csv", newline="") as f:
        return [{k: v for k, v in row.items() if k != "seconds"} for row in csv.DictReader(f)]


def model_differences(a: Path, b: Path) -> list[str]:
    """What differs between two trained model folders, timing apart: the weights (tensor by tensor,
    dtype and bits), any json file but the manifest (metrics.json without TIMING_KEYS), history.csv
    without its seconds column, the file names."""
    diffs = []
    if sorted(p.name for p in a.iterdir()) != sorted(p.name for p in b.iterdir()):
        diffs.append("files")
    wa, wb = (torch.load(f / "weights.pt", weights_only=True) for f in (a, b))
    if wa.keys() != wb.keys() or any(wa[k].dtype != wb[k].dtype or not torch.equal(wa[k], wb[k])
                                     for k in wa):
        diffs.append("weights.pt")
    for f in sorted(a.glob("*.json")):
        if f.name == "manifest.json" or not (b / f.name).is_file():     # hashes of files that hold the clocks
            continue
        ja, jb = (json.loads(g.read_text()) for g in (f, b / f.name))
        if _without_timing(ja) != _without_timing(jb):
            diffs.append(f.name)
    if (a / "history.csv").is_file() and _history(a) != _history(b):
        diffs.append("history.csv")
    return diffs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, required=True, help="a reproduction's data folder")
    ap.add_argument("--out", type=Path, required=True, help="a new folder")
    ap.add_argument("--scale", default="quick")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--runs", nargs="*", help="only these runs (default: all)")
    ap.add_argument("--reference", type=Path, help="a models folder trained with the same seeds")
    args = ap.parse_args()
    if args.out.exists() and any(args.out.iterdir()):
        raise SystemExit(f"{args.out} is not empty: choose a new --out")
    scale = get_scale(args.scale)
    runs = [r for r in plan_runs(scale) if not args.runs or r.name in args.runs]
    extra = args.data / "paper+excitation"
    jobs = training_jobs(runs, args.data / "paper", scale, args.out / "models", "cpu",
                         extra if extra.is_dir() else None)
    log_dir = args.out / "timeline"
    log_dir.mkdir(parents=True)
    load0 = os.getloadavg()
    t0 = time.monotonic()
    for _ in run_jobs(timed_job, [(str(log_dir), *job) for job in jobs], workers=args.workers):
        pass
    t1 = time.monotonic()
    load1 = os.getloadavg()
    recs = [json.loads((log_dir / f"{r.name}.json").read_text()) for r in runs]
    idle = worker_idle(recs, t0, max(r["end"] for r in recs))

    print(f"{'run':24s} {'wall s':>7s} " + " ".join(f"{p + ' s':>9s}" for p in PHASES) + "   outside CPU s")
    for r in recs:
        outside_cpu = sum(r[p]["cpu"] for p in PHASES if p != "epochs")
        print(f"{r['name']:24s} {r['end'] - r['start']:7.1f} "
              + " ".join(f"{r[p]['wall']:9.2f}" for p in PHASES) + f"   {outside_cpu:6.2f}")
    phase_wall = {p: sum(r[p]["wall"] for r in recs) for p in PHASES}
    phase_cpu = {p: sum(r[p]["cpu"] for r in recs) for p in PHASES}
    cpu = [sum(r[p]["cpu"] for p in PHASES) for r in recs]
    plan, plan_spread = list_schedule(cpu, args.workers)
    longest, longest_spread = list_schedule(sorted(cpu, reverse=True), args.workers)
    print(f"stage {t1 - t0:.1f} s wall ({args.workers} workers, load {load0[0]:.2f} -> {load1[0]:.2f}); "
          f"phases summed, wall: " + ", ".join(f"{p} {phase_wall[p]:.1f}" for p in PHASES)
          + "; CPU: " + ", ".join(f"{p} {phase_cpu[p]:.1f}" for p in PHASES))
    for pid, w in idle.items():
        print(f"worker {pid}: {w['jobs']} jobs, busy {w['busy']:.1f} s, start-up {w['startup']:.1f} s, "
              f"gaps {w['gaps']:.2f} s, idle tail {w['tail']:.1f} s")
    print(f"simulated from the jobs' CPU seconds: plan order {plan:.1f} s (spread {plan_spread:.1f}), "
          f"longest first {longest:.1f} s (spread {longest_spread:.1f})")
    result: dict[str, Any] = {
        "scale": args.scale, "workers": args.workers, "runs": len(recs), "stage_s": t1 - t0,
        "load": [load0[0], load1[0]], "phase_wall_s": phase_wall, "phase_cpu_s": phase_cpu,
        "outside_epochs_cpu_s": sum(v for p, v in phase_cpu.items() if p != "epochs"),
        "workers_idle_s": {str(pid): {k: w[k] for k in ("startup", "gaps", "tail")}
                           for pid, w in idle.items()},
        "simulated_s": {"plan": plan, "longest_first": longest},
    }
    if args.reference is not None:
        diffs = {r.name: model_differences(args.reference / r.name, args.out / "models" / r.name)
                 for r in runs}
        differing = {k: v for k, v in diffs.items() if v}
        print(f"against {args.reference}: {len(runs) - len(differing)} of {len(runs)} models identical"
              + "".join(f"\n  {k}: {', '.join(v)}" for k, v in differing.items()))
        result["reference"] = {"identical": len(runs) - len(differing), "differing": differing}
    print(json.dumps(result))


if __name__ == "__main__":
    main()
