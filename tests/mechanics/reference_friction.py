"""A slow, obviously-correct reference for the friction elements (docs/mechanics.md: Friction and
clearance), written independently of the kernels, for one case: two tubes of equal length, flush
tips, both curved at constant curvature over their whole length, bases at the front plate (β = 0)
behind transmissions of length b. Contacts act only at s = 0 and s = L (the whole overlap has one
constant precurvature, so the bundle's moment jumps only there), as play elements with the stuck
offsets θ given:

    ΔM = bending moment of the inner tube just inside the contact, |ΔM| its magnitude
    ℓ = clip(sqrt(12 δ k1 k2 / ((k1 + k2) |ΔM|)), OD1, L),  N = 2 |ΔM| / ℓ,  T = μ r N
    f = T clip((φ − θ) / ε, −1, 1),  the torque −f on the inner tube and +f on the outer

scipy's DOP853 integrates the TCM between the contacts, scipy's root finder solves uz(L⁺) = 0.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root

from ctrkin.robots.robot import Robot


def _moment_inner(psi: np.ndarray, k: np.ndarray, kap: np.ndarray) -> np.ndarray:
    """Bending moment (2,) of the inner tube in the backbone frame: k1 (u − v1)."""
    v = kap[None, :] * np.array([np.cos(psi), np.sin(psi)])  # (2, 2): column i = v_i
    u = (v * k).sum(axis=1) / k.sum()
    return k[0] * (u - v[:, 0])


def reference_pair(robot: Robot, alpha_deg: np.ndarray, theta: np.ndarray, x0: np.ndarray,
                   eps: float, tol: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
    """Tip position (3,) mm and the base torsion x (2,) rad/mm of the case above.

    alpha_deg (2,): base rotations; theta (2,): stuck offsets at s = 0 and s = L (rad); x0: a
    start for the root finder; eps: the elements' elastic range (rad)."""
    inner, outer = robot.tubes
    length = inner.length
    kap = np.array([inner.sections[0].curvature, outer.sections[0].curvature])
    k = np.array([inner.bending_stiffness, outer.bending_stiffness])
    gj = np.array([inner.torsional_stiffness, outer.torsional_stiffness])
    b = np.array(robot.transmission_length)
    gap = 0.5 * (outer.id - inner.od)
    rc = 0.25 * (inner.od + outer.id)
    keff = k[0] * k[1] / k.sum()
    alpha = np.radians(alpha_deg)

    def friction(psi: np.ndarray, th: float) -> float:
        dm = float(np.linalg.norm(_moment_inner(psi, k, kap)))
        ell = float(np.clip(np.sqrt(12.0 * gap * keff / dm), inner.od, length))
        bound = robot.friction * rc * 2.0 * dm / ell
        return bound * float(np.clip((psi[0] - psi[1] - th) / eps, -1.0, 1.0))

    def rhs(_s: float, z: np.ndarray) -> np.ndarray:
        psi, uz = z[:2], z[2:4]
        rot = z[7:16].reshape(3, 3)
        v = kap[None, :] * np.array([np.cos(psi), np.sin(psi)])
        u = (v * k).sum(axis=1) / k.sum()
        duz = k / gj * (u[0] * v[1] - u[1] * v[0])
        hat = np.array([[0.0, 0.0, u[1]], [0.0, 0.0, -u[0]], [-u[1], u[0], 0.0]])
        return np.concatenate([uz, duz, rot[:, 2], (rot @ hat).ravel()])

    def shoot(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        psi0 = alpha + b * x                       # ψ(0) = α − (β − b) x with β = 0
        f0 = friction(psi0, theta[0])
        uz0 = x + np.array([f0 / gj[0], -f0 / gj[1]])
        z = np.concatenate([psi0, uz0, np.zeros(3), np.eye(3).ravel()])
        z = solve_ivp(rhs, (0.0, length), z, method="DOP853", rtol=tol, atol=tol).y[:, -1]
        fl = friction(z[:2], theta[1])
        return z[2:4] + np.array([fl / gj[0], -fl / gj[1]]), z[4:7]

    sol = root(lambda x: shoot(x)[0], x0, method="hybr", tol=1e-14)
    return shoot(sol.x)[1], sol.x
