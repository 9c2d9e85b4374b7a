"""The joint stops of a controller as linear inequalities, and the push away from them.

Every stop of a CTR's joints is linear in q = (α1..αN, β1..βN) (docs/design.md: Conventions):

    α_i ≤ hi,  −α_i ≤ −lo                          (the controller's rotation limits)
    β_N ≤ 0,   −β_N ≤ L_N                            (the outer carriage at the front plate / tip inside)
    β_i − β_{i+1} ≤ 0,  β_{i+1} − β_i ≤ L_i − L_{i+1}   (a carriage against the next one's; i < N)

so the valid set is A q ≤ b, one row a stop. The controller keeps the rows its step would cross as
equalities of its least squares (active set: the other joints take over the task, Chan & Dubey 1995
do the same by weights), and near a stop it pushes the joints away in the null space of the tip task
(a spring over the last `zone` of each stop, scaled like the joints: Liégeois 1977's gradient
projection of a joint-limit cost).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctrkin.robots.robot import Robot


@dataclass(frozen=True, eq=False)
class Stops:
    """A q ≤ b: A (M, 2N), b (M,) in deg or mm per row; scale (M,): each row's joint scale (deg or
    mm that cost alike, the controller's s), so that slacks of rotation and translation stops compare."""

    A: np.ndarray
    b: np.ndarray
    scale: np.ndarray

    @classmethod
    def of(cls, robot: Robot, alpha_limits: tuple[float, float], alpha_scale: float, beta_scale: float
           ) -> Stops:
        """The stops of `robot` with every α within alpha_limits (lo, hi) deg (module docstring)."""
        n = robot.n_tubes
        L = robot.lengths
        rows, b, scale = [], [], []

        def row(coeffs: dict[int, float], bound: float, s: float) -> None:
            a = np.zeros(2 * n)
            for j, c in coeffs.items():
                a[j] = c
            rows.append(a)
            b.append(bound)
            scale.append(s)

        for i in range(n):
            row({i: 1.0}, alpha_limits[1], alpha_scale)
            row({i: -1.0}, -alpha_limits[0], alpha_scale)
        row({2 * n - 1: 1.0}, 0.0, beta_scale)
        row({2 * n - 1: -1.0}, float(L[-1]), beta_scale)
        for i in range(n - 1):
            row({n + i: 1.0, n + i + 1: -1.0}, 0.0, beta_scale)
            row({n + i: -1.0, n + i + 1: 1.0}, float(L[i] - L[i + 1]), beta_scale)
        return cls(np.array(rows), np.array(b), np.array(scale))

    def slack(self, q: np.ndarray) -> np.ndarray:
        """(M,) b − A q: how far q (2N,) is from each stop (deg or mm; < 0 beyond it)."""
        return np.asarray(self.b - self.A @ q)

    def crossed(self, q: np.ndarray, dq: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """(M,) bool: the stops the step dq (2N,) from q crosses."""
        return np.asarray(self.A @ (q + dq) > self.b + tol)

    def push(self, q: np.ndarray, zone: float) -> tuple[np.ndarray, float]:
        """The direction (2N,) away from the stops q is within `zone` joint scales of, each weighted
        by how far into its zone q is (1 at the stop, 0 at the zone's edge): −Σ_j (1 − s_j/zone) A_jᵀ
        scale_j over the rows with scaled slack s_j < zone (zero far from every stop); and the
        deepest weight (0 far from every stop, 1 at one)."""
        s = self.slack(q) / self.scale
        w = np.clip(1.0 - s / zone, 0.0, 1.0)
        return np.asarray(-(w * self.scale) @ self.A), float(w.max(initial=0.0))
