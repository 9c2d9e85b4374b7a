"""Task-space paths for inverse kinematics checks: a square and a triangle of 10 poses (Fig. 12).

The corners are reachable by construction: they are tip poses of the virtual robot (its true tubes,
point-wise solve) at one configuration turned as a whole about the insertion axis (the outer and
inner tube rotated together by 0, 90, 180, 270° for the square; 0, 120, 240° for the triangle), so they
lie on a circle at one height and form a regular polygon. The 10 targets are spaced evenly along the
closed polygon by arc length, starting at the first corner; positions lie on the straight edges and
the orientation along an edge is interpolated by the equivalent angle-axis of the rotation between the
edge's corner orientations (paper Sec. IV.B): R(t) = R_a · exp(t · log(R_aᵀ R_b)). The pose is then
reported the 5-DOF way, (q0, qx, qy) from the interpolated tangent R(t) e3.

A path is written as a folder: `targets.csv` (step, x, y, z, q0, qx, qy; mm and unit quaternion) and
`meta.json` (shape, corner joints, robot, seed). `load_targets` reads it back.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from ctrkin.acquisition.protocols import config
from ctrkin.acquisition.ranges import ProtocolRanges
from ctrkin.data import schema
from ctrkin.errors import DatasetError
from ctrkin.geometry import pose_rotation, quat_from_tangent
from ctrkin.mechanics import solve
from ctrkin.robots.robot import Robot
from ctrkin.util.folders import build_folder, reading_folder
from ctrkin.version import __version__
from ctrkin.virtual.robot import VirtualRobot

SHAPES = {"square": 4, "triangle": 3}
TARGETS_FILE = "targets.csv"
META_FILE = "meta.json"
# corner configuration: inner tube 90° ahead of the outer one at d = 10 mm (a smooth, single-branch
# region), outer tube 2 mm back: well inside the workspace of the paper protocol (on the paper robot;
# another robot's d and βN are these carried over, `corner_of`)
CORNER = {"relative_rotation_deg": 90.0, "relative_translation_mm": 10.0, "beta_outer_mm": -2.0}


def corner_of(robot: Robot) -> dict[str, float]:
    """`CORNER` at the same place of `robot`'s geometry (ctrkin.acquisition.ranges)."""
    ranges = ProtocolRanges.of(robot)
    return {**CORNER, "relative_translation_mm": ranges.d(CORNER["relative_translation_mm"]),
            "beta_outer_mm": ranges.beta_outer(CORNER["beta_outer_mm"])}


@dataclass(frozen=True, eq=False)
class TaskPath:
    """IK target poses along a square or a triangle (paper Fig. 12).

    Attributes
    ----------
    shape : {"square", "triangle"}
    poses : ndarray, shape (P, 6)
        Target tip poses (x, y, z mm, q0, qx, qy).
    corners : ndarray, shape (C, 6)
        The corner poses.
    corner_joints : ndarray, shape (C, 2N)
        The corners' joints (deg, mm).
    meta : dict
        Provenance: corner joints and poses, robot, seed, version.
    """

    shape: str
    poses: np.ndarray
    corners: np.ndarray
    corner_joints: np.ndarray
    meta: dict[str, Any]

    def save(self, folder: str | Path) -> Path:
        """Write the folder as one unit (ctrkin.util.folders): targets.csv and meta.json are built
        aside and swapped in together, so a failure leaves the previous folder whole. `folder`, if it
        exists, must be a task path ctrkin wrote (ctrkin.util.ownership), or empty."""
        out = Path(folder)
        frame = pd.DataFrame(self.poses, columns=schema.POSE_COLUMNS)
        frame.insert(0, "step", np.arange(len(frame), dtype=np.int64))
        with build_folder(out, "task path", DatasetError, "collect") as build:
            frame.to_csv(build / TARGETS_FILE, index=False)
            (build / META_FILE).write_text(json.dumps(self.meta, indent=2))
        return out


def task_path(virtual: VirtualRobot, shape: str, n_points: int = 10, seed: int = 0,
              corner: dict[str, float] | None = None) -> TaskPath:
    """Target poses along a square or a triangle that the virtual robot can reach (module docstring).

    Parameters
    ----------
    virtual : VirtualRobot
        The robot whose true tip poses make the corners.
    shape : {"square", "triangle"}
    n_points : int
        Targets, spaced evenly along the closed polygon (at least its corners).
    seed : int
        Turns the whole polygon about the insertion axis by a seeded angle (different seeds give
        different, equally reachable paths).
    corner : dict, optional
        The corner configuration (default `corner_of(robot)`: relative rotation, relative
        translation, βN).

    Returns
    -------
    TaskPath
    """
    if shape not in SHAPES:
        raise DatasetError(f"shape must be one of {sorted(SHAPES)}, got {shape!r}")
    if n_points < SHAPES[shape]:
        raise DatasetError(f"a {shape} needs n_points >= {SHAPES[shape]}, got {n_points}")
    c = {**corner_of(virtual.nominal), **(corner or {})}
    n = virtual.nominal.n_tubes
    k = SHAPES[shape]
    turn = float(np.random.default_rng(np.random.SeedSequence([int(seed), 0x7A5C])).uniform(0, 360))
    outer = turn + 360.0 * np.arange(k) / k
    joints = config(n, outer + c["relative_rotation_deg"], outer, c["beta_outer_mm"],
                    c["relative_translation_mm"])
    virtual.nominal.check_joints(joints)
    base = virtual.base_joints(joints)  # encoder offsets of the true robot, centred play
    corners = np.array([solve(virtual.true_robot, b, strict=True).tip_pose for b in base])
    # even arc-length spacing along the closed polygon
    ends = np.roll(corners, -1, axis=0)
    edge_len = np.linalg.norm(ends[:, :3] - corners[:, :3], axis=1)
    cum = np.r_[0.0, np.cumsum(edge_len)]
    s = cum[-1] * np.arange(n_points) / n_points
    poses = np.empty((n_points, 6))
    for i, si in enumerate(s):
        e = min(int(np.searchsorted(cum, si, side="right")) - 1, k - 1)
        t = (si - cum[e]) / edge_len[e] if edge_len[e] > 0 else 0.0
        a, b = corners[e], ends[e]
        poses[i, :3] = a[:3] + t * (b[:3] - a[:3])
        ra, rb = pose_rotation(a[3:6]), pose_rotation(b[3:6])
        rel = (ra.inv() * rb).as_rotvec()  # equivalent angle-axis of the edge's rotation
        r = ra * Rotation.from_rotvec(t * rel)
        poses[i, 3:6] = quat_from_tangent(r.apply([0.0, 0.0, 1.0]))
    meta = {"kind": "task_path", "shape": shape, "n_points": n_points, "seed": int(seed),
            "columns": ["step", *schema.POSE_COLUMNS], "units": schema.UNITS,
            "frame": "robot base (true tip poses of the virtual robot, no tracker)",
            "corner": c, "turn_deg": turn, "corner_joints": joints.tolist(),
            "corner_poses": corners.tolist(), "robot": virtual.nominal.to_dict(),
            "robot_fingerprint": virtual.nominal.fingerprint(),
            "virtual_robot": virtual.describe(), "ctrkin_version": __version__,
            "interpolation": "positions on straight edges, orientation by equivalent angle-axis"}
    return TaskPath(shape, poses, corners, joints, meta)


def load_targets(folder: str | Path) -> tuple[np.ndarray, dict[str, Any]]:
    """Read a folder written by `TaskPath.save` (`ctrkin collect --protocol square|triangle`).

    Returns
    -------
    poses : ndarray, shape (P, 6)
    meta : dict

    Raises
    ------
    DatasetError
        If the folder is not a task path.
    """
    with reading_folder(folder) as src:
        return _load_targets(src)


def _load_targets(src: Path) -> tuple[np.ndarray, dict[str, Any]]:
    if not (src / TARGETS_FILE).is_file() or not (src / META_FILE).is_file():
        raise DatasetError(f"{src} is not a task path: it needs {TARGETS_FILE} and {META_FILE} "
                           "(made by `ctrkin collect --protocol square|triangle`)")
    try:
        meta = json.loads((src / META_FILE).read_text())
        frame = pd.read_csv(src / TARGETS_FILE)
    except (OSError, ValueError) as e:
        raise DatasetError(f"cannot read task path {src}: {e}") from None
    missing = [c for c in ["step", *schema.POSE_COLUMNS] if c not in frame.columns]
    if missing:
        raise DatasetError(f"{src / TARGETS_FILE} lacks column(s) {missing}")
    poses = frame.sort_values("step")[schema.POSE_COLUMNS].to_numpy(dtype=float)
    if not np.isfinite(poses).all():
        raise DatasetError(f"{src / TARGETS_FILE} has NaN or inf values")
    return poses, meta
