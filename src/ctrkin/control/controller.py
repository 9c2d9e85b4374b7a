"""A closed-loop tip-position controller on a learned FK model (issue 24, goal 3; docs/planning.md:
Control loop).

    from ctrkin.control import Controller, ControlConfig
    ctl = Controller(ctrkin.Kinematics.load("models/fk"), ControlConfig(rate_hz=1000))
    ctl.reset(q_now)
    while running:
        cmd = ctl.cycle(tracker_pose_or_None, target_xyz, target_velocity)   # one cycle
        drive(cmd.joints)                                                     # stopped: hold still

Each cycle is resolved-rate control with damped least squares on the learned FK's Jacobian:
J = ∂p/∂q by differences of the FK's probe (the tips it would predict for 2N + 1 candidate
next joints, nothing advanced: ctrkin.models.predictor.Probing), then

    e  = gain · (p* − p_measured) + v* Δt                                   (feedback + feedforward)
    Δq = W Jᵀ (J W Jᵀ + λ² I)⁻¹ e,   W = diag(s²)                         (damped least squares)

with s the joint scales (deg and mm made comparable), Δq scaled down as a whole so that no joint
exceeds its velocity limit times Δt. The joint stops (the rotations' `alpha_limits`, the carriages'
valid translations: linear inequalities, ctrkin.control.stops) are kept, not clipped: a stop the step
would cross is added to the least squares as an equality (the joint stays at its stop and the others
take over the tip task; repeated until no stop is crossed), and within `stop_zone` joint scales of a
stop the joints are pushed away in the null space of the tip task,

    Δq += k · (I − W Jᵀ (J W Jᵀ + λ² I)⁻¹ J) W p,   p = −Σ_j (1 − s_j / zone) A_jᵀ   (s_j < zone)

(Liégeois 1977's gradient projection), k such that at a stop the fastest joint of the push moves at
`stop_speed` of its velocity limit (less further from it). Clipping instead left a loop that started
at a stop short of its target: the least squares asked the stopped joint again every cycle (a trial
from β2 = 0 stalled 1.2 mm away). The Jacobian's differences are taken backwards where forwards would
leave the valid set.

The feedback closes on the tracker: the model only needs the right Jacobian, its tip offset is
measured away (an integrating loop), so tracking error is the tracker noise the gain lets through plus
the lag on a moving target.

Snap safety: where the FK has a branch state (the snap-aware FK's fold gate), the command is probed
too, and a step that the model predicts would switch branch (a snap) is halved up to three times,
else the robot holds and the cycle says why (`snap_risk`). A lost tracker (None, or a non-finite
pose) stops the loop cleanly: the command holds the last joints (zero velocity), `stopped` is set
with the reason, and it stays stopped until `reset` (a controller never moves on stale feedback).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ctrkin.control.stops import Stops
from ctrkin.errors import CtrkinError, ModelError


class ConfigError(CtrkinError, ValueError):
    """A ControlConfig that cannot run: the message says which field and why."""


@dataclass(frozen=True)
class ControlConfig:
    """rate_hz: cycles per second (Δt = 1/rate); gain: fraction of the measured tip error corrected
    per cycle (0 < gain ≤ 1); damping_mm: λ of the damped least squares (mm); alpha_scale_deg,
    beta_scale_mm: joint scales s (deg and mm that cost alike); max_alpha_deg_s, max_beta_mm_s:
    joint velocity limits; alpha_limits: (lo, hi) deg of every α; fd_alpha_deg, fd_beta_mm: the
    Jacobian's difference steps (a secant across the transmission's backlash, which a model trained
    on a real robot's data has learned: a smaller step reads the dead band as a smaller Jacobian);
    moving: which joints the controller moves (default all; a joint
    the model never saw change, e.g. the outer translation of sweep data, is better held);
    stop_zone: how near a stop (in joint scales: alpha_scale_deg, beta_scale_mm) the joints are pushed
    away from it; stop_speed: the push at a stop, as a fraction of the joint's velocity limit (0: no
    push; the stops are kept either way)."""

    rate_hz: float = 1000.0
    gain: float = 0.2
    damping_mm: float = 0.05
    alpha_scale_deg: float = 10.0
    beta_scale_mm: float = 1.0
    max_alpha_deg_s: float = 90.0
    max_beta_mm_s: float = 10.0
    alpha_limits: tuple[float, float] = (-720.0, 720.0)
    fd_alpha_deg: float = 2.0
    fd_beta_mm: float = 0.3
    moving: tuple[bool, ...] | None = None
    stop_zone: float = 1.0
    stop_speed: float = 0.5

    def __post_init__(self) -> None:
        for name in ("rate_hz", "damping_mm", "alpha_scale_deg", "beta_scale_mm", "max_alpha_deg_s",
                     "max_beta_mm_s", "fd_alpha_deg", "fd_beta_mm", "stop_zone"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"ControlConfig.{name} must be a positive number, got {v!r}")
        if not 0.0 <= self.stop_speed <= 1.0:
            raise ConfigError(f"ControlConfig.stop_speed must lie in [0, 1], got {self.stop_speed!r}")
        if not 0.0 < self.gain <= 1.0:
            raise ConfigError(f"ControlConfig.gain must lie in (0, 1], got {self.gain!r}")
        lo, hi = self.alpha_limits
        if not lo < hi:
            raise ConfigError("ControlConfig.alpha_limits must be (lo, hi) with lo < hi, got "
                              f"{self.alpha_limits}")


@dataclass(frozen=True, eq=False)
class Command:
    """One cycle's answer. joints: (2N,) the command (deg, mm); error_mm: the measured tip error's
    norm (NaN when stopped); stopped: the loop has stopped (hold still); reason: why, or "";
    snap_risk: the step was shortened or refused because the FK predicted a branch switch."""

    joints: np.ndarray
    error_mm: float
    stopped: bool
    reason: str = ""
    snap_risk: bool = False


class Controller:
    """The loop's state between cycles (module docstring). fk: a Kinematics (or predictor) of an FK
    model whose predictor probes (an LSTM-MLP family model); config: ControlConfig."""

    def __init__(self, fk: Any, config: ControlConfig | None = None) -> None:
        self.config = config or ControlConfig()
        if getattr(fk, "task", "fk") != "fk" or not getattr(fk, "probes", False):
            raise ModelError("the controller needs an FK model that probes candidate joints (an LSTM-MLP "
                             "family FK; the refined IK's FK works)")
        self.fk = fk
        self.robot = fk.robot
        n = self.robot.n_tubes
        c = self.config
        self._n = n
        self._dt = 1.0 / c.rate_hz
        s = np.r_[np.full(n, c.alpha_scale_deg), np.full(n, c.beta_scale_mm)]
        mask = np.ones(2 * n, bool) if c.moving is None else np.asarray(c.moving, bool)
        if mask.shape != (2 * n,):
            raise ConfigError(f"ControlConfig.moving must name {2 * n} joints, got {len(mask)}")
        self._w = np.where(mask, s * s, 0.0)
        self._vmax = np.r_[np.full(n, c.max_alpha_deg_s), np.full(n, c.max_beta_mm_s)] * self._dt
        h = np.r_[np.full(n, c.fd_alpha_deg), np.full(n, c.fd_beta_mm)]
        self._probe_q = np.empty((2 * n + 1, 2 * n))
        self._h = np.where(mask, h, 0.0)
        self._eye = (c.damping_mm ** 2) * np.eye(3)
        self._stops = Stops.of(self.robot, c.alpha_limits, c.alpha_scale_deg, c.beta_scale_mm)
        self.q = np.zeros(2 * n)
        self.stopped, self.reason = False, ""

    def reset(self, joints: np.ndarray) -> None:
        """Start (or restart after a stop) at the robot's joints (2N,) (deg, mm): the FK stream starts
        there."""
        q = self.robot.check_joints(np.asarray(joints, float))
        self.q = q.copy()
        self.fk.reset()
        self.fk.step(self.q)
        self.stopped, self.reason = False, ""

    def stop(self, reason: str) -> Command:
        """Stop cleanly: hold the last joints from now on, until reset."""
        self.stopped, self.reason = True, reason
        return Command(self.q.copy(), math.nan, True, reason)

    def jacobian(self) -> np.ndarray:
        """(3, 2N) ∂tip/∂q (mm/deg, mm/mm) at the current joints, by differences of the FK's probe
        (forwards, backwards where forwards would cross a stop; held joints: zero columns)."""
        P = self._probe_q
        P[:] = self.q
        idx = np.arange(2 * self._n)
        h = self._h.copy()
        beyond = (self._stops.A @ (self.q[:, None] + np.diag(h)) > self._stops.b[:, None] + 1e-9).any(axis=0)
        h[beyond] = -h[beyond]
        P[idx + 1, idx] += h
        tips, _ = self.fk.probe_tips(P)
        h = np.where(h != 0, h, 1.0)
        return np.asarray((tips[1:] - tips[0]).T / h)

    def _step(self, J: np.ndarray, e: np.ndarray) -> np.ndarray:
        """Δq (2N,): the damped least squares of e (3,) mm on J (3, 2N) that crosses no stop, plus the
        push away from near stops in the task's null space (module docstring)."""
        stops, w = self._stops, self._w
        slack = stops.slack(self.q)
        active = np.zeros(len(slack), bool)
        moves = (np.abs(stops.A) * w).sum(axis=1) > 0          # a stop only moving joints can reach
        Ja, ea, damp = J, e, self._eye
        for _ in range(len(slack) + 1):                      # each pass adds at least one stop
            JW = Ja * w
            dq = JW.T @ np.linalg.solve(JW @ Ja.T + damp, ea)
            new = stops.crossed(self.q, dq) & moves & ~active
            if not new.any():
                break
            active |= new
            Ja = np.vstack([J, stops.A[active]])
            ea = np.r_[e, np.maximum(slack[active], 0.0)]   # the stop reached, not crossed
            damp = np.diag(np.r_[np.diag(self._eye), np.full(int(active.sum()), 1e-12)])
        if self.config.stop_speed > 0:
            push, depth = stops.push(self.q, self.config.stop_zone)
            push = w * push
            if depth > 0 and np.any(push != 0):
                JW = J * w
                push = push - JW.T @ np.linalg.solve(JW @ J.T + self._eye, J @ push)
                over = np.max(np.abs(push) / self._vmax)
                if over > 0:
                    push *= depth * self.config.stop_speed / over
                    ok = ~stops.crossed(self.q, dq + push)
                    if ok.all():
                        dq = dq + push
        return np.asarray(dq)

    def _limit(self, dq: np.ndarray) -> np.ndarray:
        """Δq scaled as a whole within the velocity limits (q and q + Δq within the stops: so is the
        scaled step), then onto the joint limits (a guard: the step already keeps them)."""
        over = np.max(np.abs(dq) / self._vmax)
        if over > 1.0:
            dq = dq / over
        q = self.q + dq
        n = self._n
        q[:n] = np.clip(q[:n], *self.config.alpha_limits)
        return np.asarray(self.robot.project_joints(q[None, :])[0])

    def _switches_branch(self, q_new: np.ndarray) -> bool:
        """Whether the FK predicts a branch switch between the current joints and q_new."""
        probe = getattr(self.fk, "probe", None)
        if probe is None:
            return False
        try:
            _, states = probe(np.vstack([self.q, q_new]))
        except ModelError:
            return False
        return states is not None and len(states) == 2 and bool(states[0] != states[1])

    def cycle(self, measured: np.ndarray | None, target: np.ndarray,
              target_velocity: np.ndarray | None = None) -> Command:
        """One cycle: the tracker's tip pose (≥ 3,) mm (None: no frame this cycle) and the target tip
        (3,) mm with its velocity (3,) mm/s -> the joint command (module docstring)."""
        if self.stopped:
            return Command(self.q.copy(), math.nan, True, self.reason)
        if measured is None or not np.all(np.isfinite(measured[:3])):
            return self.stop("tracker lost: no valid frame this cycle")
        e = np.asarray(target, float) - np.asarray(measured[:3], float)
        err = float(np.linalg.norm(e))
        e = self.config.gain * e
        if target_velocity is not None:
            e = e + np.asarray(target_velocity, float) * self._dt
        dq = self._step(self.jacobian(), e)
        risk = False
        for _ in range(4):
            q_new = self._limit(dq)
            if not self._switches_branch(q_new):
                break
            risk, dq = True, 0.5 * dq
        else:
            return Command(self.q.copy(), err, False, "a step would switch branch (snap): held", True)
        self.q = q_new
        self.fk.step(self.q)
        return Command(self.q.copy(), err, False, "", risk)
