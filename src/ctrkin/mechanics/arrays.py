"""Kernel-ready view of a Robot (stiffnesses, precurvature sections and contact geometry as flat
arrays)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ctrkin.robots.robot import Robot


@dataclass(frozen=True, eq=False)
class RobotArrays:
    """k, gj: (N,) bending and torsional stiffness (N·mm²); lengths (N,) mm;
    sec_len, sec_kap, sec_kapy: (N, S) sections base to tip (mm, precurvature κx and κy in 1/mm);
    n_sec (N,); rigid transmission flag; extra (N,) mm: Robot.transmission_length;
    kappa_scale: κ* (1/mm), the fastest rate at which the state turns along s: the largest
    precurvature, times √(1 + ν) for the torsion, whose rate on a shared curved stretch is
    √c = √((1 + ν) κi κj) (ψ'' = c sin ψ, docs/mechanics.md). The RK4 step is at most
    SolverSettings.angle_step / κ*. curved_length: ℓc, the precurved length of all tubes (mm), the
    most arc length over which the state turns (step from SolverSettings.tip_tol).
    Contact (mechanics.contact), per pair p of neighbouring tubes (p, p + 1), (N − 1,): gap, the
    radial clearance (ID_{p+1} − OD_p) / 2 (mm); rc, the contact radius (OD_p + ID_{p+1}) / 4 (mm);
    lmin, the shortest force couple, OD_p (mm). friction: μ; clearance: Robot.clearance;
    contact: whether the contact model acts at all (μ > 0 or clearance > 0)."""

    k: np.ndarray
    gj: np.ndarray
    lengths: np.ndarray
    sec_len: np.ndarray
    sec_kap: np.ndarray
    sec_kapy: np.ndarray
    n_sec: np.ndarray
    rigid: bool
    extra: np.ndarray
    kappa_scale: float
    curved_length: float
    gap: np.ndarray
    rc: np.ndarray
    lmin: np.ndarray
    friction: float
    clearance: float

    @property
    def contact(self) -> bool:
        return self.k.shape[0] > 1 and (self.friction > 0.0 or self.clearance > 0.0)

    @property
    def slots(self) -> int:
        """Friction-state slots per pair: one per tube boundary and the front plate
        (grid.build_grid's codes)."""
        return self.k.shape[0] * (self.sec_len.shape[1] + 1) + 1


_BY_ID: dict[int, tuple[Robot, RobotArrays]] = {}


def robot_arrays(robot: Robot) -> RobotArrays:
    """The kernel-ready arrays of robot: one RobotArrays per robot description (equal robots share
    it). Looked up by the object first: hashing a Robot hashes every tube's fields, ~5 µs a solve
    (issue 26); the entry holds the robot, so its id is not reused while it is there."""
    hit = _BY_ID.get(id(robot))
    if hit is not None and hit[0] is robot:
        return hit[1]
    arr = _arrays(robot)
    if len(_BY_ID) >= 64:
        _BY_ID.clear()
    _BY_ID[id(robot)] = (robot, arr)
    return arr


@functools.lru_cache(maxsize=64)
def _arrays(robot: Robot) -> RobotArrays:
    n = robot.n_tubes
    s_max = max(len(t.sections) for t in robot.tubes) or 1
    sec_len = np.zeros((n, s_max))
    sec_kap = np.zeros((n, s_max))
    sec_kapy = np.zeros((n, s_max))
    n_sec = np.zeros(n, dtype=np.int64)
    for i, t in enumerate(robot.tubes):
        n_sec[i] = len(t.sections)
        for j, s in enumerate(t.sections):
            sec_len[i, j] = s.length
            sec_kap[i, j] = s.curvature
            sec_kapy[i, j] = s.curvature_y
    kmag = np.hypot(sec_kap, sec_kapy)
    tubes = robot.tubes
    arrs = RobotArrays(
        k=np.array([t.bending_stiffness for t in tubes]),
        gj=np.array([t.torsional_stiffness for t in tubes]),
        lengths=robot.lengths, sec_len=sec_len, sec_kap=sec_kap, sec_kapy=sec_kapy, n_sec=n_sec,
        rigid=robot.transmission == "rigid",
        extra=np.array(robot.transmission_length or [0.0] * n, dtype=float),
        kappa_scale=float(kmag.max(initial=0.0) * np.sqrt(1.0 + max(t.poisson_ratio for t in tubes))),
        curved_length=float(sec_len[kmag != 0.0].sum()),
        gap=np.array([max(0.5 * (tubes[p + 1].id - tubes[p].od), 0.0) for p in range(n - 1)]),
        rc=np.array([0.25 * (tubes[p].od + tubes[p + 1].id) for p in range(n - 1)]),
        lmin=np.array([tubes[p].od for p in range(n - 1)]),
        friction=robot.friction, clearance=robot.clearance)
    for a in (arrs.k, arrs.gj, arrs.lengths, arrs.sec_len, arrs.sec_kap, arrs.sec_kapy, arrs.n_sec,
              arrs.extra, arrs.gap, arrs.rc, arrs.lmin):
        a.setflags(write=False)
    return arrs
