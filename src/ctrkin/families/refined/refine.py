"""IK refined on the learned FK: damped Gauss-Newton from several starts, history included.

Why: a direct IK network maps a tip pose to joints by regression. Where the pose does not determine
α well (near planar shapes), or where two branches give the same pose, it averages solutions, and
nothing checks where its joints put the tip. The learned FK is accurate (sub-millimetre) and cheap,
so each IK step here solves

    q* = argmin_q ‖ r(q) ‖²,   r(q) = ( p(q) − p*,  w·(t(q) − t*) )          (mm)

with p, t the tip position and unit tangent the FK model predicts for the next step after the
robot's history (its input buffer and branch state), p*, t* the target, w = `tangent_weight_mm` mm
per radian. Levenberg-Marquardt steps with a forward-difference Jacobian (the FK engine evaluates
all 1 + 2N perturbed joints in one call, ctrkin.models.engine.StreamingEngine.probe) from up to
three starts: the direct IK prediction, the previous solution (continuity along a path) and the
joints of the nearest training pose. The best residual wins; among starts within `continuity_mm` of
it, the one closest to the previous joints (so a path gets continuous joints where the pose alone
does not fix α). Joints stay within the robot's limits (ctrkin.robots.Robot.project_joints) and
within the FK model's training range (α by whole turns, β clipped); the FK history then advances
with the chosen joints, and α is returned as the whole-turn representative nearest the previous
command (a full turn is the same shape, but a real motion of the robot).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ctrkin.errors import ModelError
from ctrkin.geometry import tangent_from_quat
from ctrkin.metrics import wrap_deg
from ctrkin.models.predictor import Predictor, Probing


@dataclass(frozen=True)
class RefineSettings:
    """iterations: LM steps per start; tangent_weight_mm: mm of residual per radian of tangent error;
    fd_deg, fd_mm: finite-difference steps; tolerance_mm: stop a start below this residual;
    continuity_mm: residual margin within which the start nearest the previous joints is preferred;
    starts: which starts to use ("direct", "previous", "nearest"), tried previous first;
    accept_mm: a start that ends below this residual is taken without trying the others (along a
    path the previous solution usually is, which keeps a step to a few FK evaluations)."""

    iterations: int = 3
    tangent_weight_mm: float = 10.0
    fd_deg: float = 0.2
    fd_mm: float = 0.02
    tolerance_mm: float = 0.1
    continuity_mm: float = 0.3
    starts: tuple[str, ...] = ("direct", "previous", "nearest")
    accept_mm: float = 0.5

    def __post_init__(self) -> None:
        if self.iterations < 0 or self.tangent_weight_mm < 0 or self.fd_deg <= 0 or self.fd_mm <= 0:
            raise ModelError("RefineSettings: iterations >= 0, tangent_weight_mm >= 0, fd steps > 0")
        unknown = set(self.starts) - {"direct", "previous", "nearest"}
        if unknown or not self.starts:
            raise ModelError(f"RefineSettings.starts must be taken from direct, previous, nearest; "
                             f"got {self.starts}")

    def to_dict(self) -> dict[str, object]:
        d = asdict(self)
        d["starts"] = list(self.starts)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> RefineSettings:
        d = dict(d)
        if "starts" in d:
            d["starts"] = tuple(d["starts"])
        return cls(**d)


@dataclass(frozen=True)
class Refined:
    """joints (2N,); residual_mm: ‖r‖ at them per the FK model; start: which start won."""

    joints: np.ndarray
    residual_mm: float
    start: str


class FKResidual:
    """r(q) for K candidate joints at the next step of an FK predictor's stream (one that probes,
    ctrkin.models.predictor.Probing)."""

    def __init__(self, fk: Predictor, tangent_weight_mm: float) -> None:
        layout = fk.bundle.layout
        if layout.task != "fk" or not isinstance(fk, Probing) or not getattr(fk, "probes", False):
            raise ModelError("IK refinement needs an FK model of the LSTM-MLP family (streaming engine)")
        self.fk: Probing = fk
        self.w = tangent_weight_mm
        # the trained range of each joint input (±inf for an α the model sees only as sin/cos)
        names = list(layout.input_names)
        lo, hi = fk.bundle.x_norm.lo, fk.bundle.x_norm.hi
        joints = [f"{kind}_{i + 1}" for kind in ("alpha", "beta") for i in range(layout.n_tubes)]
        self.joint_lo = np.array([lo[names.index(c)] if c in names else -np.inf for c in joints])
        self.joint_hi = np.array([hi[names.index(c)] if c in names else np.inf for c in joints])

    def residual(self, Q: np.ndarray, target_p: np.ndarray, target_t: np.ndarray) -> np.ndarray:
        """Q: (K, 2N) -> (K, 6) residuals (mm)."""
        pos, tan = self.fk.probe_tips(Q)
        out = np.empty((len(pos), 6))
        out[:, :3] = pos - target_p
        out[:, 3:] = self.w * (tan - target_t)
        return out


def refine(res: FKResidual, starts: list[tuple[str, np.ndarray]], target: np.ndarray,
           previous: np.ndarray | None, settings: RefineSettings, project: object) -> Refined:
    """Run LM from each start; pick the best (with continuity). target: (6,) pose; project: callable
    (K, 2N) -> (K, 2N) onto the valid joints."""
    p_star = np.asarray(target[:3], float)
    t_star = tangent_from_quat(np.asarray(target[3:6], float))
    n2 = len(starts[0][1])
    n = n2 // 2
    steps = np.r_[np.full(n, settings.fd_deg), np.full(n, settings.fd_mm)]
    results: list[tuple[str, np.ndarray, float]] = []
    for name, q0 in starts:
        q = _clamp(res, project, q0[None])[0]
        r = res.residual(q[None], p_star, t_star)[0]
        cost = float(r @ r)
        lam = 1e-3
        for _ in range(settings.iterations):
            if math.sqrt(cost) < settings.tolerance_mm:
                break
            cand = np.repeat(q[None], n2 + 1, axis=0)
            cand[1:] += np.diag(steps)
            R = res.residual(cand, p_star, t_star)
            J = (R[1:] - R[0]).T / steps                     # (6, 2N) forward differences
            r = R[0]
            cost = float(r @ r)
            A = J.T @ J
            g = J.T @ r
            accepted = False
            for _try in range(3):
                try:
                    dq = -np.linalg.solve(A + lam * (np.diag(np.diag(A)) + 1e-9 * np.eye(n2)), g)
                except np.linalg.LinAlgError:
                    lam *= 10.0
                    continue
                q_new = _clamp(res, project, (q + dq)[None])[0]
                r_new = res.residual(q_new[None], p_star, t_star)[0]
                c_new = float(r_new @ r_new)
                if c_new < cost:
                    q, cost, lam, accepted = q_new, c_new, max(lam / 10.0, 1e-6), True
                    break
                lam *= 10.0
            if not accepted:
                break
        results.append((name, q, math.sqrt(cost)))
        if math.sqrt(cost) <= settings.accept_mm:
            break
    best = min(r[2] for r in results)
    close = [r for r in results if r[2] <= best + settings.continuity_mm]
    if previous is not None and len(close) > 1:
        scale = np.r_[np.full(n, 10.0), np.ones(n)]          # 10° of α weigh like 1 mm of β
        chosen = min(close, key=lambda r: float(np.sum(((_wrap_diff(r[1], previous, n)) / scale) ** 2)))
    else:
        chosen = min(results, key=lambda r: r[2])
    return Refined(chosen[1], chosen[2], chosen[0])


def _wrap_diff(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    d = np.asarray(a, float) - np.asarray(b, float)
    d[:n] = wrap_deg(d[:n])
    return d


def _clamp(res: FKResidual, project: object, Q: np.ndarray) -> np.ndarray:
    """Onto the FK model's training range (α moved by whole turns first: the same configuration,
    inside the range the model knows; then every joint clipped: the model knows nothing outside it),
    then onto the robot's valid joints."""
    Q = np.clip(res.fk.alpha_into_range(Q), res.joint_lo, res.joint_hi)
    return project(Q)  # type: ignore[operator]
