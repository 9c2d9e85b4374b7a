"""A smooth field of the tip's position in the tracker frame, identified from an FK's residuals: what
depends on where the tip is in space rather than on the joints (docs/learned_kinematics.md: The
tracker's field).

An electromagnetic tracker near metal reports a point displaced by a static, smooth,
position-dependent error (Franz et al. 2014; the virtual robot's ctrkin.virtual.field). A model
learned in the outer tube's frame (ctrkin.models.frame) can only learn it as a function of the
joints, and where the held-out sequences lie between the training ones (the outer tube at angles no
training turn had) it interpolates that function badly: the same tip position is reached with other
joints. A rotation-equivariant model (angle_encoding "relative") cannot learn it at all, so its
residuals hold it, and here it is fitted as what it is, a field of the position:

    p_tracker = p_model + w(p_model),   w(u) = Σ_k c_k · u^k   (monomials of total degree ≤ D,
                                                                 u = (p − centre) / scale)

by ridge least squares on the training rows' position residuals. D and the ridge are chosen by
cross-validation over whole training sequences (grouped folds, none of the held-out rows), the
smallest mean squared error; D = 0 with no ridge is the constant offset. Nothing about the field's
physics is assumed beyond smoothness on the scale of the workspace; orientation is not corrected.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numba import njit

from ctrkin.errors import ModelError

DEGREES = (0, 1, 2, 3, 4)             # total polynomial degrees tried
RIDGES = (1e-6, 1e-4, 1e-2, 1.0)      # ridge weights tried (per row, on scaled monomials)
FOLDS = 5                             # grouped cross-validation folds over the training sequences


def exponents(degree: int) -> np.ndarray:
    """(M, 3) exponents of the monomials of x, y, z of total degree ≤ degree, constant first."""
    rows = [e for d in range(degree + 1) for e in itertools.product(range(d + 1), repeat=3) if sum(e) == d]
    return np.array(rows, dtype=np.int64).reshape(-1, 3)


def _monomials(u: np.ndarray, exps: np.ndarray) -> np.ndarray:
    """(T, M) the monomials `exps` of scaled positions u (T, 3)."""
    return np.prod(u[:, None, :] ** exps[None, :, :], axis=2)


def _solve(A: np.ndarray, r: np.ndarray, ridge: float) -> np.ndarray:
    """(M, 3) ridge solution of A c = r (the constant unpenalised)."""
    reg = np.full(A.shape[1], ridge * len(A))
    reg[0] = 0.0
    return np.linalg.solve(A.T @ A + np.diag(reg), A.T @ r)


@dataclass(frozen=True, eq=False)
class PositionField:
    """w(p) of the module docstring: centre (3,), scale (float, mm), exponents (M, 3), coefficients
    (M, 3) mm; degree and ridge as chosen, and the cross-validated RMS of the residual it leaves and
    of the residual without it (mm). A field learned with the FK (ctrkin.models.joint_field) has
    ridge 0 and, in place of the cross-validated figures, the validation rows' position RMS with
    and without it."""

    centre: np.ndarray
    scale: float
    exps: np.ndarray
    coef: np.ndarray
    ridge: float
    cv_rms_mm: float
    cv_rms_without_mm: float

    @property
    def degree(self) -> int:
        return int(self.exps.sum(axis=1).max()) if len(self.exps) else 0

    def __call__(self, p: np.ndarray) -> np.ndarray:
        """(T, 3) w at positions p (T, 3) mm."""
        u = (np.atleast_2d(np.asarray(p, float)) - self.centre) / self.scale
        return _monomials(u, self.exps) @ self.coef

    def apply_one(self, pose: np.ndarray) -> np.ndarray:
        """A (6,) float64 pose with w added to its position (in place; the streaming path, the
        reference and the fused step alike: add_field_one)."""
        add_field_one(pose, self.centre, self.scale, self.exps, self.coef)
        return pose

    def apply_rows(self, poses: np.ndarray) -> np.ndarray:
        """(T, 6) float64 poses with w added to each position as apply_one does (in place)."""
        add_field_rows(poses, self.centre, self.scale, self.exps, self.coef)
        return poses

    @classmethod
    def fit(cls, predicted: np.ndarray, measured: np.ndarray, groups: np.ndarray,
            degrees: tuple[int, ...] = DEGREES, ridges: tuple[float, ...] = RIDGES) -> PositionField:
        """The field of residuals measured − predicted (T, 3) at the predicted positions (T, 3), D and
        the ridge chosen by grouped cross-validation over `groups` (T,) (e.g. sequence ids)."""
        P, R = np.asarray(predicted, float), np.asarray(measured, float) - np.asarray(predicted, float)
        ok = np.isfinite(P).all(1) & np.isfinite(R).all(1)
        P, R, g = P[ok], R[ok], np.asarray(groups)[ok]
        if len(P) < 10:
            raise ModelError("a position field needs at least 10 training rows with finite poses")
        centre = P.mean(axis=0)
        scale = float(np.sqrt(((P - centre) ** 2).sum(axis=1).mean())) or 1.0
        U = (P - centre) / scale
        ids = np.unique(g)
        fold = np.searchsorted(ids, g) % FOLDS if len(ids) >= 2 else np.arange(len(g)) % FOLDS
        best: tuple[float, np.ndarray, float] | None = None
        without = float(np.sqrt(np.mean(np.sum(R ** 2, axis=1))))
        for degree in degrees:
            exps = exponents(degree)
            A = _monomials(U, exps)
            for ridge in (ridges if degree > 0 else (0.0,)):
                err = np.empty_like(R)
                for k in range(FOLDS):
                    out = fold == k
                    if not out.any() or out.all():
                        continue
                    err[out] = R[out] - A[out] @ _solve(A[~out], R[~out], ridge)
                mse = float(np.mean(np.sum(err ** 2, axis=1)))
                if best is None or mse < best[0]:
                    best = (mse, exps, ridge)
        assert best is not None
        mse, exps, ridge = best
        coef = _solve(_monomials(U, exps), R, ridge)
        return cls(centre, scale, exps, coef, float(ridge), float(np.sqrt(mse)), without)

    def to_dict(self) -> dict[str, object]:
        return {"centre": self.centre.tolist(), "scale": self.scale, "exponents": self.exps.tolist(),
                "coefficients": self.coef.tolist(), "ridge": self.ridge, "cv_rms_mm": self.cv_rms_mm,
                "cv_rms_without_mm": self.cv_rms_without_mm}

    @classmethod
    def from_dict(cls, d: dict) -> PositionField:
        try:
            exps = np.asarray(d["exponents"], np.int64).reshape(-1, 3)
            coef = np.asarray(d["coefficients"], float).reshape(len(exps), 3)
            return cls(np.asarray(d["centre"], float).reshape(3), float(d["scale"]), exps, coef,
                       float(d["ridge"]), float(d["cv_rms_mm"]), float(d["cv_rms_without_mm"]))
        except (KeyError, ValueError, TypeError) as e:
            raise ModelError(f"bad position-field entry: {e}") from None


@njit(cache=True)
def add_field_one(pose: np.ndarray, centre: np.ndarray, scale: float, exps: np.ndarray, coef: np.ndarray
                  ) -> None:
    """pose[:3] += w(pose[:3]) in scalar arithmetic (PositionField: monomials by repeated products)."""
    u0, u1, u2 = ((pose[0] - centre[0]) / scale, (pose[1] - centre[1]) / scale,
                  (pose[2] - centre[2]) / scale)
    w0 = w1 = w2 = 0.0
    for k in range(exps.shape[0]):
        m = 1.0
        for _ in range(exps[k, 0]):
            m *= u0
        for _ in range(exps[k, 1]):
            m *= u1
        for _ in range(exps[k, 2]):
            m *= u2
        w0 += m * coef[k, 0]
        w1 += m * coef[k, 1]
        w2 += m * coef[k, 2]
    pose[0] += w0
    pose[1] += w1
    pose[2] += w2


@njit(cache=True)
def add_field_rows(poses: np.ndarray, centre: np.ndarray, scale: float, exps: np.ndarray, coef: np.ndarray
                   ) -> None:
    """add_field_one on each row of poses (T, 6)."""
    for r in range(poses.shape[0]):
        add_field_one(poses[r], centre, scale, exps, coef)
