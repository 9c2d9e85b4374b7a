"""Play-operator lags of the commanded joints: a memory of the joint path that no friction law shapes
(docs/learned_kinematics.md: Play lags as FK inputs).

Rate-independent hysteresis (backlash, friction wind-up, tubes sticking to each other) is, to first
order, a non-negative sum of play operators of the inputs (a Prandtl–Ishlinskii basis; Brokate and
Sprekels 1996, Kuhnen 2003). Each operator of half width r follows its input x with a dead band:

    y_t = min(max(y_{t−1}, x_t − r), x_t + r),   y = x at rest
    L_r(x)_t = (x_t − y_t) / r ∈ [−1, 1]         (the fraction of its play taken up)

The inputs are α1, αN (deg) and the relative translation d = βN − β1 (mm), the joints that set where
a pair of tubes folds and how far it has wound up. The lags carry no simulator parameter: a robot
computes them from its commanded joints as they are recorded, and what they mean for the tip is
learned from data (a network's inputs, `FeatureLayout(play=True)`) or identified (the snap form of
ctrkin.families.snap_aware.play).

Along a recorded dataset the operators run along each whole run (the `run` column, as m_N does:
ctrkin.models.motion): the unrecorded move between two sequences of a run is one step from the end of
one to the start of the next; a run starts at rest (every lag 0); glitch rows (`outlier`) repeat the
last believed joints. Streaming (`PlayState`) keeps the operators' outputs from step to step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from ctrkin.models.motion import run_continues

# the half widths of an FK's play-lag inputs: a Prandtl–Ishlinskii basis from the smallest backlash to
# the widest hysteresis loop of base rotation measured on the virtual robot (35–77°,
# docs/learned_kinematics.md: Memory), and from a lead screw's dead band to a millimetre of slide
INPUT_ANGLE_WIDTHS_DEG = (2.0, 5.0, 15.0, 45.0, 90.0)
INPUT_SLIDE_WIDTHS_MM = (0.05, 0.2, 1.0)


@dataclass(frozen=True)
class Lags:
    """Play lags along a path (fractions of each width): inner (T, K) of α1, outer (T, K) of αN,
    slide (T, J) of d."""

    inner: np.ndarray
    outer: np.ndarray
    slide: np.ndarray

    def mid(self, t: int) -> Lags:
        """Mid-way between rows t−1 and t, each (1, ·)."""
        return Lags(*(0.5 * (a[t:t + 1] + a[t - 1:t]) for a in (self.inner, self.outer, self.slide)))

    def columns(self) -> np.ndarray:
        """(T, 2K + J): inner, outer, slide side by side (an FK's play inputs, `play_names`)."""
        return np.concatenate([self.inner, self.outer, self.slide], axis=1)


@njit(cache=True)
def _lags(x: np.ndarray, starts: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """(T, K) lags (x − y) / r of the play operators along x (T,); starts (T,): a run starts at rest."""
    out = np.empty((len(x), len(widths)))
    y = np.zeros(len(widths))
    for t in range(len(x)):
        if starts[t]:
            y[:] = x[t]
        for k in range(len(widths)):
            y[k] = min(max(y[k], x[t] - widths[k]), x[t] + widths[k])
            out[t, k] = (x[t] - y[k]) / widths[k]
    return out


def play_inputs(joints: np.ndarray, n_tubes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The operators' inputs of joints (T, 2N): α1, αN (deg) and d = βN − β1 (mm), each (T,)."""
    q = np.asarray(joints, float)
    n = n_tubes
    return q[:, 0], q[:, n - 1], q[:, 2 * n - 1] - q[:, n]


def _believed_path(values: np.ndarray, bounds: list[tuple[int, int]], runs: np.ndarray | None,
                   skip: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """A copy of the path's rows (T, K) with each skipped row at the last believed one, and (T,) where
    the operators start at rest: each sequence that does not continue its run (runs (T,), file order)."""
    x = np.asarray(values, float).copy()
    if skip is not None:
        for g in np.nonzero(skip)[0]:
            x[g] = x[g - 1] if g > 0 else x[g]
    starts = np.zeros(len(x), dtype=np.bool_)
    for (a, b), cont in zip(bounds, run_continues(bounds, runs), strict=True):
        if b > a and not cont:
            starts[a] = True
    return x, starts


def path_lags(joints: np.ndarray, bounds: list[tuple[int, int]], n_tubes: int,
              runs: np.ndarray | None = None, skip: np.ndarray | None = None,
              angle_widths: tuple[float, ...] = INPUT_ANGLE_WIDTHS_DEG,
              slide_widths: tuple[float, ...] = INPUT_SLIDE_WIDTHS_MM) -> Lags:
    """The play lags of α1, αN and d = βN − β1 along the joint path (T, 2N) (module docstring):
    sequences of one run (runs (T,), file order) are one path, else each starts at rest; skip (T,):
    rows whose joints are not to be believed."""
    q, starts = _believed_path(joints, bounds, runs, skip)
    widths = (angle_widths, angle_widths, slide_widths)
    return Lags(*(_lags(np.ascontiguousarray(x), starts, np.asarray(w, float))
                  for x, w in zip(play_inputs(q, n_tubes), widths, strict=True)))


def recorded_lags(frame: Any, joints: np.ndarray, bounds: list[tuple[int, int]], n_tubes: int,
                  angle_widths: tuple[float, ...] = INPUT_ANGLE_WIDTHS_DEG,
                  slide_widths: tuple[float, ...] = INPUT_SLIDE_WIDTHS_MM) -> Lags:
    """path_lags of a Dataset's rows (its frame, joints (T, 2N) as recorded, its sequences): runs
    followed across sequences, glitch rows skipped."""
    runs = frame["run"].to_numpy() if "run" in frame.columns else None
    return path_lags(joints, bounds, n_tubes, runs, frame["outlier"].to_numpy(), angle_widths, slide_widths)


# the half widths (mm) of the play operators of a target path's position (the follow IK's play
# inputs, `target_lags`): from the tracker's noise to the size of a tube's hysteresis loop at the tip
TARGET_WIDTHS_MM = (0.3, 1.0, 3.0, 10.0)
TARGET_AXES = ("x", "y", "z")


def target_lags(positions: np.ndarray, bounds: list[tuple[int, int]], runs: np.ndarray | None = None,
                skip: np.ndarray | None = None) -> np.ndarray:
    """(T, 3K) lags of the play operators (TARGET_WIDTHS_MM) of a path of tip positions (T, 3) (mm,
    tracker frame), x then y then z: a memory of where the targets came from, which a follow IK has
    exactly (they are its inputs). Sequences of one run (runs (T,), file order) are one path, else
    each starts at rest; skip (T,): rows whose positions are not to be believed (the last believed
    ones are kept)."""
    x, starts = _believed_path(np.asarray(positions, float)[:, :3], bounds, runs, skip)
    widths = np.asarray(TARGET_WIDTHS_MM, float)
    if not len(x):
        return np.empty((0, 3 * len(widths)))
    return np.concatenate([_lags(np.ascontiguousarray(x[:, k]), starts, widths) for k in range(3)], axis=1)


def recorded_target_lags(frame: Any, poses: np.ndarray, bounds: list[tuple[int, int]]) -> np.ndarray:
    """target_lags of a Dataset's rows (its frame, poses (T, ≥3) as recorded, its sequences): runs
    followed across sequences, glitch rows skipped (as `recorded_lags` for the joints)."""
    runs = frame["run"].to_numpy() if "run" in frame.columns else None
    return target_lags(poses, bounds, runs, frame["outlier"].to_numpy())


def target_play_names() -> list[str]:
    """Names of a follow IK's play-lag inputs, in `target_lags` order (widths in mm)."""
    return [f"play_{a}_{r:g}" for a in TARGET_AXES for r in TARGET_WIDTHS_MM]


class TargetPlay:
    """The play operators of `target_lags` while streaming: `reset` starts at rest (the next position
    sets every output to itself), `advance(p)` moves them to position p (3,) and gives the lags (3K,)."""

    def __init__(self) -> None:
        self.widths = np.asarray(TARGET_WIDTHS_MM, float)
        self.y: np.ndarray | None = None

    def reset(self) -> None:
        self.y = None

    def advance(self, p: np.ndarray) -> np.ndarray:
        x = np.asarray(p, float)[:3, None]
        y = np.repeat(x, len(self.widths), axis=1) if self.y is None else self.y
        self.y = np.minimum(np.maximum(y, x - self.widths), x + self.widths)
        return ((x - self.y) / self.widths).reshape(-1)


def play_names(n_tubes: int) -> list[str]:
    """Names of an FK's play-lag inputs, in `Lags.columns` order (widths in deg, mm)."""
    def w(x: float) -> str:
        return f"{x:g}"
    return ([f"play_alpha_1_{w(r)}" for r in INPUT_ANGLE_WIDTHS_DEG]
            + [f"play_alpha_{n_tubes}_{w(r)}" for r in INPUT_ANGLE_WIDTHS_DEG]
            + [f"play_d_{w(r)}" for r in INPUT_SLIDE_WIDTHS_MM])


def input_operators() -> tuple[np.ndarray, np.ndarray]:
    """(widths (P,), the input each operator follows (P,): 0 α1, 1 αN, 2 d) of an FK's play inputs,
    in `play_names` order."""
    k, j = len(INPUT_ANGLE_WIDTHS_DEG), len(INPUT_SLIDE_WIDTHS_MM)
    return (np.array(INPUT_ANGLE_WIDTHS_DEG * 2 + INPUT_SLIDE_WIDTHS_MM, float),
            np.repeat(np.arange(3), (k, k, j)))


def slide_operators() -> tuple[np.ndarray, np.ndarray]:
    """(half widths (J,), inputs (J,): all d) of the play operators of d alone at an FK's widths: a
    fold gate's slide memory (ctrkin.families.snap_aware.fold_gate), run by PlayState and the fused
    step."""
    return np.array(INPUT_SLIDE_WIDTHS_MM, float), np.full(len(INPUT_SLIDE_WIDTHS_MM), 2.0)


@njit(cache=True)
def play_step(raw, n, widths, source, y, lags):
    """One step of the play operators: their outputs y (P + 1,: the last the at-rest flag) advanced to
    joints raw (2N,) (the inputs `source` (P,): 0 α1, 1 αN, 2 d; half widths `widths` (P,)), their
    lags written into lags (P,). PlayState and the fused step (ctrkin.models.fused) both run it."""
    p = widths.size
    rest = y[p] != 0.0
    for k in range(p):
        s = source[k]
        x = raw[0] if s == 0.0 else (raw[n - 1] if s == 1.0 else raw[2 * n - 1] - raw[n])
        yk = x if rest else y[k]
        yk = min(max(yk, x - widths[k]), x + widths[k])
        y[k] = yk
        lags[k] = (x - yk) / widths[k]
    y[p] = 0.0


class PlayState:
    """The play operators of an FK's inputs while streaming: `after` gives the lags (P,) a step to
    joints (2N,) would leave, `advance` takes that step, `peek` the lags (K, P) of K candidate next
    steps (the refined IK's probes); `reset` starts at rest (the next step sets every output to its
    input). buf (P + 1,): where the outputs and, last, the at-rest flag live (the fused step's state,
    ctrkin.models.fused, so that both paths share one state; taken as it is); default its own, at
    rest. operators: (half widths (P,), inputs (P,): 0 α1, 1 αN, 2 d), default an FK's play inputs
    (`input_operators`; the fold gate's slide memory runs its own)."""

    def __init__(self, n_tubes: int, buf: np.ndarray | None = None,
                 operators: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        self.n = n_tubes
        self.widths, which = input_operators() if operators is None else operators
        self.widths = np.ascontiguousarray(self.widths, dtype=np.float64)
        self.source = np.ascontiguousarray(which, dtype=np.float64)
        p = len(self.widths)
        self.buf = np.r_[np.zeros(p), 1.0] if buf is None else buf
        if self.buf.shape != (p + 1,):
            raise ValueError(f"a play state's buffer holds {p + 1} values, got shape {self.buf.shape}")

    def reset(self) -> None:
        self.buf[-1] = 1.0

    def after(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lags (P,), the operators' outputs (P,)) after a step to joints q (2N,), nothing changed."""
        y = self.buf.copy()
        lags = np.empty(len(self.widths))
        play_step(np.ascontiguousarray(q, dtype=np.float64), self.n, self.widths, self.source, y, lags)
        return lags, y[:-1]

    def advance(self, y: np.ndarray) -> None:
        """Take the step whose outputs `after` gave."""
        self.buf[:-1] = y
        self.buf[-1] = 0.0

    def peek(self, Q: np.ndarray) -> np.ndarray:
        """(K, P) lags after a step to each of K joints Q (K, 2N), nothing changed."""
        Q = np.atleast_2d(np.asarray(Q, float))
        return np.array([self.after(q)[0] for q in Q]).reshape(len(Q), len(self.widths))
