"""The refined IK in use: a direct IK's answer refined on a learned FK model, history included
(ctrkin.families.refined.refine). Each step checks the target against the direct IK's workspace,
solves from up to three starts (the previous answer, the direct one, the nearest training target's
joints), advances the FK model's history with the chosen joints and returns α as the whole-turn
representative nearest the previous command. A batch runs step by step, sequence after sequence."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.errors import ModelError
from ctrkin.families.refined.refine import FKResidual, RefineSettings, refine
from ctrkin.models.ik import IKResult, IKStep, StepFlags, target_pose, workspace_check
from ctrkin.models.predictor import Predictor, Probing
from ctrkin.models.predictor_base import BasePredictor


class RefinedPredictor(BasePredictor):
    """direct: the IK predictor whose answers are refined; fk: the FK predictor they are refined on
    (it must probe, ctrkin.models.predictor.Probing); settings: the refinement's."""

    refined = True

    def __init__(self, direct: Predictor, fk: Predictor, settings: RefineSettings | None = None) -> None:
        super().__init__(direct.bundle, direct.workspace)
        self.direct = direct
        layout = self.layout
        if layout.task != "ik":
            raise ModelError("only an IK model can be refined on an FK model")
        if fk.bundle.robot.mechanical_fingerprint() != self.bundle.robot.mechanical_fingerprint():
            raise ModelError("the FK model was trained on another robot than this IK model")
        settings = settings or RefineSettings()
        if "nearest" in settings.starts and (self.workspace is None or self.workspace.joints is None):
            raise ModelError("the 'nearest' start needs the training joints in workspace.npz; retrain the "
                             "IK model or drop 'nearest' from RefineSettings.starts")
        self.residual = FKResidual(fk, settings.tangent_weight_mm)
        self.fk: Probing = self.residual.fk
        self.settings = settings
        self.n = layout.n_tubes
        self._flags = StepFlags(self.workspace, self.n)

    def describe(self) -> str:
        return self.direct.describe() + ", refined"

    def export_downgrade(self) -> str | None:
        return ("the refinement on the FK model (a solve per step with FK probes, "
                "docs/learned_kinematics.md) runs outside the network: the ONNX graph would be the "
                "direct IK network alone")

    def export_onnx(self, path: Path, opset: int) -> None:
        """The direct IK's network (the refinement runs outside it)."""
        self.direct.export_onnx(path, opset)

    def predict(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                strict: bool = False, **options: Any) -> IKResult:
        """Step by step (each step starts from the previous solution and advances the FK model's
        history), one sequence after another, on a twin (stream_twin): this predictor's own stream
        is untouched."""
        raw, bounds = self.raw_inputs(data, sequence_id)
        ok, dist, reasons = workspace_check(self.workspace, raw, strict)
        joints, resid = np.empty((len(raw), 2 * self.n)), np.empty(len(raw))
        projected, jump = np.zeros(len(raw), bool), np.zeros(len(raw), bool)
        runner = self.stream_twin()
        for a, b in bounds:
            runner.reset()
            for t in range(a, b):
                st = runner.step(raw[t], check=False)
                joints[t], resid[t], projected[t], jump[t] = st.joints, st.residual_mm, st.projected, st.jump
        return IKResult(joints, ok, dist, reasons, projected, resid, jump)

    def new_stream(self) -> None:
        """Twins of the direct IK and of the FK model, whose streams the refinement advances."""
        super().new_stream()
        self.direct = self.direct.stream_twin()
        self.residual = copy.copy(self.residual)
        self.residual.fk = self.fk = self.residual.fk.stream_twin()
        self._flags = StepFlags(self.workspace, self.n)

    def reset(self) -> None:
        self.direct.reset()
        self.fk.reset()
        self._flags.reset()

    def step(self, x: np.ndarray, check: bool = True, strict: bool = False) -> IKStep:
        raw = target_pose(x)                 # read as the direct IK reads it (by name where labelled)
        st = self.direct.step(raw, check=check, strict=strict)
        q, residual = self._refine(raw, st.joints)
        return self._flags.answer(raw, q, st.in_workspace, st.reason, st.projected, residual)

    def _refine(self, target: np.ndarray, direct: np.ndarray) -> tuple[np.ndarray, float]:
        settings = self.settings
        previous = self._flags.previous_joints
        starts: list[tuple[str, np.ndarray]] = []
        if "previous" in settings.starts and previous is not None:
            starts.append(("previous", previous))
        if "direct" in settings.starts:
            starts.append(("direct", direct))
        if "nearest" in settings.starts:
            assert self.workspace is not None
            starts.append(("nearest", self.workspace.nearest_joints(target)))
        if not starts:
            starts.append(("direct", direct))
        best = refine(self.residual, starts, target, previous, settings, self.robot.project_joints)
        self.fk.step(best.joints)                 # the FK history moves on with the joints we send
        # α as the robot turns: the whole-turn representative nearest the previous command (the FK
        # saw the one inside its training range; a full turn is the same shape but a real motion)
        n = self.n
        ref = direct if previous is None else previous
        joints = best.joints.copy()
        joints[:n] = ref[:n] + (joints[:n] - ref[:n] + 180.0) % 360.0 - 180.0
        return joints, best.residual_mm

