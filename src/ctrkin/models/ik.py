"""What every IK predictor returns, and the flags they all compute alike: whether a target lies in
the trained workspace (ctrkin.models.workspace) and whether the answer jumped (an α change of more
than JUMP_DEG while the target moved less than JUMP_TARGET_MM: a switch between solutions, not a
continuous path)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ctrkin.errors import ModelError
from ctrkin.metrics import wrap_deg
from ctrkin.models.features import POSE_NAMES, by_name, real_array
from ctrkin.models.guards import check_pose_step
from ctrkin.models.workspace import Workspace

JUMP_DEG, JUMP_TARGET_MM = 20.0, 1.0    # an α change this large between targets this close is flagged


@dataclass(eq=False)
class IKResult:
    """joints: (T, 2N) (deg, mm), always within the robot's joint limits; in_workspace: (T,) whether
    each target lies in the trained workspace; distance: (T,) normalised distance to the nearest
    training target; reasons: why not, per step; projected: (T,) the network's joints were outside
    the limits and were projected onto them; residual_mm: (T,) tip distance from the target that the
    learned FK predicts for the joints (refined IK; NaN otherwise); jump: (T,) some α changed by more
    than 20° from the previous step although the target moved less than 1 mm (a switch between
    solutions, not a continuous path)."""

    joints: np.ndarray
    in_workspace: np.ndarray
    distance: np.ndarray
    reasons: list[str]
    projected: np.ndarray | None = None
    residual_mm: np.ndarray | None = None
    jump: np.ndarray | None = None

    @property
    def all_in_workspace(self) -> bool:
        return bool(np.all(self.in_workspace))


class IKStep(NamedTuple):
    joints: np.ndarray     # (2N,) deg, mm
    in_workspace: bool
    reason: str
    projected: bool = False
    residual_mm: float = math.nan
    jump: bool = False


def target_pose(x: object) -> np.ndarray:
    """A streaming IK target as (6,) float64, refused (ModelError) if it is not 6 finite real numbers,
    before any state is touched."""
    raw = real_array(by_name(x, tuple(POSE_NAMES), "target pose"))
    if raw.shape != (6,):
        raise ModelError(f"step() expects shape (6,), got {raw.shape}")
    check_pose_step(raw)
    return raw


def jumps(targets: np.ndarray, joints: np.ndarray, bounds: list[tuple[int, int]], n: int) -> np.ndarray:
    """(T,) the IKStep.jump flag for a batch: α changed > JUMP_DEG while the target moved
    < JUMP_TARGET_MM since the previous step of the same sequence."""
    out = np.zeros(len(targets), dtype=bool)
    for a, b in bounds:
        if b - a < 2:
            continue
        moved = np.linalg.norm(np.diff(targets[a:b, :3], axis=0), axis=1)
        turned = np.abs(wrap_deg(np.diff(joints[a:b, :n], axis=0))).max(axis=1)
        out[a + 1:b] = (moved < JUMP_TARGET_MM) & (turned > JUMP_DEG)
    return out


def workspace_check(workspace: Workspace | None, raw: np.ndarray, strict: bool
                    ) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The batch workspace test of targets raw (T, 6): (in_workspace (T,), distance (T,), reasons);
    strict: ModelError at the first target outside."""
    if workspace is None:
        raise ModelError("this IK model has no workspace (workspace.npz); retrain it with ctrkin train")
    ok, dist, reasons = workspace.check(raw)
    if strict and not ok.all():
        bad = np.nonzero(~ok)[0]
        raise ModelError(f"{len(bad)} IK target(s) outside the trained workspace, first at step "
                         f"{bad[0]}: {reasons[bad[0]]}")
    return ok, dist, reasons


class StepFlags:
    """The streaming flags of an IK predictor: the workspace test of each target (with the nearest
    training target of the previous step as the search's start) and the jump flag (the previous
    target and answer of the sequence)."""

    def __init__(self, workspace: Workspace | None, n_tubes: int) -> None:
        self.workspace = workspace
        self.n = n_tubes
        self._hint = 0
        self._prev: tuple[np.ndarray, np.ndarray] | None = None

    def reset(self) -> None:
        """A new sequence: no previous answer (the workspace search keeps its start)."""
        self._prev = None

    @property
    def previous_joints(self) -> np.ndarray | None:
        """The answer of the previous step of the sequence (None at its start)."""
        return None if self._prev is None else self._prev[1]

    def check(self, raw: np.ndarray, check: bool, strict: bool) -> tuple[bool, str]:
        """Is target raw (6,) in the trained workspace (True, "" unchecked); strict: ModelError if not."""
        if not check:
            return True, ""
        assert self.workspace is not None
        ok, reason, self._hint = self.workspace.check_one(raw, self._hint)
        if strict and not ok:
            raise ModelError(f"IK target outside the trained workspace: {reason}")
        return ok, reason

    def answer(self, raw: np.ndarray, q: np.ndarray, ok: bool, reason: str, projected: bool,
               residual: float = math.nan) -> IKStep:
        """The IKStep of joints q (2N,) for target raw (6,), with its jump flag; q becomes the
        previous answer."""
        jump = False
        if self._prev is not None:
            moved = float(np.linalg.norm(raw[:3] - self._prev[0][:3]))
            turned = np.abs(wrap_deg(q[:self.n] - self._prev[1][:self.n]))
            jump = bool(moved < JUMP_TARGET_MM and turned.max() > JUMP_DEG)
        self._prev = (raw, q)
        return IKStep(q, ok, reason, projected, residual, jump)
