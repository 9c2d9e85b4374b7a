"""Numerical settings of the TCM solver."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ctrkin.errors import CtrkinError


@dataclass(frozen=True)
class SolverSettings:
    """tip_tol: tip-position error (mm) the RK4 step is chosen for, by the estimate
    e(h) = κ*⁴ ℓc h⁴ / 120 (docs/mechanics.md: Numerics; RK4's phase error (κh)⁵/120 per step of a
    rotation at rate κ*, over the precurved length ℓc, acting on the arc's radius 1/κ*: a single
    curved tube's tip error is exactly this, whatever its length). Default 1e-3 mm: the measured
    error is 2-8× below it (paper robot 2.4e-4 mm at a 5.26 mm step, TIMClab robot 1.2e-4 mm at
    14.8 mm; tests/mechanics check the tolerance against a tight reference); a tighter one on
    request, e.g.
    `SolverSettings(tip_tol=1e-6)`; None: no tolerance, the step is min(step, angle_step / κ*).
    step: largest RK4 step (mm) where a tube is curved (a straight stretch is one exact step),
    default no cap; angle_step: largest turn of the state per RK4 step (rad), a guard that keeps RK4
    where the estimate holds for loose tolerances (default 0.3: it binds on neither built-in robot at
    1e-3 mm). The step is min(step, angle_step / κ*, (tip_tol / e(1))^¼) with κ* the robot's
    curvature-and-torsion scale (1/mm, see `mechanics.arrays.RobotArrays.kappa_scale`);
    `SolverSettings(tip_tol=None, step=3.0, angle_step=0.15)` is the fixed 3 mm step of earlier
    versions (e ≤ 4.2e-6 mm per mm of precurved length);
    tol: shooting residual |uz(tip)|∞ (rad/mm);
    max_iter: Newton iterations; max_step: largest Newton update |Δuz(0)|∞ (rad/mm);
    max_rk4_steps: refuse a configuration whose grid needs more RK4 steps (a guard against
    absurd lengths or step settings: ConvergenceError instead of a hang); max_search_steps: RK4
    steps (every integration of the shooting counted) after which a multi-start search (a solve
    without a guess) stops trying further starts and keeps the best found so far, and after which
    one continuation step of follow is given up (reported not converged)
    (5e5 RK4 steps: about 0.5 s on one core for three tubes; a paper-robot solve needs < 1e4,
    a continuation step of a paper-robot sweep, folds included, < 3e4).
    Friction (Robot.friction > 0; docs/mechanics.md: Friction and clearance): stick_mm (mm): the
    elastic slip of a friction element at the contact surface, within which it sticks (a play
    element's half width, the same in torsion, stick_mm / r_c rad, and axially: Coulomb's law is
    isotropic at the surface; the rigid-plastic limit as it goes to 0; default 2e-3 mm, 0.9e-2 rad
    on the paper robot's contact radius 0.22 mm: a metal contact's presliding displacement, and
    smaller values leave three-tube shooting ill-conditioned, docs/mechanics.md: Friction and
    clearance); distributed_friction: add the distributed contact
    force |M''| of the curved stretches to the breakpoints' elements (False: only the concentrated
    contacts of Lock & Dupont 2011).

    RK4's error falls as step⁴ (tests/mechanics/test_numerics.py); benchmarks/bench_mechanics.py
    measures the tip error against the reference. The estimate e(h) is 2-8× above the measured
    error on the paper, TIMClab and high-curvature robots (tests/mechanics)."""

    tip_tol: float | None = 1e-3
    step: float = math.inf
    tol: float = 1e-10
    max_iter: int = 40
    max_step: float = 0.05
    angle_step: float = 0.3
    max_rk4_steps: int = 200_000
    max_search_steps: int = 500_000
    stick_mm: float = 2e-3
    distributed_friction: bool = True

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
        if not self.stick_mm > 0:
            raise CtrkinError(f"SolverSettings.stick_mm must be > 0 mm, got {self.stick_mm}")
        if self.max_rk4_steps < 1:
            raise CtrkinError(f"SolverSettings.max_rk4_steps must be >= 1, got {self.max_rk4_steps}")


DEFAULT_SETTINGS = SolverSettings()
