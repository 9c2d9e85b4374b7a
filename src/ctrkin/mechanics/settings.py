"""Numerical settings of the TCM solver."""

from __future__ import annotations

from dataclasses import dataclass

from ctrkin.errors import CtrkinError


@dataclass(frozen=True)
class SolverSettings:
    """tip_tol: if set, tip-position error (mm) the RK4 step is chosen for, by the estimate
    e(h) = κ*⁵ ℓc min(L, 1/κ*) h⁴ / 120 (docs/mechanics.md: RK4's phase error (κh)⁵/120 per step of a
    rotation at rate κ*, over the precurved length ℓc, times the lever arm, at most the longest tube L
    and the radius 1/κ* of a wound arc); step: largest RK4 step (mm) where a tube is curved (a
    straight stretch is one exact step); angle_step: largest bending angle per RK4 step (rad). The
    step is min(step, angle_step / κ*, (tip_tol / e(1))^¼) with κ* the robot's curvature-and-torsion
    scale (1/mm, see `mechanics.arrays.RobotArrays.kappa_scale`). At the default (tip_tol None:
    3 mm, 0.15 rad) e ≤ 4.2e-6 mm per mm of precurved length, ≤ 1e-3 mm up to ℓc = 240 mm;
    `SolverSettings(step=math.inf, tip_tol=1e-3)` takes the step from the tolerance alone;
    tol: shooting residual |uz(tip)|∞ (rad/mm);
    max_iter: Newton iterations; max_step: largest Newton update |Δuz(0)|∞ (rad/mm);
    max_rk4_steps: refuse a configuration whose grid needs more RK4 steps (a guard against
    absurd lengths or step settings: ConvergenceError instead of a hang); max_search_steps: RK4
    steps (every integration of the shooting counted) after which a multi-start search (a solve
    without a guess) stops trying further starts and keeps the best found so far, and after which
    one continuation step of follow is given up (reported not converged)
    (5e5 RK4 steps: about 0.5 s on one core for three tubes; a paper-robot solve needs < 1e4,
    a continuation step of a paper-robot sweep, folds included, < 3e4).

    RK4's error falls as step⁴: on the paper robot the tip is within 3e-5 mm of a tight-tolerance
    reference at the default 3 mm (5e-6 mm at 2 mm, 1.3e-3 mm at 8 mm); with the curvature rule a
    single curved tube is within 3e-6 mm per mm of curved length of the exact arc at any curvature
    (docs/mechanics.md); benchmarks/bench_mechanics.py measures it. The estimate e(h) is 2-5× above
    the measured error on the paper, TIMClab and high-curvature robots (tests/mechanics)."""

    tip_tol: float | None = None
    step: float = 3.0
    tol: float = 1e-10
    max_iter: int = 40
    max_step: float = 0.05
    angle_step: float = 0.15
    max_rk4_steps: int = 200_000
    max_search_steps: int = 500_000

    def __post_init__(self) -> None:
        if self.tip_tol is not None and not self.tip_tol > 0:
            raise CtrkinError(f"SolverSettings.tip_tol must be > 0 mm, got {self.tip_tol}")
        if not self.step > 0:
            raise CtrkinError(f"SolverSettings.step must be > 0 mm, got {self.step}")
        if not self.tol > 0:
            raise CtrkinError(f"SolverSettings.tol must be > 0, got {self.tol}")
        if self.max_iter < 1:
            raise CtrkinError(f"SolverSettings.max_iter must be >= 1, got {self.max_iter}")
        if not self.max_step > 0:
            raise CtrkinError(f"SolverSettings.max_step must be > 0, got {self.max_step}")
        if not self.angle_step > 0:
            raise CtrkinError(f"SolverSettings.angle_step must be > 0 rad, got {self.angle_step}")
        if self.max_search_steps < 0:
            raise CtrkinError(f"SolverSettings.max_search_steps must be >= 0, got {self.max_search_steps}")
        if self.max_rk4_steps < 1:
            raise CtrkinError(f"SolverSettings.max_rk4_steps must be >= 1, got {self.max_rk4_steps}")


DEFAULT_SETTINGS = SolverSettings()
