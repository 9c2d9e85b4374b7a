"""What the predictors of every family share: the model folder's contents, the robot check, the raw
inputs of a batch (a Dataset or an array of one or more sequences) and the network on windows."""

from __future__ import annotations

import copy
from collections import deque
from pathlib import Path
from typing import Any, ClassVar, Self

import numpy as np
import torch

from ctrkin.data.dataset import Dataset
from ctrkin.data.schema import restarted_sequence, sequence_bounds
from ctrkin.errors import ModelError
from ctrkin.models.engine import StreamingEngine
from ctrkin.models.features import check_raw, delta_columns, sequence_features, window_index
from ctrkin.models.guards import check_poses
from ctrkin.models.seqnet import SeqNet
from ctrkin.models.store import ModelBundle
from ctrkin.models.workspace import Workspace
from ctrkin.robots.robot import Robot


def robot_differences(a: Robot, b: Robot) -> list[str]:
    """Human-readable differences between two robot descriptions ('key: a vs b'), names aside."""
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

    walk({**a.to_dict(), "name": None}, {**b.to_dict(), "name": None}, "")
    return out


def check_robot(model: Robot, robot: Robot) -> None:
    """Refuse a robot whose tubes or transmission differ from those a model was trained on (model),
    saying what differs; the same hardware under another name is accepted."""
    if robot.mechanical_fingerprint() != model.mechanical_fingerprint():
        diffs = robot_differences(model, robot)
        mine, theirs = model.mechanical_fingerprint(), robot.mechanical_fingerprint()
        raise ModelError(
            f"this model was trained on robot {model.name!r} ({mine}), the data comes from robot "
            f"{robot.name!r} ({theirs}); they differ in: "
            f"{'; '.join(diffs[:8]) or 'description'} (model first). Train a model on this robot's data.")


class BasePredictor:
    """The common part of a family's predictor (ctrkin.models.predictor.Predictor): bundle and IK
    workspace, the network in eval mode, the step-change columns clipped to their training range, and
    the network's streaming step: seqnet, the bundle's network where it is a SeqNet, runs in the numba
    engine (ctrkin.models.engine); other networks run torch on a kept window."""

    accepts: ClassVar[dict[str, frozenset[str]]] = {"predict": frozenset(), "reset": frozenset()}

    def __init__(self, bundle: ModelBundle, workspace: Workspace | None = None,
                 seqnet: SeqNet | None = None) -> None:
        self.bundle = bundle
        self._seqnet = seqnet
        self._engine = StreamingEngine(seqnet) if seqnet is not None else None
        self._window: deque[np.ndarray] = deque(maxlen=bundle.layout.ib)
        self.layout = bundle.layout
        self.robot = bundle.robot
        self.config = bundle.config
        self.net = bundle.net.eval()
        self.workspace = workspace
        self._x_norm, self._y_norm = bundle.x_norm, bundle.y_norm     # the model's pre/post step
        self._dcols = delta_columns(self.layout)
        self._dlo, self._dhi = bundle.x_norm.lo[self._dcols], bundle.x_norm.hi[self._dcols]

    @property
    def task(self) -> str:
        return self.layout.task

    @property
    def ib(self) -> int:
        return self.layout.ib

    @property
    def fused(self) -> bool:
        """Whether steps run as one numba call (ctrkin.models.fused; an FK model where it applies)."""
        return False

    def describe(self) -> str:
        return ""

    def export_onnx(self, path: Path, opset: int) -> None:
        raise ModelError(f"model {self.config.model!r} has no ONNX export")

    def export_downgrade(self) -> str | None:
        return None

    def raw_inputs(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None
                   ) -> tuple[np.ndarray, list[tuple[int, int]]]:
        """The raw inputs (T, 2N | 6) of `data` and its sequences [(start, stop)); a Dataset must come
        from the model's robot. A pandas DataFrame is read by its column names (features.by_name),
        its `sequence_id` column splitting it where the caller gives none; the rows of each sequence
        must be contiguous, as in a Dataset (schema.restarted_sequence)."""
        if isinstance(data, Dataset):
            check_robot(self.robot, data.robot)
            true = self.config.pose_source == "true" and data.has_truth
            raw = data.joints() if self.task == "fk" else data.poses(true=true)
            return self.guarded(check_raw(self.layout, raw), data.sequence_bounds())
        if sequence_id is None and type(data).__module__.partition(".")[0] == "pandas" \
                and "sequence_id" in getattr(data, "columns", ()):
            sequence_id = np.asarray(data["sequence_id"])
        raw = check_raw(self.layout, data)
        if sequence_id is None:
            return self.guarded(raw, [(0, len(raw))] if len(raw) else [])
        sid = np.asarray(sequence_id)
        if sid.shape != (len(raw),):
            raise ModelError(f"sequence_id must have shape ({len(raw)},), got {sid.shape}")
        row = restarted_sequence(sid)
        if row is not None:
            raise ModelError(f"sequence_id {sid[row]} starts again at row {row} after other sequences: the "
                             "rows of each sequence must be contiguous and in time order, as in a Dataset "
                             "(sort them by sequence, then time)")
        return self.guarded(raw, sequence_bounds(sid))

    def guarded(self, raw: np.ndarray, bounds: list[tuple[int, int]]
                ) -> tuple[np.ndarray, list[tuple[int, int]]]:
        """Inputs checked (an IK's targets: finite with unit quaternions, guards.check_poses; an FK's
        joints are checked and shifted by whole turns in its own, ctrkin.models.guards)."""
        if self.task == "ik":
            check_poses(raw)
        return raw, bounds

    def feature_windows(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None
                        ) -> np.ndarray:
        """(T, IB, F) un-normalised feature windows, step changes clipped to their training range as
        in `predict`: the input of the exported ONNX model."""
        raw, bounds = self.raw_inputs(data, sequence_id)
        feats = self.clip_deltas(sequence_features(self.layout, self.network_inputs(data, raw, bounds),
                                                   bounds, self.play_columns(data, raw, bounds)))
        return feats[window_index(bounds, self.ib)]

    def play_columns(self, data: Dataset | np.ndarray, raw: np.ndarray, bounds: list[tuple[int, int]]
                     ) -> np.ndarray | None:
        """(T, P) play lags of a layout with them (an FK's: FKPredictor), None without."""
        return None

    def network_inputs(self, data: Dataset | np.ndarray, raw: np.ndarray, bounds: list[tuple[int, int]]
                       ) -> np.ndarray:
        """The raw inputs (T, 2N | 6) as the network sees them (an FK in the outer tube's frame with
        an outer lag sees the frame's angle as αN)."""
        return raw

    def network_step(self, xn: np.ndarray, state: float | None = None) -> np.ndarray:
        """(O,) normalised outputs of the network at one step of normalised features xn (F,): the
        engine's (state: a state-carrying net's state from outside), or torch on the window of the
        IB latest steps, a sequence's first step repeated to fill it."""
        if self._engine is not None:
            return self._engine.step(xn, state)
        if not self._window:
            self._window.extend([xn] * (self.ib - 1))
        self._window.append(xn)
        window = torch.tensor(np.array(self._window)[None], dtype=torch.float32)
        with torch.inference_mode():
            out: np.ndarray = self.net(window)[0].numpy()
        return out

    def stream_twin(self) -> Self:
        """A predictor of the same model (bundle, network, settings shared) with a stream state of
        its own, at a sequence start: what a batch that runs step by step runs on, so that it never
        disturbs this predictor's stream, and what a second thread streams (Kinematics.copy)."""
        twin = copy.copy(self)
        twin.new_stream()
        return twin

    def new_stream(self) -> None:
        """New containers for every part of the stream state (after a shallow copy, which shares
        them), at a sequence start; a family with more state renews it too."""
        self._engine = StreamingEngine(self._seqnet) if self._seqnet is not None else None
        self._window = deque(maxlen=self.layout.ib)

    def reset_stream(self) -> None:
        """The network's streaming state back to a sequence start."""
        self._window.clear()
        if self._engine is not None:
            self._engine.reset()

    def clip_deltas(self, feats: np.ndarray) -> np.ndarray:
        """Step-change features clipped to their training range (the model knows only the step sizes
        it was trained on; a coarser path keeps its direction)."""
        if len(self._dcols):
            feats[..., self._dcols] = np.clip(feats[..., self._dcols], self._dlo, self._dhi)
        return feats

    def predict_normalised(self, Xn: np.ndarray, batch: int = 65536) -> np.ndarray:
        """Xn: (B, IB, F) normalised windows -> (B, O) network outputs (normalised); torch, no grad."""
        outs = []
        with torch.inference_mode():
            for a in range(0, len(Xn), batch):
                xb = torch.from_numpy(np.ascontiguousarray(Xn[a:a + batch], np.float32))
                outs.append(self.net(xb).numpy())
        return np.concatenate(outs) if outs else np.zeros((0, self.layout.n_outputs), np.float32)
