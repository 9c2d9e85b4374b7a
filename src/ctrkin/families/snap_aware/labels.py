"""Which equilibrium branch each sample of a dataset is on: the labels a snap-aware model learns.

A two-tube pair at full curved overlap is bistable in a band of relative rotation around α0 = 180°
(docs/mechanics.md: Model, ψ'' = c·sin ψ linearised about ψ = π). With φ = α0 − 180° wrapped to
[−180°, 180°):

    φ well below the band  -> one equilibrium, continuous with the "lower" branch (label 0)
    φ well above the band  -> one equilibrium, continuous with the "upper" branch (label 1)
    inside the band         -> both are stable; the robot stays on the branch it entered with until
                               it leaves the band, either back the way it came or by a snap at the
                               far fold: forward (α0 increasing) snaps land on 1, backward on 0.

So the label is a relay on φ whose switching points are the folds, which the data shows as snaps
(the `snap` column). Outside |φ| > band_deg the label is forced by the sign of φ; that includes the
wrap at φ = ±180°, where the label changes but the pose does not (the same configuration).

At a sequence start inside the band the branch is read ahead: the first snap (forward: the start was
on 0; backward: on 1) or, failing that, the side on which the sequence first leaves the band.
band_deg (90° by default) only has to exceed the band's half-width; it is not fitted.
"""

from __future__ import annotations

import numpy as np

from ctrkin.metrics import wrap_deg

BAND_DEG = 90.0


def phase_deg(alpha0: np.ndarray) -> np.ndarray:
    """φ = α0 − 180° wrapped to [−180°, 180°) (deg)."""
    return wrap_deg(np.asarray(alpha0, float) - 180.0)


def snap_events(snap: np.ndarray, a: int, b: int) -> np.ndarray:
    """Rows n in (a, b) where a snap starts: flagged rows, consecutive flags merged into one event.
    A flag on the first row (a snap during an unrecorded move into the sequence) is not an event
    inside the sequence: the start state already shows it."""
    flags = np.asarray(snap[a:b], bool).copy()
    if len(flags):
        flags[0] = False
    rows = np.nonzero(flags)[0]
    if len(rows) == 0:
        return rows + a
    keep = np.r_[True, np.diff(rows) > 1]
    return rows[keep] + a


def branch_labels(alpha0: np.ndarray, snap: np.ndarray, bounds: list[tuple[int, int]],
                  band_deg: float = BAND_DEG) -> tuple[np.ndarray, np.ndarray]:
    """alpha0: (T,) relative rotation α1 − αN (deg, unwrapped); snap: (T,) flags; bounds: sequences.

    Returns labels (T,) int8 in {0, 1} and forced (T,) bool: rows whose label does not depend on the
    previous state: outside the band, and past a fold in the direction of the snap (until the motion
    turns or leaves the band), where the branch the robot snapped from no longer exists."""
    a0 = np.asarray(alpha0, float)
    phi = phase_deg(a0)
    forced = np.abs(phi) > band_deg
    labels = np.zeros(len(a0), dtype=np.int8)
    for a, b in bounds:
        if b <= a:
            continue
        events = set(snap_events(snap, a, b).tolist())
        direction = np.sign(np.diff(a0[a:b], prepend=a0[a]))
        cur = _start_state(phi, forced, direction, events, a, b)
        beyond = 0      # +1 / −1: moving on past a forward / backward fold, where one branch is left
        for t in range(a, b):
            d = direction[t - a]
            if t in events and d != 0:
                cur = 1 if d > 0 else 0
                beyond = int(d)
            elif forced[t]:
                cur = 1 if phi[t] > 0 else 0
            if beyond and (d != beyond or forced[t]):
                beyond = 0
            if beyond:
                forced[t] = True
            labels[t] = cur
    return labels, forced


def _start_state(phi: np.ndarray, forced: np.ndarray, direction: np.ndarray, events: set[int],
                 a: int, b: int) -> int:
    for t in range(a, b):
        if t in events and direction[t - a] != 0:
            return 0 if direction[t - a] > 0 else 1      # the snap leaves the branch it was on
        if forced[t]:
            return 1 if phi[t] > 0 else 0
    return 1 if phi[a] > 0 else 0


def previous_labels(labels: np.ndarray, bounds: list[tuple[int, int]], unknown: float = 0.5
                    ) -> np.ndarray:
    """(T,) float32: the label of the previous row of the same sequence, `unknown` at a start."""
    prev = np.empty(len(labels), dtype=np.float32)
    prev[1:] = labels[:-1]
    for a, b in bounds:
        if b > a:
            prev[a] = unknown
    return prev
