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
from ctrkin.mechanics.contact import (
    FRESH,
    SLIP,
    ST_PAIR,
    STICK,
    gather_state,
    state_after,
    station_table,
)
from ctrkin.mechanics.settings import SolverSettings

__all__ = ["FRESH", "SLIP", "STICK", "ContactReport", "FrictionState", "Stations"]

N_OUT = 8  # per-station outputs of contact.station (the kernels' cout (K, N_OUT))


@dataclass(frozen=True, eq=False)
class Stations:
    """The friction stations of one grid (contact.station_table), K of them. table (K, 6): the
    kernels' per-station array (breakpoint, pair, ℓ_max mm, h_left mm, h_right mm, tip 0/1);
    pairs (P, 3): the per-pair array (gap mm, contact radius mm, shortest couple mm); slot (K,):
    state slot; s (K,) mm: arc length; prm (4,) = (μ, ε mm, clearance, distributed 0/1)
    (contact.apply_stations); relaxed (K + P,): the kernels' cvar without a state (every θ NaN,
    no translation)."""

    table: np.ndarray
    pairs: np.ndarray
    slot: np.ndarray
    s: np.ndarray
    prm: np.ndarray
    relaxed: np.ndarray

    @classmethod
    def build(cls, arr: RobotArrays, bounds: np.ndarray, present: np.ndarray, code: np.ndarray,
              tips: np.ndarray, settings: SolverSettings) -> Stations:
        # one compiled call (a translating step's hot path), the one warm.friction_moving_run makes
        table, slot, b = station_table(bounds, present, code, tips, arr.slots)
        k, p = b.shape[0], arr.gap.shape[0]
        pairs = np.empty((p, 3))
        pairs[:, 0], pairs[:, 1], pairs[:, 2] = arr.gap, arr.rc, arr.lmin
        prm = np.array([arr.friction, settings.stick_mm, arr.clearance,
                        1.0 if settings.distributed_friction else 0.0])
        relaxed = np.full(k + p, np.nan)
        relaxed[k:] = 0.0
        return cls(table, pairs, slot, bounds[b], prm, relaxed)

    @property
    def count(self) -> int:
        return int(self.slot.shape[0])

    @property
    def pair(self) -> np.ndarray:
        return self.table[:, ST_PAIR].astype(np.int64)


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

    @classmethod
    def after(cls, st: Stations, out: np.ndarray, q: np.ndarray, size: int) -> FrictionState:
        """The state after a converged solve whose stations gave out (K, 8) (contact.state_after:
        each element's offset moved by its slip, C6). size: P · slots."""
        return cls(state_after(st.slot, out, st.table, st.pairs, st.prm[1], size), q)

    def gather(self, st: Stations, q: np.ndarray) -> np.ndarray:
        """The kernels' cvar (K + P,) of this state at joints q (2N,): θ of the stations, then each
        pair's relative translation since the state (contact.gather_state)."""
        return gather_state(self.theta, st.slot, q, self.q)


@dataclass(frozen=True, eq=False)
class ContactReport:
    """The contacts of one equilibrium: stations (where, which pair), out (K, 8) their outputs
    (contact.station) and state, the friction state after this equilibrium (C6)."""

    stations: Stations
    out: np.ndarray
    state: FrictionState

    @property
    def s(self) -> np.ndarray:
        """(K,) mm: arc length of each contact."""
        return self.stations.s

    @property
    def pair(self) -> np.ndarray:
        """(K,): the inner tube of each contact's pair (0-based)."""
        return self.stations.pair

    @property
    def normal(self) -> np.ndarray:
        """(K,) N: contact force N_c + N_d (C2, C3)."""
        return self.out[:, 2]

    @property
    def bound(self) -> np.ndarray:
        """(K,) N·mm: the friction bound μ r N (C4)."""
        return self.out[:, 7]

    @property
    def torque(self) -> np.ndarray:
        """(K,) N·mm: the friction torque f (−f on the inner tube, +f on the outer; C5)."""
        return self.out[:, 7] * self.out[:, 1]

    @property
    def mode(self) -> np.ndarray:
        """(K,): FRESH, STICK or SLIP."""
        return self.out[:, 3].astype(np.int64)

    @property
    def tilt(self) -> np.ndarray:
        """(K,) rad: the clearance tilt at an outer tube's tip (C7)."""
        return self.out[:, 4]

    @property
    def modes(self) -> bytes:
        """Stick/slip pattern (a key: the continuation compares it step to step)."""
        return self.out[:, 3].tobytes()
