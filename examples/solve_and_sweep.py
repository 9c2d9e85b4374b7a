"""Solve the TCM at one configuration, then follow a full inner-tube rotation (paper Fig. 2b).

    python examples/solve_and_sweep.py                      # d = 20 mm: the robot snaps both ways
    python examples/solve_and_sweep.py --d 8 --step 2       # small overlap: no snap
    python examples/solve_and_sweep.py --plot sweep.png     # also draw the shapes, snaps marked

A point-wise `solve` has no history (the paper's TCM baseline); `follow` continues the equilibrium
step by step and snaps where its branch ends at a fold.
"""

from __future__ import annotations

import argparse

import numpy as np

import ctrkin
from ctrkin.acquisition.trajectories import rotation_sweep


def main(argv: list[str] | None = None) -> dict[str, object]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--d", type=float, default=20.0, help="relative translation d = β2 − β1 (mm)")
    ap.add_argument("--step", type=float, default=1.0, help="inner rotation step (deg)")
    ap.add_argument("--plot", help="write a 3-D drawing of the sweep's shapes here (.png)")
    args = ap.parse_args(argv)

    robot = ctrkin.paper_robot()                      # paper Table I, innermost tube first
    eq = ctrkin.solve(robot, [0.0, 0.0, -15.0, -5.0])  # q = (α1, α2 deg, β1, β2 mm)
    print(f"solve q = {eq.q.tolist()}: tip {np.round(eq.tip_position, 3).tolist()} mm, "
          f"stable {eq.stable}, det J {eq.stability:.3f}")

    Q = rotation_sweep(robot.n_tubes, args.d, step_deg=args.step)   # α1: 0 -> 360 -> 0°
    traj = ctrkin.follow(robot, Q)
    snaps = np.flatnonzero(traj.snaps)
    half = len(Q) // 2
    for t in snaps:
        way = "forward" if t <= half else "backward"
        jump = traj.azimuth[t] - traj.azimuth[t - 1]
        print(f"snap {way} at α1 = {Q[t, 0]:.0f}°: T(L) jumps by {jump:+.1f}°")
    print(f"d = {args.d:g} mm: {len(Q)} steps, {len(snaps)} snaps, T(L) from {traj.azimuth.min():.1f} "
          f"to {traj.azimuth.max():.1f}°")
    if args.plot:
        from ctrkin.viz.shape import plot_shape

        shown = np.linspace(0, len(Q) - 1, 8).round().astype(int)
        plot_shape(robot, [traj.equilibria[t] for t in shown], args.plot, snaps=traj.snaps,
                   tips=traj.tip_poses[:, :3])
        print(f"wrote {args.plot}")
    return {"tip_mm": eq.tip_position.tolist(), "steps": len(Q), "snap_steps": snaps.tolist()}


if __name__ == "__main__":
    main()
