"""A snap's delay identified from the recorded joint path: play operators (a Prandtl–Ishlinskii form;
docs/learned_kinematics.md: What the learned models assume about the robot).

A candidate for the fold gate's constant delay, measured beside it by benchmarks/bench_fold_gate.py,
and NOT the gate's form: on the quick data it scored no better on the held-out sweeps, because what
moves their snaps is a history the paper protocol's training rows never excite (a slide of one tube
against the other just before the turn), so its weight cannot be identified from them (the doc's
table and history probe).

Where a pair of tubes snaps depends on their own relative rotation and overlap, which lag the motors'
by what each transmission's history left: backlash, friction wind-up, tubes sticking to each other.
Rate-independent hysteresis of that kind is, to first order, a non-negative sum of play operators
(Brokate and Sprekels 1996; the identification form of Kuhnen 2003), with no friction law assumed:

    play of width r, its lag L_r   ctrkin.models.play_lags (the operators, shared with the FK's
                                   play-lag inputs)
    inputs            α1, αN (deg; widths ANGLE_WIDTHS_DEG) and the relative translation
                      d = βN − β1 (mm; widths SLIDE_WIDTHS_MM)
    thresholds        θ± = g·φ±(β) ± c + Σ w_k L_k(α1) − Σ v_k L_k(αN) ∓ Σ u_k L_k(d)
                      w, v, u ≥ 0 (deg: each operator's share of the delay when fully
                      wound); g ≥ 0, c free

with φ = α0 − 180° wrapped (labels.phase_deg) and φ± the nominal folds (fold_gate). The angle terms
are the tubes' relative rotation lagging the motors'; the slide term is an overlap lagging the
commanded one, which narrows the bistable band (a smaller overlap is less bistable: the one physical
sign assumed). A snap at row t in the direction s of the turn, taken mid-way between rows t−1 and t,
gives one equation linear in x = (c, g, w, v, u):
    φ_mid = s·c + g·φ_s(β) + Σ w_k L_k(α1) − Σ v_k L_k(αN) − s·Σ u_k L_k(d).
`identify` solves them by bounded least squares with a ridge on (w, v, u) and on g − 1 (the nominal
folds as the prior), its weight chosen by leave-one-run-out cross-validation on the same (training)
snaps (the largest ridge with one run).

The operators run along the whole joint path of a run (the `run` column, as m_N does:
ctrkin.models.motion), the unrecorded move between two sequences of a run taken as one step from the
end of one to the start of the next; a run starts at rest (every lag 0); glitch rows repeat the last
believed joints.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import lsq_linear

from ctrkin.families.snap_aware.labels import phase_deg, snap_events
from ctrkin.models import play_lags
from ctrkin.models.motion import run_continues
from ctrkin.models.play_lags import Lags
from ctrkin.models.relay import MIN_FOLD_DEG, relay_scan

ANGLE_WIDTHS_DEG = (2.0, 5.0, 15.0, 45.0, 90.0)    # the rotation operators' half widths
SLIDE_WIDTHS_MM = (0.02, 0.05, 0.2, 1.0)          # the relative translation's
RIDGES = (1e-3, 1e-2, 1e-1, 1.0, 10.0)            # ridge weights tried by cross-validation


def path_lags(joints: np.ndarray, bounds: list[tuple[int, int]], n_tubes: int,
              runs: np.ndarray | None = None, skip: np.ndarray | None = None,
              angle_widths: tuple[float, ...] = ANGLE_WIDTHS_DEG,
              slide_widths: tuple[float, ...] = SLIDE_WIDTHS_MM) -> Lags:
    """ctrkin.models.play_lags.path_lags at this form's widths."""
    return play_lags.path_lags(joints, bounds, n_tubes, runs, skip, angle_widths, slide_widths)


def dataset_lags(ds: Any, angle_widths: tuple[float, ...] = ANGLE_WIDTHS_DEG,
                 slide_widths: tuple[float, ...] = SLIDE_WIDTHS_MM) -> Lags:
    """path_lags of a Dataset's joints as recorded, its runs followed, glitch rows skipped."""
    return play_lags.recorded_lags(ds.frame, ds.joints(), ds.sequence_bounds(), ds.n_tubes, angle_widths,
                                   slide_widths)


@dataclass(frozen=True)
class SnapRows:
    """Snaps as the rows of the linear problem: direction s (E,), the fold φ_s(β) (E,) in deg, the
    phase mid-way φ_mid (E,), the lags there (Lags of E rows), and each snap's run (E,)."""

    sign: np.ndarray
    fold: np.ndarray
    phase: np.ndarray
    lags: Lags
    run: np.ndarray

    def design(self) -> tuple[np.ndarray, np.ndarray]:
        """A (E, 2 + 2K + J) over x = (c, g, w, v, u) and b (E,) of the equations φ_mid = A·x."""
        lg = self.lags
        return (np.column_stack([self.sign, self.fold, lg.inner, -lg.outer, -self.sign[:, None] * lg.slide]),
                self.phase)


@dataclass(frozen=True)
class Identified:
    """x = (c, g, w (K,), v (K,), u (J,)) of the module docstring; ridge: the chosen weight;
    cv_rms_deg: its leave-one-run-out RMS residual (NaN with fewer than two runs)."""

    x: np.ndarray
    n_angle: int
    ridge: float
    cv_rms_deg: float

    @property
    def widen_deg(self) -> float:
        return float(self.x[0])

    @property
    def fold_scale(self) -> float:
        return float(self.x[1])

    @property
    def inner(self) -> np.ndarray:
        return self.x[2:2 + self.n_angle]

    @property
    def outer(self) -> np.ndarray:
        return self.x[2 + self.n_angle:2 + 2 * self.n_angle]

    @property
    def slide(self) -> np.ndarray:
        return self.x[2 + 2 * self.n_angle:]


def _solve(A: np.ndarray, b: np.ndarray, ridge: float) -> np.ndarray:
    """Bounded least squares: c free, g and the weights ≥ 0, a ridge on the weights and on g − 1
    (the nominal folds' scale; per degree of fold, so that it weighs as a weight does)."""
    k = A.shape[1]
    scale = float(np.sqrt(np.mean(A[:, 1] ** 2))) or 1.0
    reg = np.sqrt(ridge) * np.eye(k)[1:]
    reg[0, 1] *= scale
    prior = np.r_[np.sqrt(ridge) * scale, np.zeros(k - 2)]
    lo = np.r_[-np.inf, np.zeros(k - 1)]
    return lsq_linear(np.vstack([A, reg]), np.r_[b, prior], bounds=(lo, np.full(k, np.inf))).x


def identify(rows: SnapRows, ridges: tuple[float, ...] = RIDGES) -> Identified:
    """x of the snaps `rows` (module docstring); the ridge with the lowest leave-one-run-out RMS
    residual (the largest ridge where there is a single run). No snaps: the plain nominal folds."""
    A, b = rows.design()
    n_angle = rows.lags.inner.shape[1]
    if len(b) == 0:
        x = np.zeros(A.shape[1])
        x[1] = 1.0
        return Identified(x, n_angle, float(ridges[-1]), np.nan)
    runs = np.unique(rows.run)
    best, best_rms = ridges[-1], np.nan
    if len(runs) > 1:
        scores = []
        for lam in ridges:
            err = np.empty(len(b))
            for r in runs:
                out = rows.run == r
                err[out] = A[out] @ _solve(A[~out], b[~out], lam) - b[out]
            scores.append(float(np.sqrt(np.mean(err ** 2))))
        i = int(np.argmin(scores))
        best, best_rms = ridges[i], scores[i]
    return Identified(_solve(A, b, best), n_angle, float(best), best_rms)


def snap_rows(gate: Any, ds: Any, rows: np.ndarray | None = None) -> SnapRows:
    """The snaps of ds at `rows` (row indices; default all) as SnapRows: those in the bistable band
    where the nominal robot folds in the snap's direction (as the fold gate's own fit takes them);
    gate: a FoldGate (its fold table and band)."""
    n, q = ds.n_tubes, ds.joints()
    lags = dataset_lags(ds)
    runs = ds.frame["run"].to_numpy() if "run" in ds.frame.columns else np.zeros(len(q), np.int64)
    keep = np.ones(len(q), bool) if rows is None else np.isin(np.arange(len(q)), rows)
    a0 = q[:, 0] - q[:, n - 1]
    phi = phase_deg(a0)
    fwd, bwd = gate.folds(q[:, n:])
    found: list[tuple[int, float, float, Lags, int]] = []
    for a, b in ds.sequence_bounds():
        for t in snap_events(ds.frame["snap"].to_numpy(), a, b):
            s = int(np.sign(a0[t] - a0[t - 1]))
            fold = fwd[t] if s > 0 else bwd[t]
            if keep[t] and s != 0 and abs(phi[t]) < gate.band_deg and abs(fold) >= MIN_FOLD_DEG:
                mid = float(phi[t] - 0.5 * (a0[t] - a0[t - 1]))
                found.append((s, float(fold), mid, lags.mid(t), int(runs[t])))

    def stack(name: str) -> np.ndarray:
        parts = [getattr(f[3], name) for f in found]
        return np.concatenate(parts) if parts else np.zeros((0, getattr(lags, name).shape[1]))

    return SnapRows(np.array([f[0] for f in found], float), np.array([f[1] for f in found]),
                    np.array([f[2] for f in found]), Lags(stack("inner"), stack("outer"), stack("slide")),
                    np.array([f[4] for f in found], np.int64))


def play_states(gate: Any, ident: Identified, ds: Any) -> np.ndarray:
    """(T,) branch states of ds under the identified form: the fold gate's relay
    (ctrkin.models.relay) on the thresholds of the module docstring, runs followed."""
    n, q = ds.n_tubes, ds.joints()
    lg = dataset_lags(ds)
    shift = lg.inner @ ident.inner - lg.outer @ ident.outer
    narrow = lg.slide @ ident.slide
    fwd, bwd = gate.folds(q[:, n:])
    g, c, band = ident.fold_scale, ident.widen_deg, gate.band_deg
    hi = np.where(np.abs(fwd) >= MIN_FOLD_DEG, g * fwd + c + shift - narrow, band)
    lo = np.where(np.abs(bwd) >= MIN_FOLD_DEG, g * bwd - c + shift + narrow, -band)
    bounds = ds.sequence_bounds()
    runs = ds.frame["run"].to_numpy() if "run" in ds.frame.columns else None
    return relay_scan(np.ascontiguousarray(phase_deg(q[:, 0] - q[:, n - 1])), np.maximum(hi, lo), lo,
                      np.asarray(bounds, np.int64).reshape(-1, 2),
                      np.asarray(run_continues(bounds, runs), np.bool_), band)
