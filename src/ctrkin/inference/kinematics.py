"""Trained kinematics for use: batch prediction over sequences, and streaming one step at a time.

    import ctrkin
    fk = ctrkin.Kinematics.load("models/fk")
    poses = fk.predict(Q)                 # Q: (T, 2N) joints of one sequence (deg, mm) -> (T, 6)
    fk.reset()
    for q in Q:
        pose = fk.step(q)                 # keeps the input buffer itself; equals predict() to 1e-5
    ik = ctrkin.Kinematics.load("models/ik")
    res = ik.predict(targets)             # targets: (T, 6) poses -> IKResult(joints, in_workspace, ...)
    s = fk.step_uncertain(q)              # with a calibrated uncertainty.npz in the folder: the pose, its
                                          # 90 % interval and an out-of-distribution score and flag

`Kinematics` is the face of every model family (docs/design.md: Model families): `load` opens a model
folder through the registry (ctrkin.families.registry) as its family's predictor
(ctrkin.models.predictor.Predictor), and every call goes to that predictor. What a family adds (a
snap-aware FK's `fold_gate` and `probe`, a follow IK's `follower_lag`, a refined IK's `refined`) is
reached on the face as on the predictor; a keyword option a family does not take is refused with the
families that do.

One Kinematics streams one sequence at a time. Batch `predict` never touches the stream (a family
whose batch steps runs it on a twin of its own, Predictor.stream_twin), so it may come between two
`step` calls. A sequence belongs to the thread that takes its first step: a `step` or `reset` from
another thread while that one lives is refused (ModelError), not mixed into its state; each thread
streams its own `kin.copy()`, and `hand_over()` moves a sequence to another thread on purpose (an
executor whose steps run in turn on its workers). The check is one comparison of thread ids per step.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.errors import ModelError
from ctrkin.families.registry import open_folder, predictor, refused_options
from ctrkin.models.features import FeatureLayout
from ctrkin.models.ik import IKResult, IKStep
from ctrkin.models.ood import joints_before
from ctrkin.models.predictor import Opened, Predictor
from ctrkin.models.predictor_base import check_robot, robot_differences
from ctrkin.models.store import ModelBundle, ModelConfig, read_json
from ctrkin.models.uncertainty import UncertainStep, UncertainStream, Uncertainty, with_uncertainty
from ctrkin.models.workspace import Workspace
from ctrkin.robots.robot import Robot
from ctrkin.util.folders import reading_folder

__all__ = ["IKResult", "IKStep", "Kinematics", "robot_differences"]

_thread_id = threading.get_ident
_CLAIM = threading.Lock()       # taking a stream (once per sequence, not per step)


class Kinematics:
    """A trained FK or IK model: its family's predictor (module docstring), the metrics it was trained
    to and the folder it came from.

    model: a predictor, or a ModelBundle to make one from (its family's, without the files of the
    folder it came from: a snap-aware model then predicts with its learned gate); workspace: the IK
    workspace of such a bundle; fused: whether FK steps may take the fused path."""

    def __init__(self, model: Predictor | ModelBundle, workspace: Workspace | None = None,
                 metrics: dict[str, Any] | None = None, path: Path | None = None, fused: bool = True) -> None:
        if isinstance(model, ModelBundle):
            model = predictor(Opened(model, workspace, None, fused))
        self.predictor: Predictor = model
        self.metrics = metrics or {}
        self.path = path
        self._owner: int | None = None                 # id of the thread streaming the sequence
        self._owner_thread: threading.Thread | None = None
        self.uncertainty: Uncertainty | None = None     # calibrated (ctrkin.inference.uncertainty)
        self._unc_stream: UncertainStream | None = None
        self._unc_joints: np.ndarray | None = None       # an IK's: the robot's joints, for its OOD score

    @classmethod
    def load(cls, path: str | Path, fused: bool = True) -> Kinematics:
        """Load a model folder written by `ctrkin train` (or assembled from two, a refined IK).
        fused=False: FK steps take the reference path (engine kernels called one by one from Python)
        even where the fused step applies (ctrkin.models.fused). The folder is read as one version
        while another process may replace it (ctrkin.util.folders)."""
        with reading_folder(path) as src:
            pred = open_folder(src, fused)
            metrics = read_json(src / "metrics.json") if (src / "metrics.json").is_file() else {}
            unc = Uncertainty.load(src)
        kin = cls(pred, metrics=metrics, path=src)
        kin.uncertainty = unc
        return kin

    def copy(self) -> Kinematics:
        """The same model (network, settings, gates shared) with a stream of its own, at a sequence
        start: one per thread that streams."""
        kin = Kinematics(self.predictor.stream_twin(), metrics=self.metrics, path=self.path)
        kin.uncertainty = self.uncertainty
        return kin

    def __getstate__(self) -> dict[str, Any]:
        """A copy or an unpickled Kinematics holds no thread's stream."""
        return {**self.__dict__, "_owner": None, "_owner_thread": None, "_unc_stream": None,
                "_unc_joints": None}

    def hand_over(self) -> None:
        """The calling thread continues the current sequence (its steps run on another thread from
        now on, as an executor's workers take turns); the thread that had it may no longer step."""
        with _CLAIM:
            self._owner_thread = threading.current_thread()
            self._owner = self._owner_thread.ident

    def _claim(self, what: str) -> None:
        """The calling thread takes the stream unless another live thread streams a sequence on it
        (module docstring)."""
        me = threading.current_thread()
        with _CLAIM:
            owner = self._owner_thread
            if owner is not None and owner is not me and owner.is_alive():
                raise ModelError(
                    f"Kinematics.{what}() from thread {me.name!r} while thread {owner.name!r} streams a "
                    "sequence on this model: the two would mix in one stream state (input buffer, "
                    "branch, joints). Give each thread its own copy (kin.copy(), the same model with "
                    "a stream of its own); to move the sequence to this thread on purpose, call "
                    "kin.hand_over() here first, or kin.reset() in the thread that streams it")
            self._owner_thread, self._owner = me, me.ident

    def __getattr__(self, name: str) -> Any:
        """What the model's family adds to the common interface (module docstring)."""
        if name.startswith("__") or "predictor" not in self.__dict__:   # copying, unpickling: no recursion
            raise AttributeError(name)
        try:
            return getattr(self.predictor, name)
        except AttributeError:
            raise AttributeError(f"{type(self).__name__} of model {self.config.model!r} has no attribute "
                                 f"{name!r}") from None

    def __repr__(self) -> str:
        where = "" if self.path is None else f", path={str(self.path)!r}"
        return (f"Kinematics(task={self.task!r}, model={self.config.get('model')!r}, "
                f"robot={self.robot.name!r}, n_tubes={self.layout.n_tubes}, ib={self.ib}"
                f"{self.predictor.describe()}{where})")

    # --- what every model has ----------------------------------------------------------------------
    @property
    def bundle(self) -> ModelBundle:
        return self.predictor.bundle

    @property
    def layout(self) -> FeatureLayout:
        return self.predictor.bundle.layout

    @property
    def robot(self) -> Robot:
        return self.predictor.bundle.robot

    @property
    def config(self) -> ModelConfig:
        return self.predictor.bundle.config

    @property
    def net(self) -> Any:
        return self.predictor.bundle.net

    @property
    def workspace(self) -> Workspace | None:
        return self.predictor.workspace

    @property
    def task(self) -> str:
        return self.layout.task

    @property
    def ib(self) -> int:
        return self.layout.ib

    def check_robot(self, robot: Robot) -> None:
        """Refuse a robot whose tubes or transmission differ from those the model was trained on,
        saying what differs; the same hardware under another name is accepted."""
        check_robot(self.robot, robot)

    # --- batch and streaming -----------------------------------------------------------------------
    def predict(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                strict: bool = False, **options: Any) -> Any:
        """Predict every step of one or more sequences.

        data: a Dataset (its robot must be the model's), or an array (T, 2N) joints (FK) / (T, 6) tip
        poses (IK), one sequence unless `sequence_id` (T,) splits it. Returns (T, 6) poses for FK, an
        IKResult for IK (with strict=True, targets outside the trained workspace raise ModelError).
        Options of a family (a None value is no option):
        branch_states: (T,) {0, 1}, a snap-aware FK only: use these states instead of its gate's;
        snaps: (T,) bool, a snap-aware FK only: the states the training labels give for these snap
        flags (e.g. the continued TCM's); gate: a snap-aware FK only, which gate sets the branch
        state, "fold" (ctrkin.families.snap_aware.fold_gate) or "learned" (its classifier); the default
        is the fold gate where the folder has one and its validation rows chose it
        (ctrkin.families.snap_aware.gate_choice), else the learned gate; the fold gate reads the outer
        tube's last rotation from the joints, across the sequences of one run of a Dataset.
        start_joints: (S, 2N) or (2N,), a follow IK only: the robot's joints at the start of each of
        the S sequences (default: those of the nearest training target).
        """
        if options:
            self._accepts("predict", options)
        return self.predictor.predict(data, sequence_id, strict, **options)

    def reset(self, joints: np.ndarray | None = None, **options: Any) -> None:
        """Start a new sequence: the next step() is its first. joints: a follow IK only, the robot's
        joints (2N,) at the start (default: those of the nearest training target). An FK: outer_motion,
        the direction the outer tube last turned before this sequence (+1, −1; 0: at rest since
        power-up), which shifts where a snap-aware model snaps (and, for a frame with an outer lag,
        ctrkin.models.frame, where the outer tube points); or continue_run=True: the robot moved on
        from the previous sequence without a stop (unrecorded moves in between), so its branch and
        the outer tube's last rotation carry over."""
        options = {"joints": joints, **options}
        self._accepts("reset", options)
        held = self._owner, self._owner_thread
        if self._owner != _thread_id():
            self._claim("reset")                         # held while the state is reset
        try:
            self.predictor.reset(**{k: v for k, v in options.items() if v is not None})
        except BaseException:
            self._owner, self._owner_thread = held
            raise
        self._owner = self._owner_thread = None          # the next step's thread takes the new sequence
        if self._unc_stream is not None:
            self._unc_stream.reset()
        self._unc_joints = None if joints is None else np.array(joints, dtype=np.float64).reshape(-1)

    def step(self, x: np.ndarray, check: bool = True, strict: bool = False) -> Any:
        """One step of the current sequence. x: (2N,) joints (FK) or (6,) target pose (IK).

        FK returns the (6,) tip pose; IK an IKStep(joints, in_workspace, reason) (check=False skips the
        workspace test, strict=True raises ModelError outside it). A sequence belongs to the thread
        that took its first step (module docstring)."""
        if self._owner != _thread_id():
            self._claim("step")
        return self.predictor.step(x, check, strict)

    # --- with the calibrated uncertainty (ctrkin.inference.uncertainty) ------------------------------
    def _calibrated(self) -> Uncertainty:
        if self.uncertainty is None:
            raise ModelError(f"model {self.path or '(in memory)'} has no calibrated uncertainty: calibrate "
                             "it on held-out rows (ctrkin.inference.uncertainty.calibrate) and save it "
                             "into its folder")
        return self.uncertainty

    def predict_uncertain(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                          joints: np.ndarray | None = None, **options: Any) -> Any:
        """`predict` with the calibrated uncertainty: an UncertainPrediction (value: predict's answer;
        half_width: the level's interval, FK (3,) mm, IK (2N,) deg, mm; ood_score, ood (T,)).
        joints: an IK's only, (T, 2N) the robot's joints when each target was asked, for its OOD score;
        default: a Dataset's recorded joints of the row before (a sequence's first row its own), else
        the IK's own answers of the row before (the first row: its start_joints, else its own answer)
        as a loop that executes each answer stands; step_uncertain gives the same scores."""
        unc = self._calibrated()
        raw, bounds = self.predictor.raw_inputs(data, sequence_id)  # type: ignore[attr-defined]
        value = self.predict(data, sequence_id, **options)
        if unc.scores_joints:
            asked = self._asked_joints(data, value, bounds, joints, options.get("start_joints"))
            raw = np.hstack([raw, asked])
        return with_uncertainty(unc, value, raw, bounds)

    def _asked_joints(self, data: Dataset | np.ndarray, value: IKResult, bounds: list[tuple[int, int]],
                      joints: np.ndarray | None, start_joints: np.ndarray | None) -> np.ndarray:
        """(T, 2N) the robot's joints when each target was asked (predict_uncertain)."""
        n2 = 2 * self.robot.n_tubes
        if joints is not None:
            q = np.asarray(joints, dtype=np.float64)
            if q.shape != (len(value.joints), n2):
                raise ModelError(f"joints must have shape ({len(value.joints)}, {n2}): the robot's joints "
                                 f"when each target was asked, got {q.shape}")
            return q
        if isinstance(data, Dataset):
            return joints_before(data.joints(), bounds)
        starts: list[np.ndarray | None] | None = None
        if start_joints is not None:
            arr = np.asarray(start_joints, dtype=np.float64)
            starts = list(np.broadcast_to(arr, (len(bounds), n2)) if arr.ndim == 1 else arr)
        return joints_before(value.joints, bounds, starts)

    def step_uncertain(self, x: np.ndarray, check: bool = True, strict: bool = False,
                       joints: np.ndarray | None = None) -> Any:
        """`step` with the calibrated uncertainty: an UncertainStep (value: step's answer, half_width,
        ood_score, ood); the score equals predict_uncertain's on the same sequence. joints: an IK's
        only, (2N,) the robot's joints now (the encoders), for its OOD score; default: the previous
        step's answer (a loop that executes each), at a sequence's start reset's joints, else this
        step's answer."""
        unc = self._calibrated()
        if self._unc_stream is None:
            self._unc_stream = unc.stream()
        value = self.step(x, check, strict)
        if self.task == "ik":
            asked = joints if joints is not None else self._unc_joints
            score = self._unc_stream.step(x, value.joints if asked is None else asked)
            self._unc_joints = np.array(value.joints, dtype=np.float64)
        else:
            score = self._unc_stream.step(x)
        return UncertainStep(value, self._unc_stream.half_widths, score, score > unc.threshold, unc.level)

    def _accepts(self, method: str, options: dict[str, Any]) -> None:
        why = refused_options(self.predictor, method, options)
        if why is not None:
            raise ModelError(why)

    # --- typed forms of predict and step -----------------------------------------------------------
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
