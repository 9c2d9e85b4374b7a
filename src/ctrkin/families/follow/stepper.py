"""The follow IK's streaming step: the robot's joints and the previous target are its state; each
target moves the joints by the network's joint change, through intermediate targets
when it lies farther than the training steps (substeps).

A sequence starts from joints the caller gives (where the robot is) or, without them, from the
joints of the nearest training target; either way the network is applied `settle_iterations` times
at the first target (its training from perturbed joints makes each application a correction).
A destination is settled on likewise, `arrive_iterations` more applications there
(ARRIVE_ITERATIONS at training): a far target (reached through ARRIVE_SUBSTEPS or more
intermediate targets, farther away than twice the training steps' 95th percentile) in a path of far
targets (the one before it far too, or the sequence's first), as a list of waypoints is. A path of
close targets (a recorded sequence, a control loop's stream) never takes them, not even where one of
its targets jumps (a snap): there settling cost accuracy on the validation sequences
(docs/learned_kinematics.md: Settling at a far target).

The outer tube lags its motor by λ(β) in the direction the motor last turned (ctrkin.models.outer_lag;
stored as `outer_lag_deg` in the model's follow settings). The network learned from turns recorded
after a forward outer step, so its joints are those of a tube lagging by +λ; the motor command it
returns is the play's inverse for the tube angle the network means (Follower._backlash_inverse), and
a start at rest is seen by the network with the tube's angle + λ. Both use the share
`outer_inversion` (OUTER_INVERSION at training) of λ: the identified lag is not all play.

Along the targets an application makes no joint change smaller than the dead zone (`dead_zone`,
DEAD_ZONE at training: α deg, β mm): on a robot with friction each small change the network's
answer wobbles by runs the tubes through a stretch of their hysteresis, and its drift in joints the
targets barely show (β2 above all) adds up along a sequence. Settling (a sequence's first target,
a destination) corrects with changes of any size.

On the way to a destination (the intermediate targets before a far target in a path of far targets:
the stepper's own interpolation, not poses anyone asked for) an application changes the joints by at
most `substep_cap` (SUBSTEP_CAP at training: α deg, β mm), its change scaled down as a whole: on a
robot with friction an unbounded correction towards an interpolated pose can carry the tubes onto
another branch (a snap) on the way, and the destination's settling (uncapped) makes up what the cap
held back. A stream's far target after a close one (a snap in the targets) is neither capped nor
settled on.

With the play lags (FeatureLayout.play) the follower carries the play operators of its targets'
positions (ctrkin.models.play_lags.TargetPlay): at rest at a sequence's first target (every lag 0, as
a recorded run starts), then advanced to each (sub-)target before the network sees it.

Both sides of the family run it (a policy's reset() / step()): its recipe rolls the network out along
the training sequences and scores it (ctrkin.families.follow.recipe), and its predictor predicts with
it (ctrkin.families.follow.predictor).
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np

from ctrkin.errors import ModelError
from ctrkin.families.follow.features import follow_features, substeps
from ctrkin.models.engine import StreamingEngine
from ctrkin.models.features import real_array
from ctrkin.models.guards import check_joints
from ctrkin.models.outer_lag import lag_one
from ctrkin.models.play_lags import TargetPlay
from ctrkin.models.seqnet import SeqNet
from ctrkin.models.store import ModelBundle
from ctrkin.models.workspace import Workspace

HOLD_DEG = 0.5   # a reversal of the outer tube smaller than this keeps the motor (no trip through the play)
# the share of the identified outer lag λ(β) that the stepper inverts as a play (OUTER_INVERSION·λ each
# side); chosen on the validation sequences via the robot of six reproductions (docs/learned_kinematics.md:
# How much of the outer lag to invert): part of λ comes back when the motor reverses, so a full 2λ trip
# overshoots
OUTER_INVERSION = 0.25
# the smallest joint change an application along the targets sends (α deg, β mm): a smaller change the
# network asks for is not made (module docstring; chosen on validation sequences and paths:
# docs/learned_kinematics.md, The follow IK's dead zone)
DEAD_ZONE = (2.0, 0.1)
# a destination: reached through ARRIVE_SUBSTEPS or more sub-targets, settled on with ARRIVE_ITERATIONS
# applications (chosen on validation: docs/learned_kinematics.md, Settling at a far target, and with the
# cap below, The cap on the way to a destination)
ARRIVE_ITERATIONS = 4
ARRIVE_SUBSTEPS = 3
# the largest joint change (α deg, β mm) of an application on the way to a destination (module docstring;
# chosen on validation squares and triangles of seven reproductions with ARRIVE_ITERATIONS:
# docs/learned_kinematics.md, The cap on the way to a destination)
SUBSTEP_CAP = (3.0, 0.3)


def _pair(value: object) -> tuple[float, float] | None:
    """value (a follow setting) as two finite numbers, or None where it is not."""
    try:
        a, b = (float(v) for v in value)      # type: ignore[attr-defined]
    except (TypeError, ValueError):
        return None
    return (a, b) if np.isfinite(a) and np.isfinite(b) else None


def _number(value: object) -> float:
    """value (a follow setting) as a finite number, or NaN where it is not."""
    try:
        x = float(value)                      # type: ignore[arg-type]
    except (TypeError, ValueError):
        return np.nan
    return x if np.isfinite(x) else np.nan


class Follower:
    """Step-by-step state of a follow IK model (bundle) with its training workspace."""

    def __init__(self, bundle: ModelBundle, workspace: Workspace | None) -> None:
        if bundle.frame is None or not isinstance(bundle.net, SeqNet):
            raise ModelError("a follow IK needs its outer-tube frame (frame.json) and an MLP network")
        self.n = bundle.layout.n_tubes
        self.robot = bundle.robot
        self.frame = bundle.frame
        self.net = bundle.net
        self.engine = StreamingEngine(bundle.net)
        self.x_norm, self.y_norm = bundle.x_norm, bundle.y_norm
        settings = bundle.extra.get("follow", {})
        self.max_step_mm = float(settings.get("max_step_mm", 1.0))
        self.settle = int(settings.get("settle_iterations", 5))
        self.iterations = int(settings.get("iterations", 1))    # applications per (sub-)target
        # ... at a far target; a folder trained before the setting settles as it did since (2)
        self.arrive = int(settings.get("arrive_iterations", 2))
        self.workspace = workspace
        lag = settings.get("outer_lag_deg", (0.0, 0.0))
        self.lag = (float(lag[0]), float(lag[1]))     # the outer tube's lag λ(β) (models.outer_lag)
        # the share of λ inverted and the dead zone (deg, mm); a folder trained before these settings
        # has neither and steps as it did (the whole λ, no zone), so it predicts what it predicted
        self.inversion = _number(settings.get("outer_inversion", 1.0))
        zone = _pair(settings.get("dead_zone", (0.0, 0.0)))
        if zone is None or min(zone) < 0 or not self.inversion >= 0:
            raise ModelError(f"the follow settings' dead_zone must be two numbers ≥ 0 (α deg, β mm) and "
                             f"outer_inversion a number ≥ 0; got {settings.get('dead_zone')} and "
                             f"{settings.get('outer_inversion')}")
        self.dead_zone: tuple[float, ...] = zone
        # the cap on the way to a destination (deg, mm); None (a folder trained before it): no cap
        cap = settings.get("substep_cap")
        self.substep_cap = None if cap is None else _pair(cap)
        if cap is not None and (self.substep_cap is None or min(self.substep_cap) <= 0):
            raise ModelError(f"the follow settings' substep_cap must be two numbers > 0 (α deg, β mm), "
                             f"got {cap}")
        self.joints: np.ndarray | None = None        # where the robot is, as the network sees it
        self.target: np.ndarray | None = None        # the previous target of this sequence
        self.hold_deg = HOLD_DEG
        self.tube = np.nan                           # the outer tube's angle (deg), NaN: not known yet
        self.motor = np.nan                          # the outer motor's last command (deg)
        self.play = TargetPlay() if bundle.layout.play else None      # the target path's operators
        self.outer_angle = bundle.layout.outer_angle                 # sin/cos αN among the inputs
        self.far = True                              # the last target was far, or the sequence's first

    def reset(self, joints: np.ndarray | None = None) -> None:
        """Start a sequence, at `joints` (2N,) (deg, mm) if the robot's joints are known."""
        if joints is not None:
            q = real_array(joints).reshape(-1)
            if q.shape != (2 * self.n,) or not np.all(np.isfinite(q)):
                raise ModelError(f"start joints must be {2 * self.n} finite numbers (α deg, β mm), got "
                                 f"{np.asarray(joints).tolist()}")
            joints = check_joints(self.robot, q)       # as every model input of joints
        self.joints, self.target, self.tube, self.motor = None, None, np.nan, np.nan
        self.far = True
        if self.play is not None:
            self.play.reset()
        if joints is not None:
            self._at_rest(joints)

    def twin(self) -> Follower:
        """A follower of the same network and settings (as they are now: lag, hold, substeps) with a
        state of its own, at a sequence start."""
        twin = copy.copy(self)
        twin.engine = StreamingEngine(self.net)
        twin.play = None if self.play is None else TargetPlay()
        twin.reset()
        return twin

    def run(self, targets: np.ndarray, bounds: list[tuple[int, int]],
            starts: Sequence[np.ndarray | None] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Follow each sequence [a, b) of `bounds` through targets (T, 6) (tracker frame), from its
        start joints (2N,) (deg, mm; None: those of the nearest training target) -> joints (T, 2N)
        and whether each had to be projected onto the robot's limits (T,); rows outside `bounds` are
        NaN / False. The run steps a twin: this follower's own stream (reset / step) is untouched."""
        joints = np.full((len(targets), 2 * self.n), np.nan)
        projected = np.zeros(len(targets), bool)
        runner = self.twin()
        for (a, b), start in zip(bounds, [None] * len(bounds) if starts is None else starts, strict=True):
            runner.reset(start)
            for t in range(a, b):
                joints[t], projected[t] = runner.step(targets[t])
        return joints, projected

    def _lag(self, q: np.ndarray) -> float:
        """The play the stepper inverts at joints q: `inversion` · λ(β) (deg)."""
        return 0.0 if self.lag == (0.0, 0.0) else self.inversion * lag_one(self.robot, q, self.lag)

    def _at_rest(self, q: np.ndarray) -> None:
        """The robot stands at motor joints q, its outer tube at rest (m_N = 0: tube = motor). The
        network learned from turns after a forward outer step, where the tube lags by λ, so it sees
        the joints whose outer angle is the tube's + λ (the inverted share of it, `_lag`)."""
        self.tube = self.motor = float(q[self.n - 1])
        self.joints = q.copy()
        self.joints[self.n - 1] += self._lag(q)

    def _backlash_inverse(self, q: np.ndarray) -> np.ndarray:
        """Motor joints for the network's answer q: the tube is to stand at θ = q_N − λ; the motor
        goes to θ + λ turning forward, θ − λ turning back, and stays where the tube does not move
        (the inverse of the transmission's play, ctrkin.virtual.transmission), with λ the inverted
        share of λ(β) (`_lag`)."""
        out = q.copy()
        if self.lag == (0.0, 0.0):
            return out
        lam = self._lag(q)
        theta = float(q[self.n - 1]) - lam
        if theta > self.tube + self.hold_deg or (theta > self.tube and self.motor - self.tube > 0):
            out[self.n - 1] = theta + lam          # forward, or on along the side the play is taken up
        elif theta < self.tube - self.hold_deg or (theta < self.tube and self.motor - self.tube < 0):
            out[self.n - 1] = theta - lam
        else:                                      # a reversal smaller than hold_deg: the tube stays
            out[self.n - 1] = self.motor
            return out
        self.tube, self.motor = theta, float(out[self.n - 1])
        return out

    def step(self, target: np.ndarray) -> tuple[np.ndarray, bool]:
        """target (6,) tracker-frame pose -> (joints (2N,) within the robot's limits, whether the
        network's answer had to be projected onto them)."""
        if self.target is None:
            if self.joints is None:
                if self.workspace is None:
                    raise ModelError("a follow IK without its workspace needs start joints (reset(joints))")
                self._at_rest(self.workspace.nearest_joints(target))
            assert self.joints is not None
            q, projected = self.joints, False
            lags = self._target_lags(target)
            for _ in range(self.settle):                     # settling: corrections of any size
                q, projected = self._apply(target, target, q, lags, dead_zone=False)
        else:
            assert self.joints is not None
            q, projected, previous = self.joints, False, self.target
            subs = substeps(previous, target, self.max_step_mm)
            far = len(subs) >= ARRIVE_SUBSTEPS
            destination = far and self.far                  # a far target in a path of far targets
            cap = self.substep_cap if destination else None  # on the way there: capped
            for sub in subs:
                lags = self._target_lags(sub)
                for _ in range(self.iterations):
                    q, projected = self._apply(sub, previous, q, lags, cap=cap)
                    previous = sub
            for _ in range(self.arrive if destination else 0):          # settling there
                q, projected = self._apply(target, target, q, lags, dead_zone=False)
            self.far = far
        self.joints, self.target = q, np.array(target, dtype=np.float64)
        motor = self._backlash_inverse(q)
        valid = self.robot.project_joints(motor[None])[0]
        return valid, projected or bool(np.any(np.abs(valid - motor) > 1e-9))

    def _target_lags(self, target: np.ndarray) -> np.ndarray | None:
        """With the play lags: their operators advanced to this (sub-)target's position, the lags."""
        return None if self.play is None else self.play.advance(target[:3])[None]

    def _apply(self, target: np.ndarray, previous: np.ndarray, q: np.ndarray,
               lags: np.ndarray | None = None, dead_zone: bool = True,
               cap: tuple[float, ...] | None = None) -> tuple[np.ndarray, bool]:
        feat = follow_features(self.frame, self.n, target[None], previous[None], q[None], lags,
                               self.outer_angle)[0]
        dq = self.y_norm.inverse(self.engine.step(self.x_norm.transform(feat)))
        if cap is not None:                                    # on the way to a destination
            big = (float(np.abs(dq[:self.n]).max()) / cap[0], float(np.abs(dq[self.n:]).max()) / cap[1])
            if max(big) > 1.0:
                dq = dq / max(big)
        if dead_zone:                                          # a step along the targets (DEAD_ZONE)
            a_deg, b_mm = self.dead_zone
            dq[:self.n][np.abs(dq[:self.n]) < a_deg] = 0.0
            dq[self.n:][np.abs(dq[self.n:]) < b_mm] = 0.0
        new = q + dq
        valid = self.robot.project_joints(new[None])[0]
        return valid, bool(np.any(np.abs(valid - new) > 1e-9))
