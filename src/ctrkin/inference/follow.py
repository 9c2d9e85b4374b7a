"""Running a follow IK (ctrkin.models.follow): the robot's joints and the previous target are its
state; each target moves the joints by the network's joint change, through intermediate targets
when it lies farther than the training steps (substeps).

A sequence starts from joints the caller gives (where the robot is) or, without them, from the
joints of the nearest training target; either way the network is applied `settle_iterations` times
at the first target (its training from perturbed joints makes each application a correction).
"""

from __future__ import annotations

import numpy as np

from ctrkin.errors import ModelError
from ctrkin.inference.engine import StreamingEngine
from ctrkin.models.follow import follow_features, substeps
from ctrkin.models.seqnet import SeqNet
from ctrkin.models.store import ModelBundle
from ctrkin.models.workspace import Workspace


class Follower:
    """Step-by-step state of a follow IK model (bundle) with its training workspace."""

    def __init__(self, bundle: ModelBundle, workspace: Workspace | None) -> None:
        if bundle.frame is None or not isinstance(bundle.net, SeqNet):
            raise ModelError("a follow IK needs its outer-tube frame (frame.json) and an MLP network")
        self.n = bundle.layout.n_tubes
        self.robot = bundle.robot
        self.frame = bundle.frame
        self.engine = StreamingEngine(bundle.net)
        self.x_norm, self.y_norm = bundle.x_norm, bundle.y_norm
        settings = bundle.extra.get("follow", {})
        self.max_step_mm = float(settings.get("max_step_mm", 1.0))
        self.settle = int(settings.get("settle_iterations", 5))
        self.iterations = int(settings.get("iterations", 1))    # applications per (sub-)target
        self.workspace = workspace
        self.joints: np.ndarray | None = None        # where the robot is (the last answer or the start)
        self.target: np.ndarray | None = None        # the previous target of this sequence

    def reset(self, joints: np.ndarray | None = None) -> None:
        """Start a sequence, at `joints` (2N,) (deg, mm) if the robot's joints are known."""
        if joints is not None:
            q = np.asarray(joints, dtype=np.float64).reshape(-1)
            if q.shape != (2 * self.n,) or not np.all(np.isfinite(q)):
                raise ModelError(f"start joints must be {2 * self.n} finite numbers (α deg, β mm), got "
                                 f"{np.asarray(joints).tolist()}")
            joints = self.robot.check_joints(q)
        self.joints, self.target = joints, None

    def step(self, target: np.ndarray) -> tuple[np.ndarray, bool]:
        """target (6,) tracker-frame pose -> (joints (2N,) within the robot's limits, whether the
        network's answer had to be projected onto them)."""
        if self.target is None:
            if self.joints is None:
                if self.workspace is None:
                    raise ModelError("a follow IK without its workspace needs start joints (reset(joints))")
                self.joints = self.workspace.nearest_joints(target)
            q, projected = self.joints, False
            for _ in range(self.settle):
                q, projected = self._apply(target, target, q)
        else:
            assert self.joints is not None
            q, projected, previous = self.joints, False, self.target
            for sub in substeps(previous, target, self.max_step_mm):
                for _ in range(self.iterations):
                    q, projected = self._apply(sub, previous, q)
                    previous = sub
        self.joints, self.target = q, np.array(target, dtype=np.float64)
        return q.copy(), projected

    def _apply(self, target: np.ndarray, previous: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, bool]:
        feat = follow_features(self.frame, self.n, target[None], previous[None], q[None])[0]
        dq = self.y_norm.inverse(self.engine.step(self.x_norm.transform(feat)))
        new = q + dq
        valid = self.robot.project_joints(new[None])[0]
        return valid, bool(np.any(np.abs(valid - new) > 1e-9))
