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


def rk4_stepper(rhs: Callable[..., Any]) -> Callable[..., None]:
    """The RK4 step of system `rhs` (module docstring): step(y, phi, zb, h, p, with_var, with_body, w)
    advances y, Φ (if with_var) and zb (if with_body) in place by h; w = rk4_work(...). The tangent
    is differentiated stage by stage, so it is the exact derivative of the discrete map.

    The stage sums are loops in the step itself, not helpers: numba counts references of every
    array an inlined helper takes, at each call, and in the TCM pass that reference counting cost
    more than the arithmetic (issue 26)."""

    @njit(cache=True, inline="always")
    def step(y, phi, zb, h, p, with_var, with_body, w):
        ks, qs, bs, yt, pt, zt = w
        n = y.shape[0]
        m = phi.shape[1]
        nb = zb.shape[0]
        rhs(y, phi, zb, p, with_var, with_body, ks[0], qs[0], bs[0])
        for s in range(1, 4):  # stage s from stage s − 1: yt = y + f k_s (f = h/2, h/2, h)
            f = h if s == 3 else 0.5 * h
            for j in range(n):
                yt[j] = y[j] + f * ks[s - 1, j]
            if with_var:
                for j in range(n):
                    for c in range(m):
                        pt[j, c] = phi[j, c] + f * qs[s - 1, j, c]
            if with_body:
                for j in range(nb):
                    zt[j] = zb[j] + f * bs[s - 1, j]
            rhs(yt, pt, zt, p, with_var, with_body, ks[s], qs[s], bs[s])
        h6 = h / 6.0  # y += h/6 (k1 + 2 k2 + 2 k3 + k4), likewise Φ and zb
        for j in range(n):
            y[j] += h6 * (ks[0, j] + 2.0 * ks[1, j] + 2.0 * ks[2, j] + ks[3, j])
            if with_var:
                for c in range(m):
                    phi[j, c] += h6 * (qs[0, j, c] + 2.0 * qs[1, j, c] + 2.0 * qs[2, j, c]
                                       + qs[3, j, c])
        if with_body:
            for j in range(nb):
                zb[j] += h6 * (bs[0, j] + 2.0 * bs[1, j] + 2.0 * bs[2, j] + bs[3, j])

    return step


@njit(cache=True)
def rk4_work(n, m, nb):
    """Work arrays of a step for y (n,), Φ (n, m), zb (nb,): the stage derivatives (4, n),
    (4, n, m), (4, nb) (rows k1..k4) and the stage states yt (n,), pt (n, m), zt (nb,). Six arrays,
    not one per stage: every array a kernel unpacks costs reference counting at each RK4 step."""
    return (np.empty((4, n)), np.empty((4, n, m)), np.empty((4, nb)),
            np.empty(n), np.empty((n, m)), np.empty(nb))
