"""Small logs in the two comet-lab formats, written by the tests (never the shared files), and the
two-tube nylon robot they describe."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ctrkin.robots.robot import Robot
from ctrkin.robots.tube import Tube


def nylon_robot() -> Robot:
    """The comet-lab OptiTrack robot, innermost first (tube 1 = the lab's inner tube)."""
    return Robot(tubes=(Tube(4.0, 2.8, 161.0, 50.0, 0.014, 1.935, 0.4),
                        Tube(5.8, 4.6, 91.21, 50.0, 0.011, 1.935, 0.4)), name="nylon")


def configurations(n: int, seed: int = 0) -> np.ndarray:
    """(n, 4) lab joints: rot_inner, rot_outer (deg), travel_inner >= travel_outer (mm)."""
    rng = np.random.default_rng(seed)
    outer = rng.uniform(0, 30, n)
    inner = outer + rng.uniform(0, 30, n)
    return np.column_stack([rng.uniform(-60, 60, n), rng.uniform(-30, 30, n), inner, outer])


def optitrack_log(path: Path, lab_q: np.ndarray, tips_mm: np.ndarray, repeats: int = 10,
                  padding: int = 7, noise_mm: float = 0.0, seed: int = 0) -> Path:
    """Header-less OptiTrack layout: body 1 (7), lin1..3, rot1..3, body 2 (7); metres; `repeats`
    rows per configuration; `padding` all-zero rows at the end. lab_q from configurations()."""
    rng = np.random.default_rng(seed)
    rows = []
    for q, tip in zip(lab_q, tips_mm, strict=True):
        for _ in range(repeats):
            p = (tip + rng.normal(scale=noise_mm, size=3)) / 1000.0 if noise_mm else tip / 1000.0
            rows.append([0.001, -0.004, 0.11, 1.0, 0.0, 0.0, 0.0,        # body 1 (ignored)
                         q[3], q[2], q[2] + 5, q[1], q[0], 0.0,           # lin1..3, rot1..3
                         *p, 0.96, 0.03, -0.06, 0.25])                    # body 2: tip marker
    rows += [[0.0] * 20] * padding
    np.savetxt(path, np.array(rows), delimiter=",", fmt="%.12g")
    return path


def ndi_log(path: Path, lab_q: np.ndarray, tips_ref_mm: np.ndarray, ref_rot: Rotation,
            ref_pos: np.ndarray, repeats: int = 20, bad_rows: tuple[int, ...] = ()) -> Path:
    """Header-less two-tube NDI layout (ndi_lab_log): the inner travel drives Y and Z, C stays 0.
    Tips given in the reference body's frame; rows in bad_rows are PartiallyOutOfVolume with a wild
    position. lab_q from configurations()."""
    travel = np.column_stack([lab_q[:, 3], lab_q[:, 2], lab_q[:, 2]])
    rot = np.column_stack([lab_q[:, 1], lab_q[:, 0], np.zeros(len(lab_q))])
    tips = np.repeat(tips_ref_mm[:, None, :], repeats, axis=1)
    status = np.full(tips.shape[:2], "Enabled", dtype=object)
    for k in bad_rows:
        status[k // repeats, k % repeats] = "PartiallyOutOfVolume"
        tips[k // repeats, k % repeats] += 500.0
    return ndi_lab_log(path, travel, rot, tips, ref_rot, ref_pos, status)


def ndi_lab_log(path: Path, travel: np.ndarray, rot: np.ndarray, tips_ref_mm: np.ndarray,
                ref_rot: Rotation, ref_pos: np.ndarray, status: np.ndarray | None = None) -> Path:
    """The comet-lab NDI layout (two or three tubes, ../shared/realdata/comet-lab/README.md): G-code,
    X Y Z travel, A B C rotation, tool 1 (status, x, y, z, q, rms), tool 2 (the reference body),
    trailing comma. travel (K, 3) X, Y, Z mm; rot (K, 3) A, B, C deg; tips_ref_mm (K, R, 3): each
    reading's tip in the reference body's frame (the log holds p = R_ref p_rel + p_ref); status
    (K, R) tool 1's status per reading ("Missing": its fields left empty)."""
    qw = ref_rot.as_quat()  # x, y, z, w
    qref = [qw[3], qw[0], qw[1], qw[2]]
    status = status if status is not None else np.full(tips_ref_mm.shape[:2], "Enabled", dtype=object)
    lines = []
    for t, a, tips, st in zip(travel, rot, tips_ref_mm, status, strict=True):
        gcode = (f"G0 X{t[0] * 16:.0f} Y{t[1] * 16:.0f} Z{t[2] * 16:.0f} A{a[0]:.0f} B{a[1]:.0f} "
                 f"C{a[2]:.0f}\\n")
        for tip, s in zip(tips, st, strict=True):
            w = ref_rot.apply(tip) + ref_pos
            tool1 = (",,,,,,,," if s == "Missing" else
                     f"{w[0]:.6f},{w[1]:.6f},{w[2]:.6f},0.06,0.77,0.61,-0.14,0.21,")
            lines.append(f"{gcode},{t[0]:.6f},{t[1]:.6f},{t[2]:.6f},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f},"
                         f"{s},{tool1}Enabled,{ref_pos[0]:.6f},{ref_pos[1]:.6f},{ref_pos[2]:.6f},"
                         f"{qref[0]:.9f},{qref[1]:.9f},{qref[2]:.9f},{qref[3]:.9f},0.22,")
    path.write_text("\n".join(lines) + "\n")
    return path


def to_ctrkin(robot: Robot, lab_q: np.ndarray) -> np.ndarray:
    """Lab joints -> ctrkin joints (α1 inner, α2 outer, β = travel − straight length)."""
    s = [t.straight_length for t in robot.tubes]
    return np.column_stack([lab_q[:, 0], lab_q[:, 1], lab_q[:, 2] - s[0], lab_q[:, 3] - s[1]])
