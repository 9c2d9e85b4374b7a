"""The paper's IK in use (Fig. 4 with a buffer of tip poses): the network maps the IB latest targets
(and their step changes) to joints, projected onto the robot's limits, each target checked against
the trained workspace (ctrkin.models.workspace) and flagged where the answer jumped
(ctrkin.models.ik). A SeqNet runs by chains in batch and in the numba engine streaming; other
networks run torch on windows."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.models.batch import padded_rows, seqnet_predict
from ctrkin.models.features import postprocess, sequence_features, step_features, window_index
from ctrkin.models.ik import IKResult, IKStep, StepFlags, jumps, target_pose, workspace_check
from ctrkin.models.onnx_graph import write_onnx
from ctrkin.models.predictor_base import BasePredictor
from ctrkin.models.seqnet import SeqNet
from ctrkin.models.store import ModelBundle
from ctrkin.models.workspace import Workspace


class DirectIK(BasePredictor):
    """A direct IK model (module docstring). seqnet: the bundle's network where it is a SeqNet."""

    def __init__(self, bundle: ModelBundle, workspace: Workspace | None, seqnet: SeqNet | None) -> None:
        super().__init__(bundle, workspace, seqnet)
        self._prev: np.ndarray | None = None
        self._flags = StepFlags(workspace, self.layout.n_tubes)

    def predict(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                strict: bool = False, **options: Any) -> IKResult:
        """IKResult of every target of the sequences of `data` (strict: ModelError at the first target
        outside the trained workspace)."""
        raw, bounds = self.raw_inputs(data, sequence_id)
        feats = self._x_norm.transform(self.clip_deltas(sequence_features(self.layout, raw, bounds)))
        if self._seqnet is not None:      # by chains: about half the work of windows at IB = 2
            yn = seqnet_predict(self._seqnet, *padded_rows(feats, bounds, self.ib))
        else:
            yn = self.predict_normalised(feats[window_index(bounds, self.ib)])
        y = postprocess(self.layout, self._y_norm.inverse(yn))
        ok, dist, reasons = workspace_check(self.workspace, raw, strict)
        joints = self.robot.project_joints(y)
        projected = np.any(np.abs(joints - y) > 1e-9, axis=1)
        return IKResult(joints, ok, dist, reasons, projected, np.full(len(y), np.nan),
                        jumps(raw, joints, bounds, self.layout.n_tubes))

    def new_stream(self) -> None:
        super().new_stream()
        self._flags = StepFlags(self.workspace, self.layout.n_tubes)
        self.reset()

    def reset(self) -> None:
        self._prev = None
        self._flags.reset()
        self.reset_stream()

    def step(self, x: np.ndarray, check: bool = True, strict: bool = False) -> IKStep:
        """One target pose (6,) -> IKStep (check=False skips the workspace test, strict=True raises
        ModelError outside it)."""
        raw = target_pose(x)
        feat = step_features(self.layout, raw, self._prev)
        self._prev = raw
        if len(self._dcols):
            feat[self._dcols] = np.minimum(np.maximum(feat[self._dcols], self._dlo), self._dhi)
        y = self._y_norm.inverse(self.network_step(self._x_norm.transform(feat)))
        q = self.robot.project_joints(y[None])[0]
        ok, reason = self._flags.check(raw, check, strict)
        return self._flags.answer(raw, q, ok, reason, bool(np.any(np.abs(q - y) > 1e-9)))

    def export_onnx(self, path: Path, opset: int) -> None:
        write_onnx(self.bundle, self.net, path, opset)
