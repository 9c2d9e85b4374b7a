"""Benchmark: concurrent readers and writers of one dataset folder and one model folder (issue 27 items
6, 7). Goal: every write succeeds, every read gives the old or the new version (0 failed, 0 mixed).

    python benchmarks/bench_folder_races.py                 # 20 s per folder kind, 3 readers
    python benchmarks/bench_folder_races.py --seconds 5     # quicker

One process replaces the folder over and over, alternately with two versions (a dataset by
`Dataset.save`; a model folder by building a copy beside it and `swap_in` under the writer lock, as
`ctrkin train` does), while reader processes load it in a loop (`Dataset.load`; `Kinematics.load` and
`predict` on 20 probe rows) and compare with the two versions' content (exactly). Counted: writes,
failed writes, reads, failed reads (any exception), mixed reads (content of neither version). Uses
only API that existed before issue 27, so the same script measures the code before the fix. Prints a
table and, as its last line, a JSON object of the counts.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import shutil
import sys
import tempfile
import time
import uuid
import warnings
from pathlib import Path
from typing import Any

import numpy as np

SPAWN = multiprocessing.get_context("spawn")   # clean processes: no fork after torch or arrow threads


def _writer(kind: str, versions: list[str], target: str, seconds: float, q: Any) -> None:
    from ctrkin.data import Dataset
    from ctrkin.errors import ModelError
    from ctrkin.util.folders import folder_lock, swap_in

    out = Path(target)
    sets = [Dataset.load(v) for v in versions] if kind == "dataset" else []
    writes = failed = 0
    first = ""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            if kind == "dataset":
                sets[writes % 2].save(out)
            else:
                with folder_lock(out, ModelError):
                    build = out.with_name(f".{out.name}.tmp-{uuid.uuid4().hex[:16]}")
                    shutil.copytree(versions[writes % 2], build)
                    swap_in(build, out, ModelError)
        except Exception as e:  # every failure counts
            failed += 1
            first = first or f"{type(e).__name__}: {e}"[:200]
        writes += 1
    q.put(("write", writes, failed, 0, first))


def _reader(kind: str, versions: list[str], target: str, seconds: float, q: Any) -> None:
    from ctrkin.data import Dataset

    if kind == "dataset":
        frames = [Dataset.load(v).frame.to_numpy() for v in versions]
    else:
        from ctrkin.inference import Kinematics

        probe = Dataset.load(str(Path(versions[0]).parent / "data")).joints()[:20]
        answers = [Kinematics.load(v).predict(probe) for v in versions]
    reads = failed = mixed = 0
    first = ""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                if kind == "dataset":
                    got = Dataset.load(target).frame.to_numpy()
                    ok = any(got.shape == f.shape and (got == f).all() for f in frames)
                else:
                    got = Kinematics.load(target).predict(probe)
                    ok = any(np.array_equal(got, a) for a in answers)
            mixed += not ok
        except Exception as e:  # every failure counts
            failed += 1
            first = first or f"{type(e).__name__}: {e}"[:200]
        reads += 1
    q.put(("read", reads, failed, mixed, first))


def _prepare(tmp: Path) -> dict[str, list[str]]:
    """Two versions of a dataset and of a model folder."""
    import contextlib
    import io

    from ctrkin import paper_robot
    from ctrkin.training import TrainConfig, train
    from ctrkin.training.demo import sweep_dataset

    robot = paper_robot()
    a = sweep_dataset(robot, translations=(8, 16), outer_alphas=(0, 180), step_deg=6, noise_mm=0.02, seed=0)
    b = sweep_dataset(robot, translations=(12,), outer_alphas=(0, 90, 180), step_deg=6, noise_mm=0.02,
                      seed=1)
    a.save(tmp / "data")
    b.save(tmp / "data_b")
    small = {"structure": "L8|D8"}
    with contextlib.redirect_stdout(io.StringIO()):
        for name, seed in (("model_a", 0), ("model_b", 1)):
            train(a, TrainConfig(task="fk", max_epochs=1, threads=1, options=small, seed=seed), tmp / name,
                  progress=False)
    return {"dataset": [str(tmp / "data"), str(tmp / "data_b")],
            "model": [str(tmp / "model_a"), str(tmp / "model_b")]}


def run(seconds: float, readers: int) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        versions = _prepare(tmp)
        for kind, pair in versions.items():
            target = tmp / f"{kind}_target"
            shutil.copytree(pair[0], target)
            q = SPAWN.Queue()
            procs = [SPAWN.Process(target=_writer, args=(kind, pair, str(target), seconds, q)),
                     *(SPAWN.Process(target=_reader, args=(kind, pair, str(target), seconds, q))
                       for _ in range(readers))]
            for p in procs:
                p.start()
            res = [q.get(timeout=seconds + 300) for _ in procs]
            for p in procs:
                p.join(timeout=60)
            w = [r for r in res if r[0] == "write"]
            r = [x for x in res if x[0] == "read"]
            out[kind] = {"writes": sum(x[1] for x in w), "failed_writes": sum(x[2] for x in w),
                         "reads": sum(x[1] for x in r), "failed_reads": sum(x[2] for x in r),
                         "mixed_reads": sum(x[3] for x in r),
                         "first_problem": next((x[4] for x in res if x[4]), "")}
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seconds", type=float, default=20.0, help="duration per folder kind")
    ap.add_argument("--readers", type=int, default=3, help="reader processes")
    args = ap.parse_args()
    print(f"load: {os.getloadavg()[0]:.2f} (1 min), {args.readers} readers, {args.seconds:g} s per kind")
    res = run(args.seconds, args.readers)
    print(f"{'folder':8s} {'writes':>7s} {'failed':>7s} {'reads':>7s} {'failed':>7s} {'mixed':>7s}")
    for kind, r in res.items():
        print(f"{kind:8s} {r['writes']:7d} {r['failed_writes']:7d} {r['reads']:7d} {r['failed_reads']:7d} "
              f"{r['mixed_reads']:7d}")
        if r["first_problem"]:
            print(f"  first problem: {r['first_problem']}")
    print(json.dumps(res))
    bad = sum(r["failed_writes"] + r["failed_reads"] + r["mixed_reads"] for r in res.values())
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
