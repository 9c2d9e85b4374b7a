"""Benchmark: record the paper protocol on the virtual robot (issue 3: full scale in <= 5 min, <= 2 GB).

    python benchmarks/bench_collect.py                 # full scale (~208k samples), all cores
    python benchmarks/bench_collect.py --scale quick --workers 1
    python benchmarks/bench_collect.py --central       # the virtual robot at the central values

Prints wall time, samples/s and peak memory: the resident set of this process and the largest of its
worker processes (ru_maxrss, RUSAGE_SELF and RUSAGE_CHILDREN), plus the sum as an upper bound of the
machine-wide peak. The kernels are compiled (or loaded from the numba cache) before the clock starts.
Ends with one JSON line of the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time

import numpy as np

from ctrkin.acquisition import protocols
from ctrkin.acquisition.recorder import record
from ctrkin.acquisition.summary import sweep_hysteresis
from ctrkin.robots import paper_robot
from ctrkin.virtual import VirtualConfig, VirtualRobot

LIMIT_S = 300.0
LIMIT_MB = 2048.0


def _maxrss_mb(who: int) -> float:
    kb = resource.getrusage(who).ru_maxrss  # KiB on Linux
    return kb / 1024.0 if sys.platform != "darwin" else kb / 2**20


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--scale", choices=protocols.SCALES, default="full")
    ap.add_argument("--workers", type=int, default=None, help="processes (default: all cores)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--save", action="store_true", help="also time writing the dataset folder")
    ap.add_argument("--central", action="store_true",
                    help="the virtual robot at the central values (VirtualConfig().central()) instead "
                    "of the defaults (the top of each published range)")
    args = ap.parse_args()

    robot = paper_robot()
    virtual = VirtualRobot(robot, VirtualConfig().central() if args.central else VirtualConfig(), seed=0)
    plan = protocols.build("paper", robot, scale=args.scale, seed=args.seed)
    virtual.rest(plan.runs[0].start)  # warm the numba kernels outside the timing
    workers = args.workers or os.cpu_count() or 1
    print(f"paper protocol, scale {args.scale}: {plan.n_samples} samples "
          f"({plan.n_steps} steps incl. transitions) in {len(plan.runs)} runs, {workers} workers")
    t0 = time.perf_counter()
    ds = record(plan, virtual, seed=args.seed, workers=workers, progress=True)
    wall = time.perf_counter() - t0
    if args.save:
        with tempfile.TemporaryDirectory() as tmp:
            t1 = time.perf_counter()
            ds.save(os.path.join(tmp, "paper"))
            print(f"save: {time.perf_counter() - t1:.1f} s")
    own, child = _maxrss_mb(resource.RUSAGE_SELF), _maxrss_mb(resource.RUSAGE_CHILDREN)
    n = len(ds.frame)
    print(f"wall time: {wall:.1f} s   ({n / wall:.0f} samples/s, {1e3 * wall / plan.n_steps:.3f} ms "
          "per step of wall time)")
    print(f"peak memory: main process {own:.0f} MB, largest worker {child:.0f} MB, "
          f"sum {own + child * workers:.0f} MB (upper bound with {workers} workers)")
    print(f"snap samples: {int(ds.frame['snap'].sum())}, glitches: {int(ds.frame['outlier'].sum())}, "
          f"frame {ds.frame.memory_usage(deep=True).sum() / 2**20:.0f} MB")
    print(sweep_hysteresis(ds).to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    ok_time = args.scale != "full" or wall <= LIMIT_S
    ok_mem = own + child * workers <= LIMIT_MB
    print(f"target (full scale): <= {LIMIT_S:.0f} s: {'ok' if ok_time else 'MISSED'}; "
          f"<= {LIMIT_MB:.0f} MB: {'ok' if ok_mem else 'MISSED'}")
    print(json.dumps({"scale": args.scale, "workers": workers, "samples": n, "wall_s": round(wall, 2),
                      "samples_per_s": round(n / wall, 1), "ms_per_step": round(1e3 * wall / plan.n_steps, 4),
                      "peak_mb_sum": round(own + child * workers),
                      "snap_samples": int(ds.frame["snap"].sum())}))
    return 0 if np.isfinite(wall) else 1


if __name__ == "__main__":
    sys.exit(main())
