"""Kernel-ready view of a Robot (stiffnesses and precurvature sections as flat arrays)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ctrkin.robots.robot import Robot


@dataclass(frozen=True, eq=False)
class RobotArrays:
    """k, gj: (N,) bending and torsional stiffness (N·mm²); lengths (N,) mm;
    sec_len, sec_kap: (N, S) sections base to tip (mm, 1/mm); n_sec (N,); rigid transmission flag;
    extra (N,) mm: Robot.transmission_length; kappa_scale: κ* (1/mm), the fastest rate at which the
    state turns along s: the largest precurvature, times √(1 + ν) for the torsion, whose rate on a
    shared curved stretch is √c = √((1 + ν) κi κj) (ψ'' = c sin ψ, docs/mechanics.md). The RK4 step
    is at most SolverSettings.angle_step / κ*. curved_length: ℓc, the precurved length of all
    tubes (mm), the most arc length over which the state turns (step from SolverSettings.tip_tol)."""

    k: np.ndarray
    gj: np.ndarray
    lengths: np.ndarray
    sec_len: np.ndarray
    sec_kap: np.ndarray
    n_sec: np.ndarray
    rigid: bool
    extra: np.ndarray
    kappa_scale: float
    curved_length: float


@functools.lru_cache(maxsize=64)
def robot_arrays(robot: Robot) -> RobotArrays:
    n = robot.n_tubes
    s_max = max(len(t.sections) for t in robot.tubes) or 1
    sec_len = np.zeros((n, s_max))
    sec_kap = np.zeros((n, s_max))
    n_sec = np.zeros(n, dtype=np.int64)
    for i, t in enumerate(robot.tubes):
        n_sec[i] = len(t.sections)
        for j, s in enumerate(t.sections):
            sec_len[i, j] = s.length
            sec_kap[i, j] = s.curvature
    arrs = RobotArrays(
        k=np.array([t.bending_stiffness for t in robot.tubes]),
        gj=np.array([t.torsional_stiffness for t in robot.tubes]),
        lengths=robot.lengths, sec_len=sec_len, sec_kap=sec_kap, n_sec=n_sec,
        rigid=robot.transmission == "rigid",
        extra=np.array(robot.transmission_length or [0.0] * n, dtype=float),
        kappa_scale=float(np.abs(sec_kap).max(initial=0.0)
                          * np.sqrt(1.0 + max(t.poisson_ratio for t in robot.tubes))),
        curved_length=float(sec_len[sec_kap != 0.0].sum()))
    for a in (arrs.k, arrs.gj, arrs.lengths, arrs.sec_len, arrs.sec_kap, arrs.n_sec, arrs.extra):
        a.setflags(write=False)
    return arrs
