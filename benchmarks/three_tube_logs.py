"""Three-tube logs in the comet-lab NDI format, recorded on a virtual three-tube robot.

The robot is examples/robots/comet_nylon_ndi_3tube.toml behind the virtual robot's imperfections at
their central values (`ctrkin.virtual.config.CENTRAL`, the defaults when this benchmark was written:
tube errors, backlash and friction, tracker noise; at today's top-of-range defaults the nylon tubes'
friction winds them up by tens of mm, 27 mm for the nominal TCM), driven through the rig
interfaces (`ctrkin.hardware`, a virtual rig, 20 readings per configuration as the lab took) with
the lab's own joint generator (Jointspace_Generator.m: travel lin1 in 0..40, lin2 and lin3 in 0..45
mm, cumulative X = lin1, Y = X + lin2, Z = Y + lin3; rotations −45..45°). Files (one session each,
from rest at the home configuration, all zeros in lab joints):

    random-a, random-b      21 configurations each (home first), as the two-tube NDI sessions
    sweep-wide              the inner tube (C) turning −90..90° in 5° steps at four inner
                            extensions, the middle tube at B = 30°, Y = 10 mm
    sweep-narrow            the same at −45..45° (the held-out test of a learned model)

Each reading is written as the lab's C# program wrote it (tests/lab_logs.ndi_lab_log): the tip in
the camera frame through a reference body whose pose differs per session; a few readings are
"PartiallyOutOfVolume" with a wild position and some "Missing" with empty cells, as NDI reports
them. Importing them needs examples/profiles/comet_ndi_3tube.toml (docs/real_robot.md: Three tubes).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ctrkin.acquisition.plan import Plan, Run, Segment, move
from ctrkin.acquisition.rig_recorder import LOG_FILE, RigCollection
from ctrkin.hardware import open_rig
from ctrkin.hardware.readings_log import ReadingsLog
from ctrkin.hardware.rig import parse_rig
from ctrkin.virtual.config import CENTRAL

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from tests.lab_logs import ndi_lab_log  # noqa: E402  (the one writer of the lab's format)

STRAIGHT = np.array([250.0, 170.0, 90.0])       # inner, middle, outer straight lengths (mm)
READINGS = 20
FILES = ("random-a", "random-b", "sweep-wide", "sweep-narrow")
BAD_FRACTION, MISSING_FRACTION = 0.04, 0.01


def lab_to_joints(travel: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Lab (X, Y, Z travel mm; A, B, C deg) -> ctrkin joints (α1..α3 inner first, β = travel − straight)."""
    return np.column_stack([rot[:, ::-1], travel[:, ::-1] - STRAIGHT])


def lab_random(rng: np.random.Generator, k: int) -> tuple[np.ndarray, np.ndarray]:
    lin = np.column_stack([rng.integers(0, 41, k), rng.integers(0, 46, k), rng.integers(0, 46, k)])
    travel = np.cumsum(lin, axis=1).astype(float)
    rot = rng.integers(-45, 46, (k, 3)).astype(float)
    travel[0], rot[0] = 0.0, 0.0                     # every session starts at home
    return travel, rot


def lab_sweep(limit: float) -> tuple[np.ndarray, np.ndarray]:
    c = np.arange(-limit, limit + 1e-9, 5.0)
    travel, rot = [], []
    for extension in (0.0, 15.0, 30.0, 45.0):
        travel += [[0.0, 10.0, 10.0 + extension]] * len(c)
        rot += [[0.0, 30.0, ck] for ck in c]
    return np.array(travel), np.array(rot)


def _plan(q: np.ndarray, home: np.ndarray, n_tubes: int) -> Plan:
    """One run from rest at home: an unrecorded move to each configuration, then one sample there
    (1°/0.1 mm steps; consecutive sweep points are one step apart)."""
    segs = []
    prev = home
    for qk in q:
        path = move(prev, qk, n_tubes)
        if len(path) > 1:
            segs.append(Segment(path[:-1], record=False))
        segs.append(Segment(qk[None, :], record=True))
        prev = qk
    return Plan("comet-3tube-session", (Run(tuple(segs)),))


def record(folder: Path, seed: int = 0) -> list[Path]:
    """Write the four logs into `folder` (module docstring); returns their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    sessions = {"random-a": lab_random(rng, 21), "random-b": lab_random(rng, 21),
                "sweep-wide": lab_sweep(90.0), "sweep-narrow": lab_sweep(45.0)}
    home = lab_to_joints(np.zeros((1, 3)), np.zeros((1, 3)))[0]
    paths = []
    for k, (name, (travel, rot)) in enumerate(sessions.items()):
        rig = parse_rig({"name": "virtual-comet-3tube", "robot": "comet_nylon_ndi_3tube.toml",
                         "home": home.tolist(), "actuator": {"kind": "virtual"},
                         "tracker": {"kind": "virtual", "readings": READINGS},
                         "virtual": {"seed": seed * 100 + k, "robot_seed": seed, "settings": dict(CENTRAL)}},
                        source="three_tube_logs", folder=REPO / "examples" / "robots")
        plan = _plan(lab_to_joints(travel, rot), home, 3)
        with tempfile.TemporaryDirectory() as tmp:
            actuator, tracker = open_rig(rig)
            RigCollection(plan, rig, actuator, tracker, Path(tmp) / "rig", progress=False).run()
            samples = ReadingsLog(Path(tmp) / "rig" / LOG_FILE, rig.robot.joint_names(), 1).read()
        tips = np.array([[f.poses[0, :3] for f in s.frames] for s in samples])     # (K, 20, 3)
        status = np.full(tips.shape[:2], "Enabled", dtype=object)
        draw = rng.random(tips.shape[:2])
        status[draw < BAD_FRACTION] = "PartiallyOutOfVolume"
        tips[draw < BAD_FRACTION] += rng.normal(scale=50.0, size=(int((draw < BAD_FRACTION).sum()), 3))
        status[(draw >= BAD_FRACTION) & (draw < BAD_FRACTION + MISSING_FRACTION)] = "Missing"
        ref_rot = Rotation.from_euler("xyz", [-90 + 3 * k, 1.5 * k, -88 - 2 * k], degrees=True)
        ref_pos = np.array([76.5, -25.1, -1344.8]) + rng.normal(scale=40.0, size=3)   # the camera moved
        paths.append(ndi_lab_log(folder / f"2023-12-0{k + 1}_{name}.csv", travel, rot, tips, ref_rot,
                                 ref_pos, status))
    return paths


if __name__ == "__main__":
    for p in record(Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / "out" / "three_tube_logs"):
        print(p)
