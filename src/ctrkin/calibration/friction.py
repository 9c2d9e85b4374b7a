"""μ, the friction between the tubes, fitted on the continued TCM (`ctrkin calibrate`, group
"friction").

A point-wise solve has no history, so it carries no friction load and its tip does not depend on μ:
the least squares of fit.py cannot see it. μ is fitted after the other groups, with them held, by
a bounded scalar search (scipy's minimize_scalar, Brent's method on [0, MAX_FRICTION]) of the RMS
tip distance of the calibrated robot followed along the training sequences (CalibratedTCM.
predict_continued), on whole sequences: friction is the lag a path leaves, so the order of the
samples matters. Its standard error is the Gauss-Newton one of that residual vector, the derivative
by a central difference.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from ctrkin.calibration.model import CalibratedTCM
from ctrkin.calibration.params import MAX_FRICTION

MAX_SAMPLES = 20_000     # samples (whole sequences) the continued fit uses at most
XATOL = 2e-3             # the search's tolerance on μ
STEP = 0.01              # central-difference step of the standard error


def sequences(bounds: list[tuple[int, int]], rows: np.ndarray | None, seed: int = 0,
              max_samples: int = MAX_SAMPLES) -> list[tuple[int, int]]:
    """The sequences holding `rows` (all if None), in a seeded order, whole, until max_samples."""
    if rows is not None:
        held = np.zeros(max(b for _, b in bounds), bool)
        held[np.asarray(rows)] = True
        bounds = [(a, b) for a, b in bounds if held[a:b].any()]
    order = np.random.default_rng(seed).permutation(len(bounds))
    out: list[tuple[int, int]] = []
    total = 0
    for k in order:
        a, b = bounds[k]
        if out and total + (b - a) > max_samples:
            break
        out.append((a, b))
        total += b - a
    return sorted(out)


def _residuals(model: CalibratedTCM, mu: float, joints: np.ndarray, measured: np.ndarray,
               bounds: list[tuple[int, int]]) -> np.ndarray:
    m = dataclasses.replace(model, robot=dataclasses.replace(model.robot, friction=float(mu)))
    pred = m.predict_continued(joints, bounds)
    rows = np.concatenate([np.arange(a, b) for a, b in bounds])
    r = (measured[rows, :3] - pred[rows, :3]).ravel()
    return np.where(np.isfinite(r), r, 100.0)   # mm: a step that did not converge (fit.NAN_PENALTY_MM)


def fit_friction(model: CalibratedTCM, joints: np.ndarray, measured: np.ndarray,
                 bounds: list[tuple[int, int]]) -> tuple[float, dict[str, Any]]:
    """μ of `model`'s robot that best fits the measured positions (T, 3+) of the sequences
    `bounds` of `joints` (T, 2N). Returns (μ, {"friction_mu", "std", "rms_mm",
    "rms_frictionless_mm", "evaluations", "samples"})."""
    def rms(mu: float) -> float:
        r = _residuals(model, mu, joints, measured, bounds)
        return float(np.sqrt(np.mean(r * r)))

    sol = minimize_scalar(rms, bounds=(0.0, MAX_FRICTION), method="bounded",
                          options={"xatol": XATOL})
    mu = float(sol.x)
    lo, hi = max(mu - STEP, 0.0), min(mu + STEP, MAX_FRICTION)
    d = (_residuals(model, hi, joints, measured, bounds)
         - _residuals(model, lo, joints, measured, bounds)) / (hi - lo)
    r = _residuals(model, mu, joints, measured, bounds)
    dof = max(r.size - 1, 1)
    std = float(np.sqrt(r @ r / dof / (d @ d))) if d @ d > 0 else float("inf")
    n = int(sum(b - a for a, b in bounds))
    return mu, {"friction_mu": mu, "std": std, "rms_mm": float(np.sqrt(np.mean(r * r))) * np.sqrt(3.0),
                "rms_frictionless_mm": rms(0.0) * float(np.sqrt(3.0)), "evaluations": int(sol.nfev) + 4,
                "samples": n}
