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
engine (ctrkin.models.engine); other architectures fall back to torch on a kept window. An FK
LSTM-MLP (one LSTM layer, the paper's structure) runs each whole step in one numba call
(ctrkin.inference.fused), bit for bit the reference path; `fused=False` keeps to the reference path.
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
from ctrkin.inference.batch import padded_rows, seqnet_predict, seqnet_trunk
from ctrkin.inference.fused import DECLINED, FusedFK
from ctrkin.inference.guards import FKGuard, check_pose_step, real_array
from ctrkin.inference.refine import FKResidual, RefineSettings, refine
from ctrkin.models.branch import BranchNet
from ctrkin.models.engine import StreamingEngine
from ctrkin.models.features import (
    check_raw,
    delta_columns,
    pair_features,
    postprocess,
    sequence_features,
    step_features,
    window_index,
)
from ctrkin.models.fold_gate import FOLD_GATE_FILE, FoldGate, outer_motion, recorded_motion, run_continues
from ctrkin.models.follower import Follower
from ctrkin.models.frame import OuterFrame, local_tips_to_world
from ctrkin.models.outer_lag import lag_one
from ctrkin.models.seqnet import SeqNet
from ctrkin.models.store import ModelBundle, read_json
from ctrkin.models.workspace import WORKSPACE_FILE, Workspace
from ctrkin.robots.robot import Robot
from ctrkin.util.folders import reading_folder

REFINE_FILE, REFINE_FK = "refine.json", "fk"
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


class Kinematics:
    """A trained FK or IK model with its feature layout, normalisation, robot and (IK) workspace."""

    def __init__(self, bundle: ModelBundle, workspace: Workspace | None = None,
                 metrics: dict[str, Any] | None = None, path: Path | None = None, fused: bool = True) -> None:
        self.bundle = bundle
        self.layout = bundle.layout
        self.robot = bundle.robot
        self.config = bundle.config
        self._frame = bundle.frame
        self.net = bundle.net.eval()
        self.workspace = workspace
        self.metrics = metrics or {}
        self.path = path
        self._x_norm, self._y_norm = bundle.x_norm, bundle.y_norm     # the model's pre/post step
        self._engine = StreamingEngine(self.net) if isinstance(self.net, SeqNet) else None
        self._window: deque[np.ndarray] = deque(maxlen=self.layout.ib)
        self._prev: np.ndarray | None = None
        self._ws_hint = 0      # nearest training target of the previous IK step (Workspace.check_one)
        self._dcols = delta_columns(self.layout)
        self._dlo, self._dhi = bundle.x_norm.lo[self._dcols], bundle.x_norm.hi[self._dcols]
        self.refiner: tuple[Kinematics, RefineSettings, FKResidual] | None = None
        self._ik_prev: tuple[np.ndarray, np.ndarray] | None = None   # previous (target, joints)
        self._fast_fk = self.layout.task == "fk" and self.layout.angle_encoding in ("minmax", "phase")
        # FK input checks and whole-turn α shifts, the same in predict and step (inference.guards)
        self._guard = FKGuard(self.robot, self.layout, bundle.x_norm) if self.layout.task == "fk" else None
        self._shift: np.ndarray | None = None
        # the follow IK (ctrkin.models.follow) carries the robot's joints from step to step
        self._follower = Follower(bundle, workspace) if self.layout.follow else None
        # a snap-aware FK's fold gate (ctrkin.models.fold_gate) and its streaming state: branch
        # state (−1 at a start), the outer tube's last rotation m_N and its previous angle
        self._fold_gate: FoldGate | None = None
        self._gate_state, self._outer_motion, self._outer_prev = -1, 0, math.nan
        self._lag_beta, self._lag = b"", 0.0      # the outer lag λ(β) of the last β (ctrkin.models.frame)
        # the whole FK step in one numba call where the model allows (ctrkin.inference.fused)
        self._use_fused = fused
        self._rebuild_fused()

    @property
    def fold_gate(self) -> FoldGate | None:
        """A snap-aware FK's fold gate (None: its learned gate decides the branch)."""
        return self._fold_gate

    @fold_gate.setter
    def fold_gate(self, gate: FoldGate | None) -> None:
        self._fold_gate = gate
        self._rebuild_fused()                       # it holds the gate's tables

    @property
    def frame(self) -> OuterFrame | None:
        """The outer-tube frame of a model that learned in it (ctrkin.models.frame)."""
        return self._frame

    @frame.setter
    def frame(self, frame: OuterFrame | None) -> None:
        self._frame = frame
        self._rebuild_fused()                       # it holds the registration and the lag flag

    def _rebuild_fused(self) -> None:
        self._fused = FusedFK.build(self) if self._use_fused else None

    @property
    def fused(self) -> bool:
        """Whether FK steps run as one numba call where the model allows (ctrkin.inference.fused);
        False: the reference path."""
        return self._fused is not None

    # --- loading ---------------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | Path, fused: bool = True) -> Kinematics:
        """Load a model folder written by `ctrkin train`. fused=False: FK steps take the reference
        path (engine kernels called one by one from Python) even where the fused step applies.
        The folder is read as one version while another process may replace it (ctrkin.util.folders)."""
        with reading_folder(path) as src:
            return cls._load(src, fused)

    @classmethod
    def _load(cls, src: Path, fused: bool) -> Kinematics:
        bundle = ModelBundle.load(src)
        ws = Workspace.load(src) if (src / WORKSPACE_FILE).is_file() else None
        if bundle.layout.task == "ik" and ws is None:
            raise ModelError(f"{src} is an IK model without {WORKSPACE_FILE}; retrain it with ctrkin train")
        metrics = read_json(src / "metrics.json") if (src / "metrics.json").is_file() else {}
        kin = cls(bundle, ws, metrics, src, fused)
        if (src / FOLD_GATE_FILE).is_file() and isinstance(kin.net, BranchNet):
            kin.fold_gate = FoldGate.load(src)
        if (src / REFINE_FILE).is_file():
            if bundle.layout.task != "ik" or not (src / REFINE_FK).is_dir():
                raise ModelError(f"{src / REFINE_FILE} needs an IK model with its FK model in "
                                 f"{src / REFINE_FK}")
            settings = RefineSettings.from_dict(read_json(src / REFINE_FILE))
            kin.attach_fk(Kinematics.load(src / REFINE_FK), settings)
        return kin

    def attach_fk(self, fk: Kinematics, settings: RefineSettings | None = None) -> None:
        """Refine this IK model's answers on the learned FK `fk` (ctrkin.inference.refine)."""
        if self.task != "ik":
            raise ModelError("only an IK model can be refined on an FK model")
        if fk.robot.mechanical_fingerprint() != self.robot.mechanical_fingerprint():
            raise ModelError("the FK model was trained on another robot than this IK model")
        settings = settings or RefineSettings()
        if "nearest" in settings.starts and (self.workspace is None or self.workspace.joints is None):
            raise ModelError("the 'nearest' start needs the training joints in workspace.npz; retrain the "
                             "IK model or drop 'nearest' from RefineSettings.starts")
        self.refiner = (fk, settings, FKResidual(fk, settings.tangent_weight_mm))

    def __repr__(self) -> str:
        extra = (", fold_gate" if self.fold_gate is not None else "") + (", refined" if self.refined else "")
        where = "" if self.path is None else f", path={str(self.path)!r}"
        return (f"Kinematics(task={self.task!r}, model={self.config.get('model')!r}, "
                f"robot={self.robot.name!r}, n_tubes={self.layout.n_tubes}, ib={self.ib}{extra}{where})")

    @property
    def refined(self) -> bool:
        return self.refiner is not None

    @property
    def task(self) -> str:
        return self.layout.task

    @property
    def ib(self) -> int:
        return self.layout.ib

    def check_robot(self, robot: Robot) -> None:
        """Refuse a robot whose tubes or transmission differ from those the model was trained on,
        saying what differs; the same hardware under another name is accepted."""
        if robot.mechanical_fingerprint() != self.robot.mechanical_fingerprint():
            diffs = robot_differences(self.robot, robot)
            mine, theirs = self.robot.mechanical_fingerprint(), robot.mechanical_fingerprint()
            raise ModelError(
                f"this model was trained on robot {self.robot.name!r} ({mine}), the data comes from robot "
                f"{robot.name!r} ({theirs}); they differ in: "
                f"{'; '.join(diffs[:8]) or 'description'} (model first). Train a model on this robot's data.")

    # --- batch -----------------------------------------------------------------------------------
    def _raw_from(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None
                  ) -> tuple[np.ndarray, list[tuple[int, int]]]:
        if isinstance(data, Dataset):
            self.check_robot(data.robot)
            true = self.config.pose_source == "true" and data.has_truth
            raw = data.joints() if self.task == "fk" else data.poses(true=true)
            return self._guarded(check_raw(self.layout, raw), data.sequence_bounds())
        raw = check_raw(self.layout, data)
        if sequence_id is None:
            return self._guarded(raw, [(0, len(raw))] if len(raw) else [])
        sid = np.asarray(sequence_id)
        if sid.shape != (len(raw),):
            raise ModelError(f"sequence_id must have shape ({len(raw)},), got {sid.shape}")
        return self._guarded(raw, sequence_bounds(sid))

    def _guarded(self, raw: np.ndarray, bounds: list[tuple[int, int]]
                 ) -> tuple[np.ndarray, list[tuple[int, int]]]:
        """FK joints checked and shifted by whole turns per sequence (inference.guards)."""
        return (raw if self._guard is None else self._guard.prepare(raw, bounds)), bounds

    def feature_windows(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None
                        ) -> np.ndarray:
        """(T, IB, F) un-normalised feature windows, step changes clipped to their training range as
        in `predict`: the input of the exported ONNX model."""
        raw, bounds = self._raw_from(data, sequence_id)
        net_raw, _ = self._network_joints(data, raw, bounds)
        feats = self._clip_deltas(sequence_features(self.layout, net_raw, bounds))
        return feats[window_index(bounds, self.ib)]

    def _network_joints(self, data: Dataset | np.ndarray, raw: np.ndarray, bounds: list[tuple[int, int]]
                        ) -> tuple[np.ndarray, np.ndarray | None]:
        """An FK's inputs as its network sees them (OuterFrame.network_joints: αN less the outer lag
        where it learned so) and the outer frame's angles (T,) (None without a frame)."""
        if self.task != "fk" or self.frame is None:
            return raw, None
        angles = self._frame_angles(data, raw, bounds)
        return self.frame.network_joints(raw, angles), angles

    def predict_normalised(self, Xn: np.ndarray, batch: int = 65536) -> np.ndarray:
        """Xn: (B, IB, F) normalised windows -> (B, O) network outputs (normalised); torch, no grad."""
        outs = []
        with torch.inference_mode():
            for a in range(0, len(Xn), batch):
                xb = torch.from_numpy(np.ascontiguousarray(Xn[a:a + batch], np.float32))
                outs.append(self.net(xb).numpy())
        return np.concatenate(outs) if outs else np.zeros((0, self.layout.n_outputs), np.float32)

    def predict(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                strict: bool = False, branch_states: np.ndarray | None = None,
                start_joints: np.ndarray | None = None, gate: str | None = None) -> Any:
        """Predict every step of one or more sequences.

        data: a Dataset (its robot must be the model's), or an array (T, 2N) joints (FK) / (T, 6) tip
        poses (IK), one sequence unless `sequence_id` (T,) splits it. Returns (T, 6) poses for FK, an
        IKResult for IK (with strict=True, targets outside the trained workspace raise ModelError).
        branch_states: (T,) {0, 1}, a branch model only: use these states (e.g. from the continued
        TCM, ctrkin.models.branch_labels) instead of the gate's.
        gate: a branch model only, which gate sets the branch state: "fold" (the default where the
        model has one, ctrkin.models.fold_gate) or "learned" (its classifier). The fold gate reads the
        outer tube's last rotation from the joints, across the sequences of one run of a Dataset.
        start_joints: (S, 2N) or (2N,), a follow IK only: the robot's joints at the start of each of
        the S sequences (default: those of the nearest training target).
        """
        raw, bounds = self._raw_from(data, sequence_id)
        if start_joints is not None and self._follower is None:
            raise ModelError("start_joints applies to a follow IK model (follow_mlp) only")
        if self._follower is not None:
            return self._predict_follow(raw, bounds, strict, start_joints)
        if self.task == "ik" and self.refiner is not None:
            return self._predict_refined(raw, bounds, strict)
        net_raw, angles = self._network_joints(data, raw, bounds)
        feats = self._x_norm.transform(self._clip_deltas(sequence_features(self.layout, net_raw, bounds)))
        if branch_states is not None and not isinstance(self.net, BranchNet):
            raise ModelError("branch_states needs a branch model (lstm_mlp_branch)")
        if gate is not None and (not isinstance(self.net, BranchNet) or gate not in ("fold", "learned")
                                 or (gate == "fold" and self.fold_gate is None)):
            raise ModelError(f"gate={gate!r} needs a branch model (lstm_mlp_branch) and is 'learned' or "
                             "'fold' (where the model folder has fold_gate.json)")
        if isinstance(self.net, BranchNet):     # the branch state is carried through each sequence
            h = seqnet_trunk(self.net, *padded_rows(feats, bounds, self.ib))
            if branch_states is None and self.fold_gate is not None and gate != "learned":
                branch_states = self._fold_states(data, raw, bounds)
            if branch_states is None:
                yn, _ = self.net.decode(h, bounds)
            else:
                states = np.asarray(branch_states, np.float32).reshape(-1)
                if states.shape != (len(raw),):
                    raise ModelError(f"branch_states must have shape ({len(raw)},), got {states.shape}")
                with torch.inference_mode():
                    yn = self.net.head_out(h, torch.from_numpy(states)).numpy()
        elif isinstance(self.net, SeqNet):      # by chains: about half the work of windows at IB = 2
            yn = seqnet_predict(self.net, *padded_rows(feats, bounds, self.ib))
        else:
            yn = self.predict_normalised(feats[window_index(bounds, self.ib)])
        y = postprocess(self.layout, self._y_norm.inverse(yn))
        if self.task == "fk":
            return y if self.frame is None or angles is None else self.frame.to_world(y, angles)
        ok, dist, reasons = self._workspace_check(raw, strict)
        joints = self.robot.project_joints(y)
        projected = np.any(np.abs(joints - y) > 1e-9, axis=1)
        return IKResult(joints, ok, dist, reasons, projected, np.full(len(y), np.nan),
                        _jumps(raw, joints, bounds, self.layout.n_tubes))

    def _recorded_motion(self, data: Dataset | np.ndarray, raw: np.ndarray, bounds: list[tuple[int, int]]
                         ) -> tuple[np.ndarray, np.ndarray | None]:
        """m_N (T,) from the joints as recorded (a Dataset: runs followed across sequences, glitch
        rows skipped) and the runs (T,) (None for an array)."""
        n = self.layout.n_tubes
        if isinstance(data, Dataset):
            return recorded_motion(data.frame, data.joints(), bounds, n)
        return outer_motion(raw, bounds, n), None

    def _frame_angles(self, data: Dataset | np.ndarray, raw: np.ndarray, bounds: list[tuple[int, int]]
                      ) -> np.ndarray:
        """(T,) the angle the outer frame turns with at each row (αN less the outer tube's lag)."""
        assert self.frame is not None
        motion = self._recorded_motion(data, raw, bounds)[0] if self.frame.has_lag else 0
        return self.frame.outer_angle(self.robot, raw, motion)

    def forward(self, joints: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                gate: str | None = None) -> np.ndarray:
        """An FK model's `predict`, typed: joints (T, 2N) (deg, mm) or a Dataset -> tip poses (T, 6)."""
        self._require("fk", "forward")
        return np.asarray(self.predict(joints, sequence_id, gate=gate))

    def inverse(self, poses: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                strict: bool = False, start_joints: np.ndarray | None = None) -> IKResult:
        """An IK model's `predict`, typed: target tip poses (T, 6) (mm, unit quaternion) or a Dataset
        -> IKResult (joints (T, 2N) deg, mm, and the per-target flags)."""
        self._require("ik", "inverse")
        res = self.predict(poses, sequence_id, strict=strict, start_joints=start_joints)
        assert isinstance(res, IKResult)
        return res

    def step_pose(self, joints: np.ndarray) -> np.ndarray:
        """An FK model's `step`, typed: joints (2N,) (deg, mm) -> tip pose (6,)."""
        self._require("fk", "step_pose")
        return np.asarray(self.step(joints))

    def step_joints(self, pose: np.ndarray, check: bool = True, strict: bool = False) -> IKStep:
        """An IK model's `step`, typed: target pose (6,) -> IKStep."""
        self._require("ik", "step_joints")
        res = self.step(pose, check=check, strict=strict)
        assert isinstance(res, IKStep)
        return res

    def _require(self, task: str, what: str) -> None:
        if self.task != task:
            raise ModelError(f"{what}() needs an {task.upper()} model; this is an {self.task.upper()} model "
                             f"({self.path or 'in memory'})")

    def _fold_states(self, data: Dataset | np.ndarray, raw: np.ndarray, bounds: list[tuple[int, int]]
                     ) -> np.ndarray:
        """(T,) branch states from the fold gate, m_N as _recorded_motion."""
        assert self.fold_gate is not None
        n = self.layout.n_tubes
        motion, runs = self._recorded_motion(data, raw, bounds)
        return self.fold_gate.states(raw[:, 0] - raw[:, n - 1], raw[:, n:], motion, bounds,
                                     run_continues(bounds, runs))

    def _workspace_check(self, raw: np.ndarray, strict: bool) -> tuple[np.ndarray, np.ndarray, list[str]]:
        assert self.workspace is not None
        ok, dist, reasons = self.workspace.check(raw)
        if strict and not ok.all():
            bad = np.nonzero(~ok)[0]
            raise ModelError(f"{len(bad)} IK target(s) outside the trained workspace, first at step "
                             f"{bad[0]}: {reasons[bad[0]]}")
        return ok, dist, reasons

    def _predict_refined(self, raw: np.ndarray, bounds: list[tuple[int, int]], strict: bool) -> IKResult:
        """Refined IK runs step by step (each step starts from the previous solution and advances the
        FK model's history), one sequence after another."""
        ok, dist, reasons = self._workspace_check(raw, strict)
        n2 = 2 * self.layout.n_tubes
        joints, resid = np.empty((len(raw), n2)), np.empty(len(raw))
        projected, jump = np.zeros(len(raw), bool), np.zeros(len(raw), bool)
        for a, b in bounds:
            self.reset()
            for t in range(a, b):
                st = self.step(raw[t], check=False)
                joints[t], resid[t], projected[t], jump[t] = st.joints, st.residual_mm, st.projected, st.jump
        self.reset()
        return IKResult(joints, ok, dist, reasons, projected, resid, jump)

    def _predict_follow(self, raw: np.ndarray, bounds: list[tuple[int, int]], strict: bool,
                        start_joints: np.ndarray | None) -> IKResult:
        """A follow IK runs each sequence step by step from its start joints."""
        assert self._follower is not None
        ok, dist, reasons = self._workspace_check(raw, strict)
        n2 = 2 * self.layout.n_tubes
        starts: list[np.ndarray | None] = [None] * len(bounds)
        if start_joints is not None:
            arr = np.asarray(start_joints, dtype=np.float64)
            arr = np.broadcast_to(arr, (len(bounds), n2)) if arr.shape == (n2,) else arr
            if arr.shape != (len(bounds), n2):
                raise ModelError(f"start_joints must have shape ({n2},) or ({len(bounds)}, {n2}) (one row "
                                 f"per sequence), got {np.asarray(start_joints).shape}")
            starts = list(arr)
        joints, projected = self._follower.run(raw, bounds, starts)
        return IKResult(joints, ok, dist, reasons, projected, np.full(len(raw), np.nan),
                        _jumps(raw, joints, bounds, self.layout.n_tubes))

    def _clip_deltas(self, feats: np.ndarray) -> np.ndarray:
        """Step-change features clipped to their training range (the model knows only the step sizes
        it was trained on; a coarser path keeps its direction)."""
        if len(self._dcols):
            feats[..., self._dcols] = np.clip(feats[..., self._dcols], self._dlo, self._dhi)
        return feats

    def alpha_into_range(self, Q: np.ndarray) -> np.ndarray:
        """FK only: joints Q (K, 2N) with each α moved by whole turns (the same configuration) to the
        representative nearest the middle of this model's trained α range."""
        if self._guard is None:
            raise ModelError("alpha_into_range() is for FK models")
        return self._guard.nearest_turns(np.atleast_2d(np.asarray(Q, float)))

    def _probe_outputs(self, Q: np.ndarray, what: str
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """The engine's answers for K candidate next steps Q (K, 2N), nothing advanced: (Q shifted by
        the sequence's whole turns, de-normalised outputs (K, O), branch states (K,), the outer
        frame's angles (K,) or None without a frame). m_N follows αN as given, as in `step`."""
        if self.task != "fk" or self._engine is None:
            raise ModelError(f"{what}() needs an FK model of the LSTM-MLP family")
        Q = np.atleast_2d(np.asarray(Q, float))
        outer = Q[:, self.layout.n_tubes - 1].copy()
        if self._guard is not None and len(Q):
            Q = Q - (self._shift if self._shift is not None else self._guard.shift(Q[0]))
        angles, net_q = None, Q
        if self.frame is not None:
            angles = self._probe_angles(Q, outer)
            net_q = self.frame.network_joints(Q, angles)
        prev = net_q if self._prev is None else np.broadcast_to(self._prev, Q.shape)
        xn = self._x_norm.transform(self._clip_deltas(pair_features(self.layout, net_q, prev)))
        given = None
        if self.fold_gate is not None:
            given = np.array([self._fold_step(q, float(a))[0] for q, a in zip(Q, outer, strict=True)],
                             dtype=np.float64)
        yn, states = self._engine.probe(xn, given)
        return Q, self._y_norm.inverse(yn), states, angles

    def probe_tips(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """FK only, the refinement's inner loop: tip positions (K, 3) and unit tangents (K, 3) in the
        tracker frame that `step` would give for each of K candidate joints Q (K, 2N); nothing is
        advanced (`probe` without the quaternion round trip)."""
        Q, y, _, angles = self._probe_outputs(Q, "probe_tips")
        if self.frame is not None and angles is not None:
            reg = self.frame.registration
            return local_tips_to_world(y, angles, reg.rotation, reg.translation)
        return local_tips_to_world(y, np.zeros(len(Q)), np.eye(3), np.zeros(3))

    def probe(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """FK only: the poses (K, 6) and branch states (K,) that `step` would return for each of K
        candidate joints Q (K, 2N) as the next step of the current sequence; nothing is advanced."""
        Q, y, states, angles = self._probe_outputs(Q, "probe")
        y = postprocess(self.layout, y)
        if self.frame is not None and angles is not None:
            y = self.frame.to_world(y, angles)
        return y, states

    def _probe_angles(self, Q: np.ndarray, outer: np.ndarray) -> np.ndarray:
        """(K,) outer-frame angles of K candidate next joints Q (K, 2N), shifted by the sequence's
        whole turns; outer (K,): their αN as given, whose m_N a step to each would leave."""
        assert self.frame is not None
        if not self.frame.has_lag:
            return Q[:, self.layout.n_tubes - 1]
        motion = np.array([self._motion_after(float(a)) for a in outer], float)
        return self.frame.outer_angle(self.robot, Q, motion)

    # --- streaming -------------------------------------------------------------------------------
    def reset(self, joints: np.ndarray | None = None, outer_motion: int = 0,
              continue_run: bool = False) -> None:
        """Start a new sequence: the next step() is its first. joints: a follow IK only, the robot's
        joints (2N,) at the start (default: those of the nearest training target). An FK with a fold
        gate (ctrkin.models.fold_gate): outer_motion, the direction the outer tube last turned before
        this sequence (+1, −1; 0: at rest since power-up), which shifts where it snaps (and, for a frame
        with an outer lag, ctrkin.models.frame, where the outer tube points); or
        continue_run=True: the robot moved on from the previous sequence without a stop (unrecorded
        moves in between), so its branch and the outer tube's last rotation carry over."""
        if joints is not None and self._follower is None:
            raise ModelError("reset(joints) applies to a follow IK model (follow_mlp) only")
        if outer_motion not in (-1, 0, 1):
            raise ModelError(f"outer_motion must be -1, 0 or 1, got {outer_motion!r}")
        if not continue_run:
            self._gate_state, self._outer_motion, self._outer_prev = -1, int(outer_motion), math.nan
        if self._follower is not None:
            self._follower.reset(joints)
        self._prev = None
        self._ik_prev = None
        self._shift = None
        self._window.clear()
        if self._engine is not None:
            self._engine.reset()
        if self.refiner is not None:
            self.refiner[0].reset()

    def step(self, x: np.ndarray, check: bool = True, strict: bool = False) -> Any:
        """One step of the current sequence. x: (2N,) joints (FK) or (6,) target pose (IK).

        FK returns the (6,) tip pose; IK an IKStep(joints, in_workspace, reason) (check=False skips the
        workspace test, strict=True raises ModelError outside it)."""
        if (self._fused is not None and type(x) is np.ndarray and x.dtype == np.float64
                and x.shape == (self.layout.raw_width,) and x.flags.c_contiguous):
            y = self._fused_step(x)
            if y is not None:
                return y
        raw = real_array(x)
        if raw.shape != (self.layout.raw_width,):
            raise ModelError(f"step() expects shape ({self.layout.raw_width},), got {raw.shape}")
        outer = float(raw[self.layout.n_tubes - 1])     # as given: whole-turn shifts differ by sequence
        if self._guard is not None:
            raw, self._shift = self._guard.step(raw, self._shift if self._prev is not None else None)
        else:
            check_pose_step(raw)
        if self._follower is not None:
            q, projected = self._follower.step(raw)
            return self._ik_step(raw, q, projected, check, strict)
        angle = math.nan if self.frame is None else self._step_angle(raw, outer)
        net_raw = raw
        if self.frame is not None and self.frame.lags_inputs:      # the network sees the frame's angle
            net_raw = raw.copy()
            net_raw[self.layout.n_tubes - 1] = angle
        if self._fast_fk:
            n = self.layout.n_tubes
            a0 = net_raw[0] - net_raw[n - 1]
            feat = np.empty(self.layout.n_inputs)
            feat[: 2 * n] = net_raw
            feat[2 * n] = a0
            k = 2 * n + 1
            if self.layout.angle_encoding == "phase":
                r = math.radians(a0)
                feat[k], feat[k + 1] = math.sin(r), math.cos(r)
                k += 2
            if self.layout.delta:
                feat[k] = 0.0 if self._prev is None else a0 - (self._prev[0] - self._prev[n - 1])
        else:
            feat = step_features(self.layout, net_raw, self._prev)
        self._prev = net_raw
        if len(self._dcols):
            feat[self._dcols] = np.minimum(np.maximum(feat[self._dcols], self._dlo), self._dhi)
        xn = self._x_norm.transform(feat)
        if self._engine is not None:
            state = None
            if self.fold_gate is not None:
                self._gate_state, self._outer_motion, self._outer_prev = self._fold_step(raw, outer)
                state = float(self._gate_state)
            yn = self._engine.step(xn, state)
        else:
            if not self._window:
                self._window.extend([xn] * (self.ib - 1))
            self._window.append(xn)
            with torch.inference_mode():
                yn = self.net(torch.tensor(np.array(self._window)[None], dtype=torch.float32))[0].numpy()
        y = self._y_norm.inverse(yn)
        if self.task == "fk":
            if self.frame is not None:
                if self.frame.has_lag and self.fold_gate is None:    # m_N followed here, else by the gate
                    self._outer_motion, self._outer_prev = self._motion_after(outer), outer
                return self.frame.to_world_one(y, angle)
            nq = math.sqrt(y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
            if nq > 1e-12:
                y[3:6] /= nq
            return y
        q = self.robot.project_joints(y[None])[0]
        return self._ik_step(raw, q, bool(np.any(np.abs(q - y) > 1e-9)), check, strict)

    @property
    def follower_lag(self) -> tuple[float, float]:
        """A follow IK's outer lag (a deg, b deg/mm) of λ = a + b·overlap (ctrkin.models.outer_lag);
        (0, 0) for a follow IK trained before it, ModelError for any other model."""
        if self._follower is None:
            raise ModelError("follower_lag applies to a follow IK model (follow_mlp) only")
        return self._follower.lag

    def _fused_step(self, raw: np.ndarray) -> np.ndarray | None:
        """The FK step in one numba call (ctrkin.inference.fused) on this object's streaming state;
        None where it declines (the reference path then raises with its message)."""
        assert self._fused is not None and self._guard is not None and self._engine is not None
        shift = self._shift
        if self._prev is None or shift is None:       # a sequence's first step fixes its whole turns
            shift = self._guard.step(raw, None)[1]
        lag = self._lag_at(raw) if self.frame is not None and self.frame.has_lag else 0.0
        y, st = self._fused.step(raw, shift, self._prev, self._gate_state, self._outer_motion,
                                 self._outer_prev, lag)
        if st.gate_state == DECLINED:
            return None
        self._shift, self._prev = shift, self._fused.prev
        self._gate_state, self._outer_motion, self._outer_prev = st.gate_state, st.outer_motion, st.outer_prev
        self._engine._fresh, self._engine.state = False, st.branch
        return y

    def _motion_after(self, a_n: float) -> int:
        """m_N after the outer motor reaches a_n (deg) as the next step."""
        if not math.isnan(self._outer_prev) and abs(a_n - self._outer_prev) > 1e-9:
            return 1 if a_n > self._outer_prev else -1
        return self._outer_motion

    def _fold_step(self, raw: np.ndarray, outer: float | None = None) -> tuple[int, int, float]:
        """The fold gate's (state, m_N, αN) after joints raw (2N,) as the next step, nothing changed.
        outer: αN as the caller gave it (default raw's)."""
        assert self.fold_gate is not None
        n = self.layout.n_tubes
        a_n = float(raw[n - 1]) if outer is None else outer
        motion = self._motion_after(a_n)
        state = self.fold_gate.step(self._gate_state, float(raw[0] - raw[n - 1]), raw[n:], motion)
        return state, motion, a_n

    def _step_angle(self, raw: np.ndarray, outer: float) -> float:
        """The outer frame's angle for joints raw (2N,) as the next step: αN less the lag λ(β)·m_N
        (λ cached per β), m_N as it will be once the motor reaches αN as given (outer); nothing
        changed."""
        assert self.frame is not None
        a_n = float(raw[self.layout.n_tubes - 1])
        if not self.frame.has_lag:
            return a_n
        return a_n - self._lag_at(raw) * self._motion_after(outer)

    def _lag_at(self, raw: np.ndarray) -> float:
        """λ(β) (deg) of the outer frame's lag at joints raw (2N,), cached for the last β."""
        assert self.frame is not None
        beta = raw[self.layout.n_tubes:].tobytes()
        if self._lag_beta != beta:
            self._lag_beta = beta
            self._lag = lag_one(self.robot, raw, self.frame.lag)
        return self._lag

    def _ik_step(self, raw: np.ndarray, q: np.ndarray, projected: bool, check: bool, strict: bool
                 ) -> IKStep:
        """The IK step's flags (workspace, jump), and the refinement of a refined model."""
        ok, reason = True, ""
        if check:
            assert self.workspace is not None
            ok, reason, self._ws_hint = self.workspace.check_one(raw, self._ws_hint)
            if strict and not ok:
                raise ModelError(f"IK target outside the trained workspace: {reason}")
        residual = math.nan
        if self.refiner is not None:
            q, residual = self._refine(raw, q)
        jump = False
        if self._ik_prev is not None:
            n = self.layout.n_tubes
            moved = float(np.linalg.norm(raw[:3] - self._ik_prev[0][:3]))
            turned = np.abs((q[:n] - self._ik_prev[1][:n] + 180.0) % 360.0 - 180.0)
            jump = bool(moved < JUMP_TARGET_MM and turned.max() > JUMP_DEG)
        self._ik_prev = (raw, q)
        return IKStep(q, ok, reason, projected, residual, jump)

    def _refine(self, target: np.ndarray, direct: np.ndarray) -> tuple[np.ndarray, float]:
        assert self.refiner is not None
        fk, settings, residual = self.refiner
        previous = None if self._ik_prev is None else self._ik_prev[1]
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
        best = refine(residual, starts, target, previous, settings, self.robot.project_joints)
        fk.step(best.joints)                 # the FK history moves on with the joints we send
        # α as the robot turns: the whole-turn representative nearest the previous command (the FK
        # saw the one inside its training range; a full turn is the same shape but a real motion)
        n = self.layout.n_tubes
        ref = direct if previous is None else previous
        joints = best.joints.copy()
        joints[:n] = ref[:n] + (joints[:n] - ref[:n] + 180.0) % 360.0 - 180.0
        return joints, best.residual_mm


def _jumps(targets: np.ndarray, joints: np.ndarray, bounds: list[tuple[int, int]], n: int) -> np.ndarray:
    """(T,) the IKStep.jump flag for a batch: α changed > JUMP_DEG while the target moved
    < JUMP_TARGET_MM since the previous step of the same sequence."""
    out = np.zeros(len(targets), dtype=bool)
    for a, b in bounds:
        if b - a < 2:
            continue
        moved = np.linalg.norm(np.diff(targets[a:b, :3], axis=0), axis=1)
        turned = np.abs((np.diff(joints[a:b, :n], axis=0) + 180.0) % 360.0 - 180.0).max(axis=1)
        out[a + 1:b] = (moved < JUMP_TARGET_MM) & (turned > JUMP_DEG)
    return out
