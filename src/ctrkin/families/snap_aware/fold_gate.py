"""The fold gate: a snap-aware model's branch state from the robot's folds
(docs/learned_kinematics.md: The fold gate).

A learned gate (ctrkin.families.snap_aware.net) places each switch where its classifier boundary lies, a few
degrees from the fold, and it has to learn from a few dozen snaps how the fold moves with the
translations. The fold gate takes that dependence from the physics and the offsets from the data:

    θ+ = g·φ+(β) + w − κ·m_N ,  θ− = g·φ−(β) − w − κ·m_N ,   w = c − Σ_k u_k·|ℓ_k|
        φ±: folds of the nominal TCM (ctrkin.mechanics.folds), tabulated over the training translations
        m_N ∈ {−1, 0, +1}: direction of the outer tube's last rotation (0: at rest since the run began)
        ℓ_k ∈ [−1, 1]: the slide memory, play-operator lags of the relative translation d = βN − β1 at
              half widths SLIDE_WIDTHS_MM (ctrkin.models.play_lags, along the commanded joints): how far
              a slide of one tube against the other since the last reversal of d has taken up each play
        g: 1 (the nominal folds' size), or with `fold_scale` fitted in [G_MIN, G_MAX] and kept only
              where it lowers the leave-one-run-out residual (a robot whose folds change with the
              overlap less or more than the nominal robot's: measured by bench_fold_gate.py, not the
              default)
        c, κ, u_k ≥ 0: bounded least squares on the training snaps, each weighted by φ±² (near the
              critical overlap the fold moves fast with the tube parameters, so there it says little
              about the offset); the slide memory is kept only where it lowers the leave-one-run-out
              residual of the training snaps (`_fit_offsets`), else u = 0 (the form without it)
    a snap flagged at row t lies between rows t−1 and t: the fold is taken mid-way, for the table
    (sweeps at 0.5°) and for the data alike.
    s_t = 1 if φ_t > band, 0 if φ_t < −band          outside the bistable band one branch exists
        = 1 if s_{t−1} = 0 and φ_t ≥ θ+              past the forward fold: snap to the upper branch
        = 0 if s_{t−1} = 1 and φ_t < θ−              past the backward fold: snap to the lower branch
        = s_{t−1} otherwise;  at a sequence start 1[φ > 0]
    where the nominal pair does not snap (|φ±| < MIN_FOLD_DEG) θ± = ±band: the state changes only
    outside the band, as the labels the heads learned from do (ctrkin.families.snap_aware.labels).
    A recording with no snap at all gives a gate with no fold (θ± = ±band everywhere): the nominal
    folds are not assumed where the robot never snapped (a three-tube robot at μ 0.69 does not).

with φ = α0 − 180° wrapped (ctrkin.families.snap_aware.labels, the labels the heads were trained on).
Why |ℓ|: on the default robot a slide of either tube, of 0.2 mm or of 4 mm, either way, before a turn
moves both of its snaps towards the nominal folds by the same 6–9° (the history probe in
docs/learned_kinematics.md: What the learned models assume about the robot): the friction the slide
left along the tubes, a state that no joint reading shows. The form assumes only that the delay's
change saturates with the slide (a play's lag) and does not depend on its direction (|ℓ|); the sizes
u_k are identified from the snaps that follow slides (the excitation runs) and are 0 where no training
snap follows one.
Why m_N: the encoders read the motors, and a tube base lags its motor by up to half the transmission's
dead band, on the side it last moved from (backlash and friction wind-up, a play operator). The inner
tube's lag is set by the turn itself: it widens the band symmetrically, as does a fold of the real
tubes wider than the nominal one (c). The outer tube's was set before the sequence (an unrecorded move
to its angle, or rest) and shifts both folds the same way (κ). Forward and backward snaps separate the
two even when every snap of the data has the same m_N. m_N is read from the joint path, carried across
the sequences of one run (the `run` column, glitch rows skipped) and reset at rest; so is the
branch state, which the unrecorded move between two sequences of a run does not reset either.
θ+ ≥ θ− always (no chattering where the pair is not bistable and both are 0). The table is
interpolated multilinearly in β and clamped at the edges of the trained range.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import lsq_linear

from ctrkin.errors import ModelError
from ctrkin.families.snap_aware.labels import BAND_DEG, phase_deg, snap_events
from ctrkin.mechanics.folds import fold_angles
from ctrkin.models.play_lags import (
    INPUT_SLIDE_WIDTHS_MM,
    PlayState,
    path_lags,
    recorded_lags,
    slide_operators,
)
from ctrkin.models.relay import (
    MIN_FOLD_DEG,
    GateTables,
    gate_step,
    interpolate_rows,
    relay_scan,
    threshold_rows,
)
from ctrkin.models.store import read_json, write_json
from ctrkin.robots.robot import Robot

FOLD_GATE_FILE = "fold_gate.json"
MAX_GRID_POINTS = 400       # translations at which the folds are computed (≈ 0.07 s each, paper robot)
FOLD_STEP_DEG = 0.5         # the table's sweep step
G_MIN, G_MAX = 0.25, 2.0    # the bounds of a fitted fold scale g
SLIDE_WIDTHS_MM = INPUT_SLIDE_WIDTHS_MM    # the slide memory's play widths: an FK's play inputs of d


def slide_lags(data: Any, joints: np.ndarray, bounds: list[tuple[int, int]], n_tubes: int) -> np.ndarray:
    """(T, K) the slide memory's lags ℓ along joints (T, 2N): of a Dataset (`data`) as recorded, its
    runs followed and glitch rows skipped (ctrkin.models.play_lags.recorded_lags); of an array, each
    sequence from rest."""
    if hasattr(data, "frame"):
        return recorded_lags(data.frame, joints, bounds, n_tubes, (), SLIDE_WIDTHS_MM).slide
    return path_lags(joints, bounds, n_tubes, angle_widths=(), slide_widths=SLIDE_WIDTHS_MM).slide


@dataclass(frozen=True, eq=False)
class FoldGate:
    """axes: per tube, the grid of β (mm, increasing); forward, backward: fold tables φ± (deg) of
    shape (len(axes[0]), …); widen_deg: c; outer_lag_deg: κ; band_deg: half-width of the band;
    fold_scale: g; in_use: whether the model switches branches by this gate (False where its
    validation rows chose the learned gate, ctrkin.families.snap_aware.gate_choice; the gate then
    stays in the folder for `predict(..., gate="fold")`). `tables` holds the grid flattened, the folds
    times g, for the relay's numba kernels (ctrkin.models.relay: the batch scan, and `gate_step` in the
    fused FK step)."""

    axes: tuple[np.ndarray, ...]
    forward: np.ndarray
    backward: np.ndarray
    widen_deg: float = 0.0
    outer_lag_deg: float = 0.0
    band_deg: float = BAND_DEG
    slide_weights_deg: tuple[float, ...] = ()
    fold_scale: float = 1.0
    in_use: bool = True
    tables: GateTables = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.fold_scale) and self.fold_scale > 0):
            raise ModelError(f"a fold gate's fold scale must be finite and > 0, got {self.fold_scale}")
        object.__setattr__(self, "tables", GateTables.of(self, self.fold_scale))
        if self.slide_weights_deg and len(self.slide_weights_deg) != len(SLIDE_WIDTHS_MM):
            raise ModelError(f"a fold gate's slide memory has {len(SLIDE_WIDTHS_MM)} weights, got "
                             f"{len(self.slide_weights_deg)}")

    @property
    def slides(self) -> bool:
        """Whether the gate has a slide memory (some u_k > 0): it then needs the lags ℓ of d."""
        return any(u > 0 for u in self.slide_weights_deg)

    def widen(self, slide_lags: np.ndarray | None = None) -> np.ndarray:
        """w = c − Σ u_k |ℓ_k| (deg) at each row of slide_lags (T, K) (None or no memory: c), (T,) or
        (1,)."""
        if not self.slides or slide_lags is None:
            return np.full(1 if slide_lags is None else len(slide_lags), self.widen_deg)
        ell = np.atleast_2d(slide_lags)
        total = np.zeros(len(ell))
        for k, u in enumerate(self.slide_weights_deg):      # term by term: the fused step's order
            total += u * np.abs(ell[:, k])
        return self.widen_deg - total

    def folds(self, betas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """betas (T, N) -> the folds g·φ+ (T,), g·φ− (T,) in deg, interpolated."""
        betas = np.atleast_2d(np.asarray(betas, float))
        if betas.shape[1] != len(self.axes):
            raise ModelError(f"the fold gate is for {len(self.axes)} tubes, got translations of shape "
                             f"{betas.shape}")
        tb = self.tables
        x = np.ascontiguousarray(betas)
        return (interpolate_rows(tb.axes, tb.start, tb.size, tb.forward, x),
                interpolate_rows(tb.axes, tb.start, tb.size, tb.backward, x))

    def thresholds(self, betas: np.ndarray, outer_motion: np.ndarray | float = 0.0,
                   slide_lags: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """betas (T, N), outer_motion m_N (T,) or scalar, slide_lags ℓ (T, K) (`slide_lags`; needed
        where the gate `slides`) -> switching phases θ+, θ− (T,) deg, θ+ ≥ θ−."""
        fwd, bwd = self.folds(betas)
        motion = np.ascontiguousarray(np.broadcast_to(np.asarray(outer_motion, float), fwd.shape))
        widen = np.ascontiguousarray(np.broadcast_to(self.widen(slide_lags), fwd.shape), dtype=np.float64)
        return threshold_rows(fwd, bwd, motion, widen, self.outer_lag_deg, self.band_deg)

    def states(self, alpha0: np.ndarray, betas: np.ndarray, outer_motion: np.ndarray,
               bounds: list[tuple[int, int]], continues: list[bool] | None = None,
               slide_lags: np.ndarray | None = None) -> np.ndarray:
        """(T,) int8 branch states along each sequence. alpha0 (T,) deg, betas (T, N) mm,
        outer_motion (T,) m_N (ctrkin.models.motion.outer_motion); continues: per sequence, True
        where it continues the previous one's run (the branch is kept across the unrecorded move);
        slide_lags (T, K): ℓ along the same path (`slide_lags`), where the gate `slides`."""
        if self.slides and slide_lags is None:
            raise ModelError("this fold gate has a slide memory: states() needs the slide lags")
        phi = np.ascontiguousarray(phase_deg(alpha0), dtype=np.float64)
        hi, lo = self.thresholds(betas, outer_motion, slide_lags)
        keep = np.zeros(len(bounds), dtype=np.bool_) if continues is None else np.asarray(continues, np.bool_)
        edges = np.asarray(bounds, dtype=np.int64).reshape(-1, 2)
        return relay_scan(phi, hi, lo, edges, keep, self.band_deg)

    def step(self, state: int, alpha0: float, betas: np.ndarray, outer_motion: int,
             slide_lags: np.ndarray | None = None) -> int:
        """The state after one step from `state` (−1: a sequence start); slide_lags (K,): ℓ after
        this step (a `slide_state`'s), where the gate `slides`."""
        if self.slides and slide_lags is None:
            raise ModelError("this fold gate has a slide memory: step() needs the slide lags")
        tb = self.tables
        return int(gate_step(state, float(alpha0), np.ascontiguousarray(betas, dtype=np.float64),
                             float(outer_motion), tb.axes, tb.start, tb.size, tb.forward, tb.backward,
                             float(self.widen(slide_lags)[0]), self.outer_lag_deg, self.band_deg))

    def slide_state(self, n_tubes: int) -> PlayState | None:
        """The slide memory's operators for streaming (at rest), None where the gate has none."""
        return PlayState(n_tubes, operators=slide_operators()) if self.slides else None

    # --- files -----------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, object]:
        return {"axes_mm": [a.tolist() for a in self.axes], "forward_deg": self.forward.tolist(),
                "backward_deg": self.backward.tolist(), "widen_deg": self.widen_deg,
                "outer_lag_deg": self.outer_lag_deg, "band_deg": self.band_deg,
                "slide_widths_mm": list(SLIDE_WIDTHS_MM), "slide_weights_deg": list(self.slide_weights_deg),
                "fold_scale": self.fold_scale, "in_use": self.in_use}

    @classmethod
    def from_dict(cls, d: dict) -> FoldGate:
        try:
            axes = tuple(np.asarray(a, float) for a in d["axes_mm"])
            shape = tuple(len(a) for a in axes)
            fwd = np.asarray(d["forward_deg"], float).reshape(shape)
            bwd = np.asarray(d["backward_deg"], float).reshape(shape)
            widen = float(d["widen_deg"])
            lag = float(d["outer_lag_deg"])
            band = float(d["band_deg"])
            slide = tuple(float(u) for u in d.get("slide_weights_deg", ()))     # absent: an older gate
            widths = tuple(float(r) for r in d.get("slide_widths_mm", SLIDE_WIDTHS_MM))
            scale = float(d.get("fold_scale", 1.0))                               # absent: g = 1
            in_use = d.get("in_use", True)                                      # absent: the fold gate
        except (KeyError, ValueError, TypeError, IndexError) as e:
            raise ModelError(f"malformed fold gate ({type(e).__name__}: {e})") from None
        if not all(np.all(np.diff(a) > 0) for a in axes) or not (
                np.isfinite(fwd).all() and np.isfinite(bwd).all()
                and math.isfinite(widen) and math.isfinite(lag)):
            raise ModelError("malformed fold gate: axes must increase and tables be finite")
        if slide and (widths != SLIDE_WIDTHS_MM or not all(math.isfinite(u) and u >= 0 for u in slide)):
            raise ModelError(f"malformed fold gate: a slide memory at widths {list(SLIDE_WIDTHS_MM)} mm with "
                             f"finite weights ≥ 0, got widths {list(widths)} and weights {list(slide)}")
        if not (math.isfinite(scale) and scale > 0):
            raise ModelError(f"malformed fold gate: fold_scale must be finite and > 0, got {scale}")
        if not isinstance(in_use, bool):
            raise ModelError(f"malformed fold gate: in_use must be true or false, got {in_use!r}")
        return cls(axes, fwd, bwd, widen, lag, band, slide, scale, in_use)

    def save(self, folder: str | Path) -> None:
        write_json(Path(folder) / FOLD_GATE_FILE, self.to_dict())

    @classmethod
    def load(cls, folder: str | Path) -> FoldGate:
        return cls.from_dict(read_json(Path(folder) / FOLD_GATE_FILE))


def build_fold_gate(robot: Robot, joints: np.ndarray, snap: np.ndarray, bounds: list[tuple[int, int]],
                    motion: np.ndarray, spacing_mm: float = 1.0,
                    progress: Callable[[int, int], None] | None = None,
                    slide: np.ndarray | None = None, groups: np.ndarray | None = None,
                    fold_scale: bool = False) -> FoldGate:
    """The fold gate of `robot` over the translations of `joints` (T, 2N) (the training rows), its
    offsets fitted to the snaps flagged in `snap` (T,) within `bounds`; motion (T,): m_N of each row
    (ctrkin.models.motion.outer_motion, computed on the whole dataset so that runs are followed
    across the split); slide (T, K): the slide memory's lags ℓ of each row (`slide_lags`, on the
    whole dataset likewise; None: no slide memory); groups (T,): each row's run, the folds of the
    leave-one-run-out check that decides whether the slide memory is kept (`_fit_offsets`);
    fold_scale: also fit g (module docstring; default g = 1).
    spacing_mm: grid step, widened until the grid has at most MAX_GRID_POINTS points.
    progress(done, total) after each grid point."""
    joints = np.asarray(joints, float)
    n = robot.n_tubes
    betas = joints[:, n:]
    lo, hi = betas.min(axis=0), betas.max(axis=0)
    while True:
        counts = np.maximum(np.ceil((hi - lo) / spacing_mm).astype(int) + 1, 1)
        if np.prod(counts) <= MAX_GRID_POINTS:
            break
        spacing_mm *= 1.25
    axes = tuple(np.linspace(a, b, k) if k > 1 else np.array([a])
                 for a, b, k in zip(lo, hi, counts, strict=True))
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, n)
    shape = tuple(len(a) for a in axes)
    if not any(len(snap_events(snap, a, b)) for a, b in bounds):
        # the recording holds no snap (friction can carry the tubes across the nominal folds): the
        # gate has no fold either and switches only outside the band, as the heads' labels do
        if progress is not None:
            progress(len(grid), len(grid))
        return FoldGate(axes, np.zeros(shape), np.zeros(shape))
    fwd, bwd = fold_angles(robot, grid, step_deg=FOLD_STEP_DEG, progress=None if progress is None else
                           (lambda p: progress(p + 1, len(grid))))
    half = 0.5 * FOLD_STEP_DEG                    # mid-way between the last row before and the snap
    fwd, bwd = np.where(fwd > 0, fwd - half, 0.0), np.where(bwd < 0, bwd + half, 0.0)
    table = FoldGate(axes, fwd.reshape(shape), bwd.reshape(shape))
    widen, lag, weights, g = _fit_offsets(table, joints, snap, bounds, np.asarray(motion), n, slide, groups,
                                          fold_scale)
    return FoldGate(axes, table.forward, table.backward, widen, lag, slide_weights_deg=weights, fold_scale=g)


def _fit_offsets(gate: FoldGate, joints: np.ndarray, snap: np.ndarray, bounds: list[tuple[int, int]],
                 motion: np.ndarray, n: int, slide: np.ndarray | None = None,
                 groups: np.ndarray | None = None, fold_scale: bool = False
                 ) -> tuple[float, float, tuple[float, ...], float]:
    """c, κ, the slide weights u and g: weighted least squares of the data's snaps,
    φ_e − φ±(β_e) = (g − 1)·φ±(β_e) ± (c − Σ u_k |ℓ_k|) − κ·m_N with u ≥ 0, weights φ±(β_e)² (module
    docstring), φ_e and ℓ mid-way between the snap row and the one before. κ is 0 where the snaps
    cannot separate it from c (all of one direction and one m_N, or none with m_N ≠ 0). g (with
    `fold_scale`, in [G_MIN, G_MAX]) and then the slide memory (with `slide`) are each kept only where
    the leave-one-run-out weighted RMS residual over the snaps (runs: `groups`; at least two with
    snaps) is below the form's without them; else g = 1, u = ()."""
    alpha0 = joints[:, 0] - joints[:, n - 1]
    phi = phase_deg(alpha0)
    fwd, bwd = gate.folds(joints[:, n:])
    rows: list[tuple[int, float, float, float, int]] = []      # direction, m_N, residual, fold, row
    for a, b in bounds:
        for t in snap_events(snap, a, b):
            sign = int(np.sign(alpha0[t] - alpha0[t - 1]))
            fold = fwd[t] if sign > 0 else bwd[t]
            mid = phi[t] - 0.5 * (alpha0[t] - alpha0[t - 1])
            if sign != 0 and abs(phi[t]) < gate.band_deg and abs(fold) >= MIN_FOLD_DEG:
                rows.append((sign, float(motion[t]), float(mid - fold), float(fold), t))
    if not rows:
        return 0.0, 0.0, (), 1.0
    d, m, r, fold = (np.array(c, dtype=float) for c in list(zip(*rows, strict=True))[:4])
    at = np.array([row[4] for row in rows])
    sw = np.abs(fold)                                            # √ of the weights φ±²
    A = np.stack([d, -m], axis=1)
    if np.linalg.matrix_rank(A * sw[:, None]) < 2:
        A = A[:, :1]
    free = len(A[0])
    runs = None if groups is None else np.asarray(groups)[at]
    cv = runs is not None and len(np.unique(runs)) >= 2
    scaled = 0
    if fold_scale and cv:
        assert runs is not None
        S = np.concatenate([A, fold[:, None]], axis=1)
        if _loro_rms(S, r, sw, runs, free, 1) < _loro_rms(A, r, sw, runs, free):
            A, scaled = S, 1

    def read(x: np.ndarray) -> tuple[float, float, tuple[float, ...], float]:
        """(c, κ, u, g) of a solution [c, (κ), (g − 1), u...]."""
        u = tuple(float(v) for v in x[free + scaled:])
        return (float(x[0]), float(x[1]) if free > 1 else 0.0, u if any(v > 0 for v in u) else (),
                1.0 + float(x[free]) if scaled else 1.0)

    base = read(_weighted_fit(A, r, sw, free, scaled))
    if slide is None or not cv:
        return base
    assert runs is not None
    ell = np.abs(0.5 * (slide[at] + slide[at - 1]))             # |ℓ| mid-way, (E, K)
    B = np.concatenate([A, -d[:, None] * ell], axis=1)
    if not (ell > 0).any() or (_loro_rms(B, r, sw, runs, free, scaled)
                               >= _loro_rms(A, r, sw, runs, free, scaled)):
        return base
    return read(_weighted_fit(B, r, sw, free, scaled))


def _weighted_fit(A: np.ndarray, r: np.ndarray, sw: np.ndarray, free: int, scaled: int = 0) -> np.ndarray:
    """Least squares of A·x = r, rows weighted by sw: the first `free` unknowns free, then `scaled`
    (0 or 1) unknown g − 1 in [G_MIN − 1, G_MAX − 1], the rest ≥ 0."""
    rest = A.shape[1] - free - scaled
    lo = np.r_[np.full(free, -np.inf), np.full(scaled, G_MIN - 1.0), np.zeros(rest)]
    hi = np.r_[np.full(free, np.inf), np.full(scaled, G_MAX - 1.0), np.full(rest, np.inf)]
    return lsq_linear(A * sw[:, None], r * sw, bounds=(lo, hi)).x


def _loro_rms(A: np.ndarray, r: np.ndarray, sw: np.ndarray, runs: np.ndarray, free: int,
              scaled: int = 0) -> float:
    """The weighted RMS residual of each run's snaps under the fit to the other runs' (deg)."""
    err = np.empty(len(r))
    for g in np.unique(runs):
        out = runs == g
        err[out] = A[out] @ _weighted_fit(A[~out], r[~out], sw[~out], free, scaled) - r[out]
    return float(np.sqrt(np.sum(sw ** 2 * err ** 2) / np.sum(sw ** 2)))
