"""What a protocol asks the robot to do: runs of segments of commanded motor joints.

A `Run` is what one robot does without interruption: it starts at rest at its first joints and its
state (equilibrium branch, backlash) carries over from segment to segment. A recorded `Segment`
becomes one dataset sequence (a continuous stretch that splits keep whole); an unrecorded one is a
transition the robot performs between sequences (e.g. the outer tube stepping 10°). Runs are
independent of each other, so they can be recorded in parallel.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ctrkin.errors import JointError

MAX_STEP_DEG = 1.0  # joint step of transitions and moves, as the paper's 1° increments
MAX_STEP_MM = 0.1


@dataclass(frozen=True, eq=False)
class Segment:
    """A stretch of commanded joints.

    Attributes
    ----------
    q : ndarray, shape (T, 2N)
        Commanded motor joints (deg, mm).
    record : bool
        True: it becomes one dataset sequence; False: a transition, performed but not recorded.
    level : int
        Index into `Plan.levels` (−1: none).
    is_target : ndarray of bool, shape (T,), optional
        Marks target configurations (random points).
    """

    q: np.ndarray
    record: bool = True
    level: int = -1
    is_target: np.ndarray | None = None

    def __post_init__(self) -> None:
        q = np.atleast_2d(np.asarray(self.q, dtype=float))
        object.__setattr__(self, "q", q)
        if self.is_target is not None:
            t = np.asarray(self.is_target, dtype=bool)
            if t.shape != (q.shape[0],):
                raise ValueError(f"Segment.is_target must have shape ({q.shape[0]},), got {t.shape}")
            object.__setattr__(self, "is_target", t)


@dataclass(frozen=True, eq=False)
class Run:
    """Segments performed one after the other by one robot, starting at rest at the first joints.

    Attributes
    ----------
    segments : tuple of Segment
        Empty segments are dropped; at least one must remain.
    """

    segments: tuple[Segment, ...]

    def __post_init__(self) -> None:
        segs = tuple(s for s in self.segments if s.q.shape[0] > 0)
        if not segs:
            raise ValueError("a Run needs at least one non-empty segment")
        object.__setattr__(self, "segments", segs)

    @property
    def start(self) -> np.ndarray:
        """(2N,) the joints the run starts from, at rest."""
        return self.segments[0].q[0]

    @property
    def n_steps(self) -> int:
        """Steps performed, transitions included."""
        return sum(s.q.shape[0] for s in self.segments)

    @property
    def n_samples(self) -> int:
        """Steps recorded."""
        return sum(s.q.shape[0] for s in self.segments if s.record)


@dataclass(frozen=True, eq=False)
class Plan:
    """What a protocol asks the robot to do.

    Attributes
    ----------
    protocol : str
        The protocol's name.
    runs : tuple of Run
        Independent runs (recorded in parallel).
    levels : tuple of dict
        Per level index a description, e.g. ``{"relative_translation_mm": 12.0}``.
    params : dict
        The protocol's resolved parameters (stored in the dataset's meta).
    """

    protocol: str
    runs: tuple[Run, ...]
    levels: tuple[dict[str, Any], ...] = ()
    params: dict[str, Any] = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        """Samples the plan records."""
        return sum(r.n_samples for r in self.runs)

    @property
    def n_steps(self) -> int:
        """Steps the robot performs, transitions included."""
        return sum(r.n_steps for r in self.runs)

    def all_joints(self) -> np.ndarray:
        """(S, 2N) every commanded joint vector, for validation."""
        return np.concatenate([s.q for r in self.runs for s in r.segments])


def move(a: np.ndarray, b: np.ndarray, n_tubes: int, max_deg: float = MAX_STEP_DEG,
         max_mm: float = MAX_STEP_MM) -> np.ndarray:
    """A straight line in joint space, in small steps.

    The valid joint set is convex (linear inequalities), so a move between valid joints stays valid.

    Parameters
    ----------
    a, b : ndarray, shape (2N,)
        From (excluded) and to (included), deg and mm.
    n_tubes : int
        N.
    max_deg, max_mm : float
        Largest step of a rotation (deg) and of a translation (mm).

    Returns
    -------
    ndarray, shape (K, 2N)
        K = 0 when a == b.

    Raises
    ------
    JointError
        If a and b differ in shape.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.shape != b.shape:
        raise JointError(f"move: joint vectors of different shapes {a.shape} and {b.shape}")
    delta = b - a
    k = int(np.ceil(max(np.abs(delta[:n_tubes]).max(initial=0.0) / max_deg,
                        np.abs(delta[n_tubes:]).max(initial=0.0) / max_mm) - 1e-9))
    if k <= 0:
        return np.empty((0, a.shape[0]))
    frac = np.arange(1, k + 1) / k
    return a + frac[:, None] * delta


def transition(a: np.ndarray, b: np.ndarray, n_tubes: int) -> Segment:
    """An unrecorded move from a towards b that stops one step short of b (where the next recorded
    segment starts)."""
    path = move(a, b, n_tubes)
    return Segment(path[:-1], record=False)
