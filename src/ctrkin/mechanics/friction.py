"""The contact stations of a prepared configuration and the friction state carried along a path
(docs/mechanics.md: Friction and clearance; the kernels are mechanics.contact).

A friction element's stuck offset θ is kept per *slot*: the pair of tubes and the identity of the
breakpoint it sits at (a tube boundary or the front plate, grid.build_grid), so a contact keeps its
state while its arc length moves with a translation. A state is valid at the joints it was set at;
the next step's relative translation of each pair (the axial slip of its contacts, C4) is measured
from there. No state (NaN θ) means a fresh contact: no friction force until a step has set it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctrkin.mechanics.arrays import RobotArrays
from ctrkin.mechanics.contact import FRESH, SLIP, STICK, build_stations
from ctrkin.mechanics.settings import SolverSettings

__all__ = ["FRESH", "SLIP", "STICK", "ContactReport", "FrictionState", "Stations"]

N_OUT = 8  # per-station outputs of contact.station


@dataclass(frozen=True, eq=False)
class Stations:
    """The friction stations of one grid (contact.build_stations), K of them. b (K,): breakpoint
    index; pair (K,); slot (K,): state slot; lmax, hl, hr (K,) mm; tip (K,) bool; s (K,) mm: arc
    length; prm (5,) = (μ, ε_t rad, ε_a mm, clearance, distributed 0/1)."""

    b: np.ndarray
    pair: np.ndarray
    slot: np.ndarray
    lmax: np.ndarray
    hl: np.ndarray
    hr: np.ndarray
    tip: np.ndarray
    s: np.ndarray
    prm: np.ndarray

    @classmethod
    def build(cls, arr: RobotArrays, bounds: np.ndarray, present: np.ndarray, code: np.ndarray,
              tips: np.ndarray, settings: SolverSettings) -> Stations:
        b, pair, slot, lmax, hl, hr, tip = build_stations(bounds, present, code, tips, arr.slots)
        prm = np.array([arr.friction, settings.stick_rad, settings.stick_mm, arr.clearance,
                        1.0 if settings.distributed_friction else 0.0])
        return cls(b, pair, slot, lmax, hl, hr, tip, bounds[b], prm)

    @property
    def count(self) -> int:
        return int(self.b.shape[0])


@dataclass(frozen=True, eq=False)
class FrictionState:
    """theta: (P · slots,) stuck offsets of the friction elements (rad; NaN: no contact, or a
    fresh one); q: (2N,) the joints (deg, mm) the state holds at."""

    theta: np.ndarray
    q: np.ndarray

    @classmethod
    def relaxed(cls, arr: RobotArrays, q: np.ndarray) -> FrictionState:
        """No history: every contact fresh (the point-wise solve's state)."""
        return cls(np.full(max(arr.k.shape[0] - 1, 0) * arr.slots, np.nan), np.asarray(q, float))

    def gather(self, st: Stations, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """θ (K,) of the stations of a grid and dd (P,): each pair's relative translation
        Δ(β_p − β_{p+1}) (mm) from this state's joints to q (2N,)."""
        n = q.shape[0] // 2
        rel_now = q[n:n + n - 1] - q[n + 1:]
        rel_then = self.q[n:n + n - 1] - self.q[n + 1:]
        return self.theta[st.slot], rel_now - rel_then


@dataclass(frozen=True, eq=False)
class ContactReport:
    """The contacts of one equilibrium. s (K,) mm: where; pair (K,): the inner tube of each
    (0-based); normal (K,) N: contact force N_c + N_d; bound (K,) N·mm: μ r N; torque (K,) N·mm:
    the friction torque f (−f on the inner tube, +f on the outer); mode (K,): FRESH, STICK, SLIP;
    tilt (K,) rad: the clearance tilt at an outer tube's tip; state: the friction state after
    this equilibrium (θ moved by the slip, C6)."""

    s: np.ndarray
    pair: np.ndarray
    normal: np.ndarray
    bound: np.ndarray
    torque: np.ndarray
    mode: np.ndarray
    tilt: np.ndarray
    state: FrictionState

    @classmethod
    def from_outputs(cls, st: Stations, out: np.ndarray, before: FrictionState | None,
                     q: np.ndarray, arr: RobotArrays) -> ContactReport:
        """The report of a converged solve: out (K, 8) the stations' outputs (contact.station)."""
        eps_t = float(st.prm[1])
        theta = np.full(max(arr.k.shape[0] - 1, 0) * arr.slots, np.nan)
        phi, g = out[:, 0], out[:, 1]
        mode = out[:, 3].astype(np.int64)
        theta[st.slot] = np.where(mode == FRESH, phi, phi - eps_t * g)   # (C6)
        del before  # a contact that is not a station any more loses its state
        return cls(st.s, st.pair, out[:, 2].copy(), out[:, 7].copy(), out[:, 7] * g, mode,
                   out[:, 4].copy(), FrictionState(theta, np.asarray(q, float).copy()))

    @property
    def modes(self) -> tuple[int, ...]:
        """Stick/slip pattern (a key: the continuation compares it step to step)."""
        return tuple(int(m) for m in self.mode)


def contact_tuple(st: Stations, theta: np.ndarray, dd: np.ndarray, arr: RobotArrays
                  ) -> tuple[np.ndarray, ...]:
    """The kernels' contact argument (contact.apply_stations) with fresh output and scratch
    arrays; its element 12 is the (K, 8) output of the last pass."""
    n = arr.k.shape[0]
    return (st.b, st.pair, st.lmax, st.hl, st.hr, st.tip, theta, dd, arr.gap, arr.rc, arr.lmin,
            st.prm, np.zeros((st.count, N_OUT)), np.empty(2 * n), np.empty((4, n)),
            np.empty((n, 2)), np.empty(n))
