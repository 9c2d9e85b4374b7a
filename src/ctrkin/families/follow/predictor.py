"""The follow IK in use: each sequence followed step by step by its streaming step
(ctrkin.families.follow.stepper) from the joints the robot is at (`start_joints`, `reset(joints)`)
or, without them, from those of the nearest training target."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.errors import ModelError
from ctrkin.families.follow.stepper import Follower
from ctrkin.models.ik import IKResult, IKStep, StepFlags, jumps, target_pose, workspace_check
from ctrkin.models.predictor_base import BasePredictor
from ctrkin.models.store import ModelBundle
from ctrkin.models.workspace import Workspace


class FollowPredictor(BasePredictor):
    """A follow IK model with its training workspace (module docstring)."""

    accepts: ClassVar[dict[str, frozenset[str]]] = {"predict": frozenset({"start_joints"}),
                                                     "reset": frozenset({"joints"})}

    def __init__(self, bundle: ModelBundle, workspace: Workspace | None) -> None:
        super().__init__(bundle, workspace)
        self.follower = Follower(bundle, workspace)
        self._flags = StepFlags(workspace, self.layout.n_tubes)

    @property
    def follower_lag(self) -> tuple[float, float]:
        """The outer lag (a deg, b deg/mm) of λ = a + b·overlap (ctrkin.models.outer_lag), identified
        on the training rows, of which the stepper inverts the share `Follower.inversion` as a play;
        (0, 0) for a follow IK trained before it."""
        return self.follower.lag

    def predict(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                strict: bool = False, start_joints: np.ndarray | None = None, **options: Any) -> IKResult:
        """Each sequence step by step from its start joints: start_joints (S, 2N) or (2N,), the robot's
        joints at the start of each of the S sequences (default: the nearest training target's)."""
        raw, bounds = self.raw_inputs(data, sequence_id)
        ok, dist, reasons = workspace_check(self.workspace, raw, strict)
        n2 = 2 * self.layout.n_tubes
        starts: list[np.ndarray | None] = [None] * len(bounds)
        if start_joints is not None:
            arr = np.asarray(start_joints, dtype=np.float64)
            arr = np.broadcast_to(arr, (len(bounds), n2)) if arr.shape == (n2,) else arr
            if arr.shape != (len(bounds), n2):
                raise ModelError(f"start_joints must have shape ({n2},) or ({len(bounds)}, {n2}) (one row "
                                 f"per sequence), got {np.asarray(start_joints).shape}")
            starts = list(arr)
        joints, projected = self.follower.run(raw, bounds, starts)
        return IKResult(joints, ok, dist, reasons, projected, np.full(len(raw), np.nan),
                        jumps(raw, joints, bounds, self.layout.n_tubes))

    def new_stream(self) -> None:
        super().new_stream()
        self.follower = self.follower.twin()
        self._flags = StepFlags(self.workspace, self.layout.n_tubes)

    def reset(self, joints: np.ndarray | None = None) -> None:
        """Start a sequence at the robot's joints (2N,) (deg, mm; default: those of the nearest
        training target of its first target)."""
        self.follower.reset(joints)
        self._flags.reset()

    def step(self, x: np.ndarray, check: bool = True, strict: bool = False) -> IKStep:
        """One target (6,) -> IKStep; the answer becomes the robot's joints for the next step."""
        raw = target_pose(x)
        q, projected = self.follower.step(raw)
        ok, reason = self._flags.check(raw, check, strict)
        return self._flags.answer(raw, q, ok, reason, projected, math.nan)

    def export_onnx(self, path: Path, opset: int) -> None:
        raise ModelError("a follow IK (follow_mlp) cannot be exported to ONNX: its state (the robot's "
                         "joints), sub-steps and outer-lag inversion loop outside the network, and its "
                         "network alone answers joint steps, not joints; run it with Kinematics.step "
                         "(Python), or export "
                         "the paper's IK (ctrkin train --task ik --model lstm_mlp) instead")
