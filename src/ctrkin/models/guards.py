"""Input guards of a learned FK model, shared by `Kinematics.predict` and `Kinematics.step`.

A learned model knows only the joints it was trained on. Joints that the robot cannot take (β2 > 0,
NaN) are an error (JointError, from `Robot.check_joints`). Rotations are periodic: αi and αi + 360° are
the same tube position, so a sequence that starts outside the trained α range is shifted, per tube, by
the whole turns that bring its first step into the range (the same shift for every step of the
sequence, so Δα0 and the history are untouched; predict and step shift alike). A step that is then
still more than one turn outside the trained range is an error (ModelError): the network would
extrapolate (α = 1e5 and α mod 360 gave poses 28 mm apart).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ctrkin.data.schema import QUAT_NORM_TOL
from ctrkin.errors import JointError, ModelError
from ctrkin.models.features import FeatureLayout
from ctrkin.models.normalize import MinMax
from ctrkin.robots.robot import Robot

TURN_DEG = 360.0
MAX_ABS_ALPHA_DEG = 1e9      # beyond this a float angle has no sub-millidegree resolution left
RANGE_SLACK_DEG = TURN_DEG   # how far past the trained α range a (shifted) step may go


class FKGuard:
    """Checks and α shifts for the joints (T, 2N) (deg, mm) fed to an FK model."""

    def __init__(self, robot: Robot, layout: FeatureLayout, x_norm: MinMax) -> None:
        self.robot = robot
        self.n = layout.n_tubes
        names = list(layout.input_names)
        cols = [names.index(f"alpha_{i + 1}") for i in range(self.n) if f"alpha_{i + 1}" in names]
        self.periodic_only = len(cols) != self.n     # sin/cos encoding: any α is in range
        if not self.periodic_only:
            self.lo = np.asarray(x_norm.lo, float)[cols]
            self.hi = np.asarray(x_norm.hi, float)[cols]
            self._lo_arr, self._hi_arr = self.lo - RANGE_SLACK_DEG, self.hi + RANGE_SLACK_DEG
            self._lo = self._lo_arr.tolist()     # scalar bounds of the fast path
            self._hi = self._hi_arr.tolist()

    def check(self, raw: np.ndarray) -> None:
        """Raise JointError for joints the robot cannot take or absurd angles. raw: (T, 2N) or (2N,)."""
        check_joints(self.robot, raw)

    def shift(self, first: np.ndarray) -> np.ndarray:
        """(2N,) whole turns to subtract from every step of a sequence whose first step is `first`:
        nonzero only for a tube whose first α lies outside the trained range."""
        out = np.zeros(2 * self.n)
        if self.periodic_only:
            return out
        for i in range(self.n):
            a = float(first[i])
            if self.lo[i] <= a <= self.hi[i]:
                continue
            centre = 0.5 * (self.lo[i] + self.hi[i])
            out[i] = TURN_DEG * math.floor((a - centre) / TURN_DEG + 0.5)
        return out

    def nearest_turns(self, Q: np.ndarray) -> np.ndarray:
        """Q (K, 2N) with each α moved by whole turns (the same configuration) to the representative
        nearest the middle of the trained range; unchanged for a sin/cos encoding."""
        out = np.array(Q, dtype=float, copy=True)
        if not self.periodic_only:
            mid = 0.5 * (self.lo + self.hi)
            out[:, : self.n] -= TURN_DEG * np.round((out[:, : self.n] - mid) / TURN_DEG)
        return out

    def check_range(self, shifted: np.ndarray) -> None:
        """Raise ModelError if a shifted step is more than a turn outside the trained α range."""
        if self.periodic_only:
            return
        alpha = np.atleast_2d(shifted)[:, : self.n]
        if _alphas_within(alpha, self._lo_arr, self._hi_arr):    # one pass where every step passes
            return
        bad = (alpha < self.lo - RANGE_SLACK_DEG) | (alpha > self.hi + RANGE_SLACK_DEG)
        if bad.any():
            r, i = (int(v[0]) for v in np.nonzero(bad))
            raise ModelError(
                f"alpha_{i + 1} = {alpha[r, i]:.6g} deg (after whole-turn shifts) at step {r} is more than "
                f"a turn outside the range the model was trained on [{self.lo[i]:.6g}, {self.hi[i]:.6g}] "
                "deg: it would extrapolate. Record training data there, or start the sequence nearer")

    def prepare(self, raw: np.ndarray, bounds: list[tuple[int, int]]) -> np.ndarray:
        """Check a batch raw (T, 2N) of sequences `bounds`; return it with each sequence shifted."""
        self.check(raw)
        out = np.array(raw, dtype=float, copy=True)
        for a, b in bounds:
            if b > a:
                out[a:b] -= self.shift(out[a])
        self.check_range(out)
        return out

    def step(self, raw: np.ndarray, shift: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """One streaming step (2N,): checked, shifted by the sequence's turns (fixed by its first step,
        `shift` None). Returns (shifted step, shift). Raises before any model state is touched."""
        if shift is not None and self._fast_ok(raw, shift):       # the control-loop case
            return raw - shift, shift
        self.check(raw)
        if shift is None:
            shift = self.shift(raw)
        out = raw - shift
        self.check_range(out)
        return out, shift

    def _fast_ok(self, raw: np.ndarray, shift: np.ndarray) -> bool:
        """Scalar version of check + check_range for one step that passes both (else the full checks
        run and raise with their messages)."""
        self.robot.check_joints(raw)              # its fast path for one valid configuration
        vals, sh = raw.tolist(), shift.tolist()
        for i in range(self.n):
            a = vals[i]
            if abs(a) > MAX_ABS_ALPHA_DEG:
                return False
            if not self.periodic_only and not (self._lo[i] <= a - sh[i] <= self._hi[i]):
                return False
        return True


def check_joints(robot: Robot, raw: np.ndarray) -> np.ndarray:
    """Joints raw (T, 2N) or (2N,) (deg, mm) that a model may take: those the robot can take
    (Robot.check_joints, JointError) with no α beyond ±MAX_ABS_ALPHA_DEG (JointError: an angle that
    large has lost its fraction of a turn). Every model input of joints passes here: an FK's inputs
    in batch and streaming, a follow IK's start joints. Returns them as a float array."""
    q = robot.check_joints(raw)
    alpha = np.atleast_2d(q)[:, : robot.n_tubes]
    bound = np.full(robot.n_tubes, MAX_ABS_ALPHA_DEG)
    if not _alphas_within(alpha, -bound, bound):
        r = int(np.argmax(np.abs(alpha).max(axis=1)))
        raise JointError(f"rotation {alpha[r].tolist()} deg at row {r} exceeds ±{MAX_ABS_ALPHA_DEG:g} deg; "
                         "wrap the angles (α mod 360 is the same joint)")
    return q


@njit(cache=True)
def _alphas_within(alpha: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether every α of alpha (T, N) deg lies in [lo, hi] (N,) (NaN does not): the checks' one pass
    where every row passes (a 1,024-row predict spent ~0.15 ms in numpy's temporaries here)."""
    for t in range(alpha.shape[0]):
        for i in range(alpha.shape[1]):
            if not lo[i] <= alpha[t, i] <= hi[i]:
                return False
    return True


def check_poses(raw: np.ndarray) -> None:
    """IK targets raw (T, 6) or (6,) (x, y, z mm, q0, qx, qy) must be finite and their quaternions
    unit to QUAT_NORM_TOL, the import's rule (ctrkin.data.schema): a zero or far-from-unit quaternion
    names no tip direction (ModelError), whatever the family, in batch and streaming."""
    rows = np.atleast_2d(raw)
    finite = np.isfinite(rows).all(axis=1)
    if not finite.all():
        r = int(np.argmax(~finite))
        raise ModelError(f"IK target pose contains NaN or inf at row {r}: {rows[r].tolist()}")
    norm = np.linalg.norm(rows[:, 3:6], axis=1)
    bad = np.abs(norm - 1.0) > QUAT_NORM_TOL
    if bad.any():
        r = int(np.argmax(bad))
        raise ModelError(f"IK target at row {r} has the quaternion (q0, qx, qy) = {rows[r, 3:6].tolist()} of "
                         f"norm {norm[r]:.4g}: a target's orientation is a unit quaternion (within "
                         f"{QUAT_NORM_TOL:g}); normalise it, or give the tip tangent as one "
                         "(ctrkin.geometry.quat_from_tangent)")


def check_pose_step(raw: np.ndarray) -> None:
    """A streaming IK target (6,) must be finite with a unit quaternion (check_poses: ModelError),
    before any state is touched (in scalar arithmetic where it passes: the control-loop case)."""
    v = raw.tolist()
    if all(map(math.isfinite, v)) and abs(math.sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5]) - 1.0) \
            <= QUAT_NORM_TOL:
        return
    check_poses(raw)
