"""`solve(q, guess=prev)` through a snap (issue 24): the loop a controller writes.

    python benchmarks/bench_solve_after_snap.py              # TIMClab robot, 721 steps
    python benchmarks/bench_solve_after_snap.py --follow     # and follow on the same path (slow)

A full inner turn (0.5° steps, 721 joint rows) of the TIMClab robot with its tips 0.01 mm apart
(the tubes' curved sections on each other), solved step by step with `prev = solve(robot, q,
guess=prev)`. Prints the unconverged and unstable steps, the steps where the tip jumps by more than
1 mm (snaps), the time per step, and with --follow the same for `follow` and the largest tip
difference between the two. Issue 24 counted 445 unconverged steps of 721 before `solve` recovered
after a snap. Ends with one JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

from ctrkin import follow, solve
from ctrkin.robots import timclab_robot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--follow", action="store_true", help="also run follow on the path")
    args = ap.parse_args()
    robot = timclab_robot()
    lengths = robot.lengths
    tip = 150.0        # mm beyond the front plate; the tubes' tips 0.02 and 0.01 mm beyond the outer's
    beta = np.array([tip - lengths[0] + 0.02, tip - lengths[1] + 0.01, tip - lengths[2]])
    Q = np.zeros((721, 6))
    Q[:, 0] = np.linspace(0.0, 360.0, 721)
    Q[:, 3:] = beta
    solve(robot, Q[0])                          # compile outside the timing
    t0 = time.perf_counter()
    prev = None
    eqs = []
    for q in Q:
        prev = solve(robot, q, guess=prev)
        eqs.append(prev)
    per_step = (time.perf_counter() - t0) / len(Q)
    tips = np.array([e.tip_position for e in eqs])
    jumps = np.linalg.norm(np.diff(tips, axis=0), axis=1)
    out = {"steps": len(Q), "unconverged": int(sum(not e.converged for e in eqs)),
           "unstable": int(sum(not e.stable for e in eqs)),
           "jumps_over_1mm": int(np.nansum(jumps > 1.0)), "solve_ms_per_step": 1e3 * per_step}
    print(f"solve(q, guess=prev): {out['unconverged']} of {len(Q)} steps unconverged, "
          f"{out['unstable']} unstable, {out['jumps_over_1mm']} tip jumps > 1 mm, "
          f"{out['solve_ms_per_step']:.2f} ms per step")
    if args.follow:
        t0 = time.perf_counter()
        traj = follow(robot, Q)
        out["follow_ms_per_step"] = 1e3 * (time.perf_counter() - t0) / len(Q)
        out["follow_snaps"] = traj.n_snaps
        out["max_tip_difference_mm"] = float(np.nanmax(np.linalg.norm(traj.tip_positions - tips, axis=1)))
        print(f"follow: {traj.n_snaps} snaps, {out['follow_ms_per_step']:.2f} ms per step; largest tip "
              f"difference to the solve loop {out['max_tip_difference_mm']:.3g} mm")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
