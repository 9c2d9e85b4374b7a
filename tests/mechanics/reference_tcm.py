"""A slow, obviously-correct TCM reference (docs/mechanics.md: Model), written independently of the
kernels: scipy's DOP853 at tight tolerance on each smooth stretch, scipy root finding on uz(0).

Used by the tests and by benchmarks/bench_mechanics.py to check the fast solver's accuracy.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root

from ctrkin.robots.robot import Robot


def _curvature(robot: Robot, beta: np.ndarray, i: int, s: float) -> float:
    sigma = s - beta[i]
    cum = 0.0
    for sec in robot.tubes[i].sections:
        cum += sec.length
        if sigma < cum:
            return sec.curvature
    return 0.0


def _breaks(robot: Robot, beta: np.ndarray) -> list[float]:
    tips = beta + robot.lengths
    pts = {0.0, float(tips.max())}
    for i, t in enumerate(robot.tubes):
        b = beta[i]
        for sec in t.sections:
            b += sec.length
            if 0.0 < b < tips.max():
                pts.add(float(b))
    return sorted(pts)


def _rhs(robot: Robot, beta: np.ndarray, mid: float):
    n = robot.n_tubes
    k = np.array([t.bending_stiffness for t in robot.tubes])
    gj = np.array([t.torsional_stiffness for t in robot.tubes])
    tips = beta + robot.lengths
    present = tips > mid
    kap = np.array([_curvature(robot, beta, i, mid) if present[i] else 0.0 for i in range(n)])

    def f(_s: float, z: np.ndarray) -> np.ndarray:
        psi, uz = z[:n], z[n:2 * n]
        rot = z[2 * n + 3:2 * n + 12].reshape(3, 3)
        ksum = k[present].sum()
        u = np.array([np.sum((k * kap * np.cos(psi))[present]), np.sum((k * kap * np.sin(psi))[present]),
                      0.0]) / ksum
        dpsi = np.where(present, uz, 0.0)
        duz = np.where(present, k / gj * kap * (np.sin(psi) * u[0] - np.cos(psi) * u[1]), 0.0)
        hat = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        return np.concatenate([dpsi, duz, rot[:, 2], (rot @ hat).ravel()])

    return f


def reference_tip(robot: Robot, q: np.ndarray, x0: np.ndarray | None = None, tol: float = 1e-12
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tip position (3,) mm, tangent (3,) and base torsion uz(0) (N,) by the reference method.
    x0: initial guess of uz(0) (e.g. the fast solver's answer, to land on the same branch)."""
    n = robot.n_tubes
    q = np.asarray(q, float)
    alpha, beta = np.radians(q[:n]), q[n:]
    tips = beta + robot.lengths
    rigid = robot.transmission == "rigid"
    breaks = _breaks(robot, beta)

    def integrate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        z = np.concatenate([alpha if rigid else alpha - beta * x, x, np.zeros(3), np.eye(3).ravel()])
        res = np.zeros(n)
        for a, b in itertools.pairwise(breaks):
            sol = solve_ivp(_rhs(robot, beta, 0.5 * (a + b)), (a, b), z, method="DOP853",
                            rtol=tol, atol=tol)
            z = sol.y[:, -1]
            for i in range(n):
                if abs(tips[i] - b) < 1e-9:
                    res[i] = z[n + i]
        for i in range(n):
            if tips[i] <= 1e-9:
                res[i] = x[i]
        return res, z

    guess = np.zeros(n) if x0 is None else np.asarray(x0, float)
    sol = root(lambda x: integrate(x)[0], guess, method="hybr", tol=1e-14)
    _, z = integrate(sol.x)
    rot = z[2 * n + 3:2 * n + 12].reshape(3, 3)
    return z[2 * n:2 * n + 3], rot[:, 2] / np.linalg.norm(rot[:, 2]), sol.x
