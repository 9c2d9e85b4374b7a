"""The learned snap model beside the mechanics: a learned FK with a branch state (the snap-aware
`lstm_mlp_branch`, the recommended FK) streamed along the planner's routes from the robot's state.

Only the streaming interface of ctrkin.inference.Kinematics is used (`reset`, `step`, and `probe`:
the poses and branch states the model would give for candidate next joints, nothing advanced), never
how the model sets its state: whatever gate it carries (a fold gate, a learned one) is what it
predicts.

**A predicted snap.** Along a route the model is stepped as the robot would be (the history since the
plan's start replayed first, then the route's ≤ 5° / 1 mm steps). A step whose branch state differs
from the last is a snap where the pose jumps across it: the step is cut into 32 candidate next steps
probed from the last state, and the tips on either side of the first flipped candidate (1/32 of a
step apart: ~0.05 mm of ordinary motion) are compared; a jump above `jump_mm` is a snap, a flip
without one a relabel (the labels' convention changes at α0 ≡ 0 and at the band's edge where the
pair is not bistable, docs/learned_kinematics.md, and the pose does not jump there).

**The learned margin** of a step: the inner-tube rotation left (deg) before the model predicts a snap,
either way: from the step's state, α1 ± k·5° probed as the next step (k = 1..cap/5) and the first
flip that is a snap (as above, located within 5°/16) gives it; none within the cap gives the cap.
It is a one-step look-ahead from the step's state: a model whose switch depends on the path taken
within that rotation (not only on where it ends) is probed as if the rotation were one step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ctrkin.errors import ModelError

CUTS = 32             # candidates a flipped step is cut into
PROBE_DEG = 5.0       # the margin's probe spacing
REFINE = 16           # candidates between two margin probes, where the state flips


@dataclass(frozen=True, eq=False)
class LearnedRoute:
    """A route (T steps) streamed on the learned FK: state (T,) the branch state after each step,
    snap (T,) bool a predicted snap in the step, jump_mm (T,) the predicted tip jump of a flip (0
    elsewhere), margin_deg (T,) the inner rotation left before a predicted snap (≤ cap); refused: why
    the model would not step along it ("" if it did; e.g. joints more than a turn outside its trained
    range: it would extrapolate), the arrays then cut at the refused step."""

    state: np.ndarray
    snap: np.ndarray
    jump_mm: np.ndarray
    margin_deg: np.ndarray
    refused: str = ""

    def last(self) -> LearnedRoute:
        """The route's last step as a one-step route."""
        return LearnedRoute(self.state[-1:], self.snap[-1:], self.jump_mm[-1:], self.margin_deg[-1:])


class LearnedSnapModel:
    """A learned FK with a branch state, streamed from the robot's state (module docstring).

    kin: a Kinematics of an FK that probes and has a branch state (lstm_mlp_branch); jump_mm: a flip
    counts as a snap above this predicted tip jump (mm); cap_deg: the margin's reach (deg);
    reset: options of kin.reset at the plan's start (e.g. outer_motion, how the outer tube last
    turned). history, state, here: the joints the robot came through since `start`, the branch state
    they left, and that last step as a one-step LearnedRoute."""

    def __init__(self, kin: Any, jump_mm: float = 2.0, cap_deg: float = 180.0,
                 reset: dict[str, Any] | None = None) -> None:
        if getattr(kin, "task", None) != "fk" or not getattr(kin, "probes", False):
            raise ModelError("the planner's learned snap model is an FK that probes candidate joints "
                             "(the snap-aware lstm_mlp_branch)")
        if "branch_states" not in getattr(kin.predictor, "accepts", {}).get("predict", ()):
            raise ModelError(f"model {kin.path or '(in memory)'} ({kin.config.get('model')}) has no branch "
                             "state: the planner's learned snap model needs a snap-aware FK "
                             "(lstm_mlp_branch)")
        self.kin = kin.copy()               # a stream of its own: the caller's is never touched
        self.jump_mm, self.cap_deg = float(jump_mm), float(cap_deg)
        self._reset = dict(reset or {})
        self.history: list[np.ndarray] = []
        self.state = -1                     # the branch state the history left
        self.here = LearnedRoute(np.array([-1]), np.zeros(1, bool), np.zeros(1), np.full(1, np.nan))

    @staticmethod
    def _state(states: np.ndarray | None) -> int:
        return -1 if states is None or not np.isfinite(states[0]) else round(float(states[0]))

    def _replay(self, rows: list[np.ndarray]) -> None:
        self.kin.reset(**self._reset)
        for q in rows:
            self.kin.step(np.ascontiguousarray(q, dtype=np.float64))

    def start(self, q0: np.ndarray, history: np.ndarray | None = None) -> LearnedRoute:
        """The robot is at joints q0 (2N,), having come through `history` (H, 2N) (None: it starts
        there, the model's state its own at a sequence start). Returns the start as a one-step route."""
        rows = [] if history is None else [np.asarray(h, float) for h in np.atleast_2d(history)]
        self.history, self.state = [], -1
        route = self.stream(np.array([*rows, np.asarray(q0, float)]))
        if route.refused:
            raise ModelError(f"the learned snap model cannot start at the robot's joints: {route.refused}")
        if route.state[-1] < 0:
            raise ModelError(f"model {self.kin.path or '(in memory)'} has no branch state: the planner's "
                             "learned snap model needs a snap-aware FK (lstm_mlp_branch)")
        self.history, self.state = [*rows, np.asarray(q0, float)], int(route.state[-1])
        self.here = route.last()
        return self.here

    def accept(self, q: np.ndarray, route: LearnedRoute) -> None:
        """The robot moves through q (T, 2N), streamed as `route`: it becomes history."""
        self.history.extend(np.asarray(q, float))
        self.state = int(route.state[-1])
        self.here = route.last()

    def stream(self, q: np.ndarray, margins: bool = True) -> LearnedRoute:
        """Step the model along q (T, 2N) after the history (module docstring); nothing is kept.
        margins=False: states and snaps only (margin NaN)."""
        q = np.atleast_2d(np.asarray(q, float))
        self._replay(self.history)
        T = len(q)
        state, snap = np.full(T, -1), np.zeros(T, bool)
        jump, margin = np.zeros(T), np.full(T, np.nan)
        prev_q = self.history[-1] if self.history else None
        prev_s = self.state if self.history else None
        for t in range(T):
            _, states = self.kin.probe(q[t][None])
            s = self._state(states)
            if prev_s is not None and prev_q is not None and s != prev_s:
                jump[t] = self._jump(prev_q + np.linspace(0.0, 1.0, CUTS + 1)[:, None] * (q[t] - prev_q),
                                     prev_s)
                snap[t] = jump[t] > self.jump_mm
            try:
                self.kin.step(np.ascontiguousarray(q[t]))
            except ModelError as e:     # outside what it knows: it cannot vouch for the route
                return LearnedRoute(state[:t], snap[:t], jump[:t], margin[:t], str(e))
            state[t] = s
            if margins:
                margin[t] = self._margin(q[t], s)
            prev_q, prev_s = q[t], s
        return LearnedRoute(state, snap, jump, margin)

    def _jump(self, cands: np.ndarray, s0: int) -> float:
        """The predicted tip jump (mm) at the first of K candidate next joints cands (K, 2N), ordered
        along a path from the current state s0, whose state differs from s0 (0 if none does)."""
        poses, states = self.kin.probe(cands)
        flipped = np.nonzero(np.rint(states) != s0)[0]
        if len(flipped) == 0:
            return 0.0
        k = int(flipped[0])
        if k == 0:          # flipped without moving (the model's own history): no jump to measure
            return 0.0
        return float(np.linalg.norm(poses[k, :3] - poses[k - 1, :3]))

    def _margin(self, q: np.ndarray, s: int) -> float:
        """The inner rotation (deg) from q (2N,), the stream at its state s, before a predicted snap
        either way (module docstring), at most cap_deg."""
        steps = np.arange(1, int(self.cap_deg // PROBE_DEG) + 1) * PROBE_DEG
        best = self.cap_deg
        for sign in (1.0, -1.0):
            cands = np.repeat(q[None], len(steps) + 1, axis=0)
            cands[1:, 0] += sign * steps
            _, states = self.kin.probe(cands)
            st = np.rint(states).astype(int)
            st[0] = s
            for k in np.nonzero(st[1:] != st[:-1])[0] + 1:          # every flip along the probes
                a, b = (k - 1) * PROBE_DEG, k * PROBE_DEG
                if a >= best:
                    break
                fine = np.repeat(q[None], REFINE + 1, axis=0)
                fine[:, 0] += sign * np.linspace(a, b, REFINE + 1)
                poses, fs = self.kin.probe(fine)
                f = np.nonzero(np.rint(fs) != st[k - 1])[0]
                if len(f) == 0 or f[0] == 0:
                    continue
                j = int(f[0])
                if np.linalg.norm(poses[j, :3] - poses[j - 1, :3]) > self.jump_mm:
                    best = min(best, a + (j - 0.5) * (b - a) / REFINE)
                    break
        return float(best)
