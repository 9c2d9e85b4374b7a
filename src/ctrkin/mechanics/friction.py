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
    PR_DD,
    PR_RC,
    SLIP,
    ST_PAIR,
    ST_THETA,
    STICK,
    build_stations,
)
from ctrkin.mechanics.settings import SolverSettings

__all__ = ["FRESH", "SLIP", "STICK", "ContactReport", "FrictionState", "Stations"]

N_OUT = 8  # per-station outputs of contact.station (the kernels' cout (K, N_OUT))


@dataclass(frozen=True, eq=False)
class Stations:
    """The friction stations of one grid (contact.build_stations), K of them. table (K, 7): the
    kernels' per-station array (breakpoint, pair, ℓ_max mm, h_left mm, h_right mm, tip 0/1, θ =
    NaN); pairs (P, 4): the per-pair array (Δd = 0, gap mm, contact radius mm, shortest couple mm);
    slot (K,): state slot; s (K,) mm: arc length; prm (4,) = (μ, ε mm, clearance, distributed
    0/1) (contact.apply_stations)."""

    table: np.ndarray
    pairs: np.ndarray
    slot: np.ndarray
    s: np.ndarray
    prm: np.ndarray

    @classmethod
    def build(cls, arr: RobotArrays, bounds: np.ndarray, present: np.ndarray, code: np.ndarray,
              tips: np.ndarray, settings: SolverSettings) -> Stations:
        b, pair, slot, lmax, hl, hr, tip = build_stations(bounds, present, code, tips, arr.slots)
        table = np.column_stack([b, pair, lmax, hl, hr, tip, np.full(b.shape[0], np.nan)])
        pairs = np.column_stack([np.zeros(arr.gap.shape[0]), arr.gap, arr.rc, arr.lmin])
        prm = np.array([arr.friction, settings.stick_mm, arr.clearance,
                        1.0 if settings.distributed_friction else 0.0])
        return cls(table, pairs, slot, bounds[b], prm)

    @property
    def count(self) -> int:
        return int(self.slot.shape[0])

    @property
    def pair(self) -> np.ndarray:
        return self.table[:, ST_PAIR].astype(np.int64)

    def arrays(self, theta: np.ndarray | None, dd: np.ndarray | None
               ) -> tuple[np.ndarray, np.ndarray]:
        """The kernels' cst (K, 7) and cpr (P, 4) for stuck offsets theta (K,) and relative
        translations dd (P,) (None: fresh contacts, no translation)."""
        cst, cpr = self.table, self.pairs
        if theta is not None:
            cst = cst.copy()
            cst[:, ST_THETA] = theta
        if dd is not None and dd.any():
            cpr = cpr.copy()
            cpr[:, PR_DD] = dd
        return cst, cpr


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
        """The state after a converged solve whose stations gave out (K, 8) (contact.station): each
        element's offset moved by its slip (C6), a fresh one set where it is; a contact that is
        not a station any more loses its state. size: P · slots."""
        theta = np.full(size, np.nan)
        phi, g = out[:, 0], out[:, 1]
        eps_t = st.prm[1] / st.pairs[st.table[:, ST_PAIR].astype(np.int64), PR_RC]
        theta[st.slot] = np.where(out[:, 3] == FRESH, phi, phi - eps_t * g)
        return cls(theta, q)

    def gather(self, st: Stations, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """θ (K,) of the stations of a grid and dd (P,): each pair's relative translation
        Δ(β_p − β_{p+1}) (mm) from this state's joints to q (2N,)."""
        n = q.shape[0] // 2
        dd = (q[n:2 * n - 1] - self.q[n:2 * n - 1]) - (q[n + 1:] - self.q[n + 1:])
        return self.theta[st.slot], dd


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
