"""Trained kinematics for use: batch prediction over sequences, and streaming one step at a time.

    import ctrkin
    fk = ctrkin.Kinematics.load("models/fk")
    poses = fk.predict(Q)                 # Q: (T, 2N) joints of one sequence (deg, mm) -> (T, 6)
    fk.reset()
    for q in Q:
        pose = fk.step(q)                 # keeps the input buffer itself; equals predict() to 1e-5
    ik = ctrkin.Kinematics.load("models/ik")
    res = ik.predict(targets)             # targets: (T, 6) poses -> IKResult(joints, in_workspace, ...)

Batch and streaming give the same numbers: both see windows of the IB latest steps of a sequence,
padded at its start by repeating the first step. Streaming runs LSTM-MLP/LSTM/MLP models in a numba
engine (ctrkin.inference.engine); other architectures fall back to torch on a kept window.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch

from ctrkin.data.dataset import Dataset
from ctrkin.data.schema import sequence_bounds
from ctrkin.errors import ModelError
from ctrkin.inference.batch import padded_rows, seqnet_predict
from ctrkin.inference.engine import StreamingEngine
from ctrkin.inference.workspace import WORKSPACE_FILE, Workspace
from ctrkin.models.features import (
    check_raw,
    postprocess,
    sequence_features,
    step_features,
    window_index,
)
from ctrkin.models.seqnet import SeqNet
from ctrkin.models.store import ModelBundle, read_json
from ctrkin.robots.robot import Robot


@dataclass(eq=False)
class IKResult:
    """joints: (T, 2N) (deg, mm); in_workspace: (T,) whether each target lies in the trained workspace;
    distance: (T,) normalised distance to the nearest training target; reasons: why not, per step."""

    joints: np.ndarray
    in_workspace: np.ndarray
    distance: np.ndarray
    reasons: list[str]

    @property
    def all_in_workspace(self) -> bool:
        return bool(np.all(self.in_workspace))


class IKStep(NamedTuple):
    joints: np.ndarray     # (2N,) deg, mm
    in_workspace: bool
    reason: str


def robot_differences(a: Robot, b: Robot) -> list[str]:
    """Human-readable differences between two robot descriptions ('key: a vs b')."""
    out: list[str] = []

    def walk(x: Any, y: Any, key: str) -> None:
        if isinstance(x, dict) and isinstance(y, dict):
            for k in sorted(set(x) | set(y)):
                walk(x.get(k), y.get(k), f"{key}.{k}" if key else str(k))
        elif isinstance(x, list) and isinstance(y, list) and len(x) == len(y):
            for i, (u, v) in enumerate(zip(x, y, strict=True)):
                walk(u, v, f"{key}[{i}]")
        elif x != y:
            out.append(f"{key}: {x!r} vs {y!r}")

    walk(a.to_dict(), b.to_dict(), "")
    return out


class Kinematics:
    """A trained FK or IK model with its feature layout, normalisation, robot and (IK) workspace."""

    def __init__(self, bundle: ModelBundle, workspace: Workspace | None = None,
                 metrics: dict[str, Any] | None = None, path: Path | None = None) -> None:
        self.bundle = bundle
        self.layout = bundle.layout
        self.robot = bundle.robot
        self.config = bundle.config
        self.net = bundle.net.eval()
        self.workspace = workspace
        self.metrics = metrics or {}
        self.path = path
        self._xlo, self._xspan = bundle.x_norm.lo, bundle.x_norm.span
        self._ylo, self._yspan = bundle.y_norm.lo, bundle.y_norm.span
        self._engine = StreamingEngine(self.net) if isinstance(self.net, SeqNet) else None
        self._window: deque[np.ndarray] = deque(maxlen=self.layout.ib)
        self._prev: np.ndarray | None = None
        self._ws_hint = 0      # nearest training target of the previous IK step (Workspace.check_one)
        self._fast_fk = self.layout.task == "fk" and self.layout.angle_encoding == "minmax"

    # --- loading ---------------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | Path) -> Kinematics:
        """Load a model folder written by `ctrkin train`."""
        src = Path(path)
        bundle = ModelBundle.load(src)
        ws = Workspace.load(src) if (src / WORKSPACE_FILE).is_file() else None
        if bundle.layout.task == "ik" and ws is None:
            raise ModelError(f"{src} is an IK model without {WORKSPACE_FILE}; retrain it with ctrkin train")
        metrics = read_json(src / "metrics.json") if (src / "metrics.json").is_file() else {}
        return cls(bundle, ws, metrics, src)

    @property
    def task(self) -> str:
        return self.layout.task

    @property
    def ib(self) -> int:
        return self.layout.ib

    def check_robot(self, robot: Robot) -> None:
        """Refuse a robot other than the one the model was trained on, saying what differs."""
        if robot.fingerprint() != self.robot.fingerprint():
            diffs = robot_differences(self.robot, robot)
            raise ModelError(
                f"this model was trained on robot {self.robot.name!r} ({self.robot.fingerprint()}), the data "
                f"comes from robot {robot.name!r} ({robot.fingerprint()}); they differ in: "
                f"{'; '.join(diffs[:8]) or 'description'} (model first). Train a model on this robot's data.")

    # --- batch -----------------------------------------------------------------------------------
    def _raw_from(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None
                  ) -> tuple[np.ndarray, list[tuple[int, int]]]:
        if isinstance(data, Dataset):
            self.check_robot(data.robot)
            true = self.config.get("pose_source") == "true" and data.has_truth
            raw = data.joints() if self.task == "fk" else data.poses(true=true)
            return check_raw(self.layout, raw), data.sequence_bounds()
        raw = check_raw(self.layout, data)
        if sequence_id is None:
            return raw, [(0, len(raw))] if len(raw) else []
        sid = np.asarray(sequence_id)
        if sid.shape != (len(raw),):
            raise ModelError(f"sequence_id must have shape ({len(raw)},), got {sid.shape}")
        return raw, sequence_bounds(sid)

    def feature_windows(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None
                        ) -> np.ndarray:
        """(T, IB, F) un-normalised feature windows: the input of the exported ONNX model."""
        raw, bounds = self._raw_from(data, sequence_id)
        feats = sequence_features(self.layout, raw, bounds)
        return feats[window_index(bounds, self.ib)]

    def predict_normalised(self, Xn: np.ndarray, batch: int = 65536) -> np.ndarray:
        """Xn: (B, IB, F) normalised windows -> (B, O) network outputs (normalised); torch, no grad."""
        outs = []
        with torch.inference_mode():
            for a in range(0, len(Xn), batch):
                xb = torch.from_numpy(np.ascontiguousarray(Xn[a:a + batch], np.float32))
                outs.append(self.net(xb).numpy())
        return np.concatenate(outs) if outs else np.zeros((0, self.layout.n_outputs), np.float32)

    def predict(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                strict: bool = False) -> Any:
        """Predict every step of one or more sequences.

        data: a Dataset (its robot must be the model's), or an array (T, 2N) joints (FK) / (T, 6) tip
        poses (IK), one sequence unless `sequence_id` (T,) splits it. Returns (T, 6) poses for FK, an
        IKResult for IK (with strict=True, targets outside the trained workspace raise ModelError).
        """
        raw, bounds = self._raw_from(data, sequence_id)
        feats = (sequence_features(self.layout, raw, bounds) - self._xlo) / self._xspan
        if isinstance(self.net, SeqNet):        # by chains: about half the work of windows at IB = 2
            yn = seqnet_predict(self.net, *padded_rows(feats, bounds, self.ib))
        else:
            yn = self.predict_normalised(feats[window_index(bounds, self.ib)])
        y = postprocess(self.layout, yn * self._yspan + self._ylo)
        if self.task == "fk":
            return y
        assert self.workspace is not None
        ok, dist, reasons = self.workspace.check(raw)
        if strict and not ok.all():
            bad = np.nonzero(~ok)[0]
            raise ModelError(f"{len(bad)} IK target(s) outside the trained workspace, first at step "
                             f"{bad[0]}: {reasons[bad[0]]}")
        return IKResult(y, ok, dist, reasons)

    # --- streaming -------------------------------------------------------------------------------
    def reset(self) -> None:
        """Start a new sequence: the next step() is its first."""
        self._prev = None
        self._window.clear()
        if self._engine is not None:
            self._engine.reset()

    def step(self, x: np.ndarray, check: bool = True, strict: bool = False) -> Any:
        """One step of the current sequence. x: (2N,) joints (FK) or (6,) target pose (IK).

        FK returns the (6,) tip pose; IK an IKStep(joints, in_workspace, reason) (check=False skips the
        workspace test, strict=True raises ModelError outside it)."""
        raw = np.asarray(x, dtype=np.float64)
        if raw.shape != (self.layout.raw_width,):
            raise ModelError(f"step() expects shape ({self.layout.raw_width},), got {raw.shape}")
        if self._fast_fk:
            n = self.layout.n_tubes
            a0 = raw[0] - raw[n - 1]
            feat = np.empty(self.layout.n_inputs)
            feat[: 2 * n] = raw
            feat[2 * n] = a0
            if self.layout.delta:
                feat[2 * n + 1] = 0.0 if self._prev is None else a0 - (self._prev[0] - self._prev[n - 1])
        else:
            feat = step_features(self.layout, raw, self._prev)
        self._prev = raw
        xn = (feat - self._xlo) / self._xspan
        if self._engine is not None:
            yn = self._engine.step(xn)
        else:
            if not self._window:
                self._window.extend([xn] * (self.ib - 1))
            self._window.append(xn)
            with torch.inference_mode():
                yn = self.net(torch.tensor(np.array(self._window)[None], dtype=torch.float32))[0].numpy()
        y = yn * self._yspan + self._ylo
        if self.task == "fk":
            nq = math.sqrt(y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
            if nq > 1e-12:
                y[3:6] /= nq
            return y
        if not check:
            return IKStep(y, True, "")
        assert self.workspace is not None
        ok, reason, self._ws_hint = self.workspace.check_one(raw, self._ws_hint)
        if strict and not ok:
            raise ModelError(f"IK target outside the trained workspace: {reason}")
        return IKStep(y, ok, reason)
