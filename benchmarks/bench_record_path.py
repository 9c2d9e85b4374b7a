"""Recording time of the paper's arbitrary path (Fig. 10c) on the default virtual robot, with
follow's det J continuity check as it is and as it was before issue 20's fix (compared on
translating sub-steps with slipping elements too: docs/mechanics.md: Friction and clearance).

    python benchmarks/bench_record_path.py [--rounds 3] [--seed 0]

Records the path in this process (one worker), the two rules interleaved round by round, and
prints per rule the median wall time, the Newton solves of the recording and the largest tip
difference between the two recordings (mm). Ends with one JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from ctrkin import paper_robot
from ctrkin.acquisition.protocols import arbitrary
from ctrkin.acquisition.recorder import record
from ctrkin.mechanics import continuation
from ctrkin.virtual import VirtualRobot

CURRENT = continuation._det_comparable


def _before(before: bytes, after: bytes, translating: bool) -> bool:
    """The rule before the fix: det J compared whenever the stick/slip pattern held."""
    return before == after


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0, help="virtual robot seed")
    args = ap.parse_args()
    nominal = paper_robot()
    virtual = VirtualRobot(nominal, seed=args.seed)
    plan = arbitrary(nominal)
    real_newton = continuation.newton
    calls = [0]

    def counted(*a, **k):
        calls[0] += 1
        return real_newton(*a, **k)

    continuation.newton = counted
    times: dict[str, list[float]] = {"after": [], "before": []}
    solves: dict[str, int] = {}
    tips: dict[str, np.ndarray] = {}
    record(plan, virtual, seed=0, workers=1, progress=False)       # compile and warm
    for _ in range(args.rounds):
        for rule, fn in (("after", CURRENT), ("before", _before)):
            continuation._det_comparable = fn
            calls[0] = 0
            t0 = time.perf_counter()
            ds = record(plan, virtual, seed=0, workers=1, progress=False)
            times[rule].append(time.perf_counter() - t0)
            solves[rule] = calls[0]
            tips[rule] = ds.frame[["true_x", "true_y", "true_z"]].to_numpy()
    continuation._det_comparable = CURRENT
    diff = float(np.linalg.norm(tips["after"] - tips["before"], axis=1).max())
    load = os.getloadavg()[0]
    print(f"arbitrary path, {len(tips['after'])} samples, default virtual robot seed {args.seed} "
          f"(load {load:.1f}), {args.rounds} rounds interleaved")
    print(f"{'det J rule':>12s} {'median s':>9s} {'Newton solves':>14s}")
    out: dict[str, float] = {"load": load, "max_tip_difference_mm": diff}
    for rule in ("before", "after"):
        med = float(np.median(times[rule]))
        print(f"{rule:>12s} {med:9.2f} {solves[rule]:14d}")
        out |= {f"{rule}_s": med, f"{rule}_solves": solves[rule]}
    print(f"largest true-tip difference between the two recordings: {diff:.3f} mm; "
          f"speed-up {out['before_s'] / out['after_s']:.0f}x")
    print(json.dumps({k: float(f"{v:.4g}") for k, v in out.items()}))


if __name__ == "__main__":
    main()
