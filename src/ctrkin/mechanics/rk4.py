"""The classical fourth-order Runge-Kutta step, written once for every integration along s.

A system is a derivative function

    rhs(y, phi, zb, p, with_var, with_body, dy, dphi, dzb)

that writes y' (n,) into dy, the tangent Φ' (n, m) into dphi (if with_var) and the derivative of an
extra state zb' (nb,) into dzb (if with_body); p is a tuple of the system's parameters. Both the TCM
shooting pass (mechanics.kernels: y = (ψ, uz), Φ = ∂y/∂uz(0), zb = backbone and energy) and the
calibration tangent (calibration.sensitivity: y = (ψ, uz, p, R), Φ = ∂y/∂(x, θ)) are such systems.

`rk4_stepper(rhs)` returns the step of that system. The system is bound when the module that defines
it is imported, not passed at run time, because numba cannot cache a kernel that takes a function as
an argument; the step is inlined into its caller, so it costs nothing over a hand-written one.
(numba's cache tracks only the caller's own file: after editing this file, clear the __pycache__
folders of its users.)
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _stage(y, phi, zb, f, dy, dphi, dzb, with_var, with_body, yt, pt, zt):
    """Stage state: yt = y + f dy, pt = Φ + f dΦ (if with_var), zt = zb + f dzb (if with_body)."""
    for j in range(y.shape[0]):
        yt[j] = y[j] + f * dy[j]
    if with_var:
        for j in range(phi.shape[0]):
            for c in range(phi.shape[1]):
                pt[j, c] = phi[j, c] + f * dphi[j, c]
    if with_body:
        for j in range(zb.shape[0]):
            zt[j] = zb[j] + f * dzb[j]


@njit(cache=True, inline="always")
def _update(y, phi, zb, h, k1, k2, k3, k4, q1, q2, q3, q4, b1, b2, b3, b4, with_var, with_body):
    """y += h/6 (k1 + 2 k2 + 2 k3 + k4), likewise Φ and zb."""
    h6 = h / 6.0
    for j in range(y.shape[0]):
        y[j] += h6 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        if with_var:
            for c in range(phi.shape[1]):
                phi[j, c] += h6 * (q1[j, c] + 2.0 * q2[j, c] + 2.0 * q3[j, c] + q4[j, c])
    if with_body:
        for j in range(zb.shape[0]):
            zb[j] += h6 * (b1[j] + 2.0 * b2[j] + 2.0 * b3[j] + b4[j])


def rk4_stepper(rhs: Callable[..., Any]) -> Callable[..., None]:
    """The RK4 step of system `rhs` (module docstring): step(y, phi, zb, h, p, with_var, with_body, w)
    advances y, Φ (if with_var) and zb (if with_body) in place by h; w = rk4_work(...). The tangent
    is differentiated stage by stage, so it is the exact derivative of the discrete map."""

    @njit(cache=True, inline="always")
    def step(y, phi, zb, h, p, with_var, with_body, w):
        k1, k2, k3, k4, q1, q2, q3, q4, b1, b2, b3, b4, yt, pt, zt = w
        rhs(y, phi, zb, p, with_var, with_body, k1, q1, b1)
        _stage(y, phi, zb, 0.5 * h, k1, q1, b1, with_var, with_body, yt, pt, zt)
        rhs(yt, pt, zt, p, with_var, with_body, k2, q2, b2)
        _stage(y, phi, zb, 0.5 * h, k2, q2, b2, with_var, with_body, yt, pt, zt)
        rhs(yt, pt, zt, p, with_var, with_body, k3, q3, b3)
        _stage(y, phi, zb, h, k3, q3, b3, with_var, with_body, yt, pt, zt)
        rhs(yt, pt, zt, p, with_var, with_body, k4, q4, b4)
        _update(y, phi, zb, h, k1, k2, k3, k4, q1, q2, q3, q4, b1, b2, b3, b4, with_var, with_body)

    return step


@njit(cache=True)
def rk4_work(n, m, nb):
    """Work arrays of a step for y (n,), Φ (n, m), zb (nb,): the stage derivatives k1..k4, q1..q4,
    b1..b4 and the stage states yt, pt, zt."""
    return (np.empty(n), np.empty(n), np.empty(n), np.empty(n),
            np.empty((n, m)), np.empty((n, m)), np.empty((n, m)), np.empty((n, m)),
            np.empty(nb), np.empty(nb), np.empty(nb), np.empty(nb),
            np.empty(n), np.empty((n, m)), np.empty(nb))
