"""Friction and clearance on the paper robot (docs/mechanics.md: Friction and clearance).

    python benchmarks/bench_friction.py

Prints, for μ = 0 … 0.5, the T(L) loop width of 1° inner sweeps at d = 8 and 12 mm and the inner
angle of the forward snap at d = 20 mm (the frictionless fold at μ = 0); the contact forces, couple
lengths and friction bounds at d = 12 mm, α1 = 90°; and the clearance tilt at the outer tube's tip
with the tip displacement it makes, over a full inner turn at d = 4, 12 and 20 mm. Ends with one JSON line.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from ctrkin import follow, paper_robot, solve
from ctrkin.acquisition.trajectories import rotation_sweep

MUS = (0.0, 0.05, 0.1, 0.2, 0.3, 0.5)


def loop_width(robot, d: float) -> float:
    tr = follow(robot, rotation_sweep(2, d))
    return float(np.abs(tr.azimuth[:361] - tr.azimuth[360:][::-1]).max())


def main() -> None:
    base = paper_robot()
    out: dict[str, float] = {}
    print(f"{'μ':>5s} {'loop d=8 (deg)':>15s} {'loop d=12 (deg)':>16s} {'forward snap d=20 (α1 deg)':>27s}")
    for mu in MUS:
        robot = dataclasses.replace(base, friction=mu)
        w8, w12 = loop_width(robot, 8.0), loop_width(robot, 12.0)
        snap = float(np.nonzero(follow(robot, rotation_sweep(2, 20.0)).snaps)[0][0])
        print(f"{mu:5.2f} {w8:15.1f} {w12:16.1f} {snap:27.0f}")
        out |= {f"loop_d8_mu{mu}": w8, f"loop_d12_mu{mu}": w12, f"snap_d20_mu{mu}": snap}

    rough = dataclasses.replace(base, friction=0.2, clearance=1.0)
    tr = follow(rough, rotation_sweep(2, 12.0)[:91])
    rep = tr.equilibria[-1].contact
    assert rep is not None
    print("contacts at d = 12 mm, α1 = 90° after turning up from 0 (μ = 0.2):")
    for s, n, bound, torque, mode in zip(rep.s, rep.normal, rep.bound, rep.torque, rep.mode, strict=True):
        print(f"  s = {s:5.1f} mm: N = {n:.3f} N, bound {bound:.4f} N·mm, torque {torque:+.4f} N·mm, "
              f"mode {mode}")
    for d in (4.0, 12.0, 20.0):
        tilts, moves = [], []
        for a in np.arange(0.0, 360.0, 10.0):
            q = np.array([a, 0.0, -d, 0.0])
            with_gap = solve(dataclasses.replace(base, clearance=1.0), q)
            tip = with_gap.contact.tilt.max() if with_gap.contact is not None else 0.0
            tilts.append(np.degrees(tip))
            moves.append(np.linalg.norm(with_gap.tip_position - solve(base, q).tip_position))
        print(f"clearance tilt at the outer tip, d = {d:4.1f} mm (inner tube {72.0 - d - 51.5:4.1f} mm "
              f"beyond it), full turn: {min(tilts):.2f}–{max(tilts):.2f} deg, tip moved "
              f"{min(moves):.2f}–{max(moves):.2f} mm")
        out |= {f"tilt_d{d:g}_max_deg": max(tilts), f"tilt_d{d:g}_tip_max_mm": max(moves),
                f"tilt_d{d:g}_tip_min_mm": min(moves)}
    print(json.dumps({k: float(f"{v:.4g}") for k, v in out.items()}))


if __name__ == "__main__":
    main()
