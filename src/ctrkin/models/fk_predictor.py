"""A learned FK model in use: batch prediction over sequences and streaming one step at a time, with
the input guards, the outer-tube frame and the fused numba step (docs/learned_kinematics.md:
Inference). The paper's sequence models predict through it as it is; the snap-aware FK
(ctrkin.families.snap_aware) adds its branch state through the hooks marked below.

Batch and streaming give the same numbers: both see windows of the IB latest steps of a sequence,
padded at its start by repeating the first step. A SeqNet (LSTM-MLP, LSTM, MLP) runs by chains in
batch (ctrkin.models.batch) and in the numba engine streaming (ctrkin.models.engine); other networks
run torch on windows. An LSTM-MLP with one LSTM layer runs each whole step in one numba call
(ctrkin.models.fused), bit for bit the reference path; `fused=False` keeps to the reference path.

Streaming state: the previous joints as the network saw them, the sequence's whole-turn shift, the
relay state of a model with a tabulated gate (−1 at a start), the direction m_N in which the outer
motor last turned and its previous angle (ctrkin.models.motion), the outer lag λ(β) of the last β,
and for a model with play-lag inputs the play operators' outputs (ctrkin.models.play_lags: in the
fused step's buffer, so both paths share them; in ONNX they are columns of the graph's window).

A model trained with tcm_prior (ctrkin.models.tcm_prior) adds the calibrated TCM's position to the
network's residual: in batch followed along a Dataset's recorded runs or along each sequence of an
array from rest, streaming one TCM step per step from its last equilibrium (carried over by
`reset(continue_run=True)`). Its steps take the reference path (the fused step cannot run the TCM);
probe and ONNX export are refused.
"""

from __future__ import annotations

import math
import threading
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.errors import ModelError
from ctrkin.models.batch import fk_padded_rows, fk_poses, padded_rows, seqnet_predict
from ctrkin.models.engine import StreamingEngine
from ctrkin.models.features import (
    by_name,
    check_raw,
    pair_features,
    postprocess,
    real_array,
    sequence_features,
    step_features,
    window_index,
)
from ctrkin.models.frame import OuterFrame, local_tips_to_world
from ctrkin.models.fused import DECLINED, Clip, FusedFK, Relay, _fk_step
from ctrkin.models.guards import FKGuard
from ctrkin.models.motion import outer_motion, recorded_motion
from ctrkin.models.onnx_graph import write_onnx
from ctrkin.models.outer_lag import lag_one
from ctrkin.models.play_lags import PlayState, path_lags, recorded_lags
from ctrkin.models.predictor_base import BasePredictor
from ctrkin.models.seqnet import SeqNet
from ctrkin.models.store import ModelBundle
from ctrkin.models.tcm_prior import PriorStream, dataset_prior, prior_poses

_F64 = np.dtype(np.float64)      # step's fast path: `is` on the dtype (numpy's builtin dtypes are singletons)
FUSED_ROWS = 16      # predict runs the fused step on sequences up to this long (bench_streaming)
MAX_ROW_THREADS = 8  # predict's fused buffers kept for this many threads (then made anew)


class FKPredictor(BasePredictor):
    """An FK model (module docstring). seqnet: the bundle's network where it is a SeqNet (chains in
    batch, the numba engine streaming), None: torch on windows."""

    accepts: ClassVar[dict[str, frozenset[str]]] = {"predict": frozenset(),
                                                     "reset": frozenset({"outer_motion", "continue_run"})}

    def __init__(self, bundle: ModelBundle, seqnet: SeqNet | None, fused: bool = True) -> None:
        super().__init__(bundle, None, seqnet)
        self._frame = bundle.frame
        self._prev: np.ndarray | None = None
        self._fast = self.layout.angle_encoding in ("minmax", "phase") and not self.layout.equivariant
        # input checks and whole-turn α shifts, the same in predict and step (ctrkin.models.guards)
        self._guard = FKGuard(self.robot, self.layout, bundle.x_norm)
        self._shift: np.ndarray | None = None
        self._gate_state, self._outer_motion, self._outer_prev = -1, 0, math.nan
        self._lag_beta, self._lag = b"", 0.0      # the outer lag λ(β) of the last β (ctrkin.models.frame)
        self._prior = bundle.prior                # the calibrated TCM under the network (tcm_prior)
        self._prior_stream = PriorStream(self._prior) if self._prior is not None else None
        self._use_fused = fused and self._prior is None     # the fused step cannot run the TCM
        self._fused: FusedFK | None = None
        self._play: PlayState | None = None
        self._rebuild_fused()
        # predict by chains with features and poses each in one numba pass (batch.fk_padded_rows,
        # batch.fk_poses): the paper's FK features on a SeqNet whose outputs need no family's hook
        self._chains_fast = (seqnet is not None and self._fast and self.layout.family is None
                             and not self.layout.play and self.layout.n_outputs == 6
                             and type(self)._batch_outputs is FKPredictor._batch_outputs)

    # --- hooks of a model with a branch state (ctrkin.families.snap_aware) -------------------------
    def _batch_outputs(self, feats: np.ndarray, bounds: list[tuple[int, int]], data: Dataset | np.ndarray,
                       raw: np.ndarray, options: dict[str, Any]) -> np.ndarray:
        """(T, O) normalised outputs of normalised features (T, F) of the sequences `bounds`."""
        if self._seqnet is not None:      # by chains: about half the work of windows at IB = 2
            return seqnet_predict(self._seqnet, *padded_rows(feats, bounds, self.ib))
        return self.predict_normalised(feats[window_index(bounds, self.ib)])

    def _state_before(self, raw: np.ndarray, outer: float) -> float | None:
        """The state the engine is to use at this step (None: its own gate, if any), and whatever
        follows it updated; raw: the shifted joints, outer: αN as given."""
        return None

    def _probe_states(self, Q: np.ndarray, outer: np.ndarray) -> np.ndarray | None:
        """The states (K,) the engine is to use for K candidate next joints (None: its own gate)."""
        return None

    @property
    def _follows_motion(self) -> bool:
        """Whether `_state_before` follows m_N (else step does, for a lagged frame)."""
        return False

    def _relay(self) -> Relay | None:
        """The tabulated relay the fused step runs for the branch state (None: none)."""
        return None

    # --- frame and fused step --------------------------------------------------------------------
    @property
    def frame(self) -> OuterFrame | None:
        """The outer-tube frame of a model that learned in it (ctrkin.models.frame)."""
        return self._frame

    @frame.setter
    def frame(self, frame: OuterFrame | None) -> None:
        self._frame = frame
        self._rebuild_fused()                       # it holds the registration and the lag flag

    def _rebuild_fused(self) -> None:
        self.__dict__.pop("_rows_fused", None)      # predict's own, built again when next needed
        clip = Clip(self._dcols, self._dlo, self._dhi)
        self._fused = (FusedFK.build(self.bundle, self._engine, self._guard, clip, self.frame, self._relay())
                       if self._use_fused else None)
        self._fused_lag = self.frame is not None and self.frame.has_lag      # step() reads λ(β)
        self._raw_shape = (self.layout.raw_width,)
        self._link_play()

    def _link_play(self) -> None:
        """The play operators' streaming state (a play layout's), in the fused step's buffer where
        there is one (both paths share it), its values kept."""
        if not self.layout.play:
            return
        old = self._play
        buf = self._fused.play_state if self._fused is not None else None
        self._play = PlayState(self.layout.n_tubes, buf)
        if old is not None:
            self._play.buf[:] = old.buf

    def __setstate__(self, state: dict[str, Any]) -> None:
        """An unpickled predictor's fused step holds buffers of its own (FusedFK.__setstate__): the
        play state is linked to them again."""
        self.__dict__.update(state)
        self._link_play()

    @property
    def fused(self) -> bool:
        """Whether steps run as one numba call where the model allows (ctrkin.models.fused); False:
        the reference path."""
        return self._fused is not None

    def new_stream(self) -> None:
        super().new_stream()
        self._prior_stream = PriorStream(self._prior) if self._prior is not None else None
        self._rebuild_fused()                       # it holds the engine
        self.reset()

    # --- batch -----------------------------------------------------------------------------------
    def guarded(self, raw: np.ndarray, bounds: list[tuple[int, int]]
                ) -> tuple[np.ndarray, list[tuple[int, int]]]:
        """Joints checked and shifted by whole turns per sequence (ctrkin.models.guards)."""
        return self._guard.prepare(raw, bounds), bounds

    def network_inputs(self, data: Dataset | np.ndarray, raw: np.ndarray, bounds: list[tuple[int, int]]
                       ) -> np.ndarray:
        return self._network_joints(data, raw, bounds)[0]

    def _network_joints(self, data: Dataset | np.ndarray, raw: np.ndarray, bounds: list[tuple[int, int]]
                        ) -> tuple[np.ndarray, np.ndarray | None]:
        """The inputs as the network sees them (OuterFrame.network_joints: αN less the outer lag where
        it learned so) and the outer frame's angles (T,) (None without a frame)."""
        if self.frame is None:
            return raw, None
        angles = self._frame_angles(data, raw, bounds)
        return self.frame.network_joints(raw, angles), angles

    def predict(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                strict: bool = False, **options: Any) -> np.ndarray:
        """(T, 6) tip poses of every step of the sequences of `data` (Kinematics.predict). A short
        sequence of joints (an array of up to FUSED_ROWS rows, one sequence) runs the fused streaming
        step row by row (float64, equal to `step`), longer ones the network by chains in torch
        (float32): the two agree to float32 round-off."""
        if (type(data) is np.ndarray and data.ndim == 2 and 0 < data.shape[0] <= FUSED_ROWS
                and data.shape[1] == self.layout.raw_width and data.dtype == np.float64
                and sequence_id is None and not options and self._fused is not None
                and self._fused.stateless):
            y = self._fused_rows(data)
            if y is not None:
                return y
        raw, bounds = self.raw_inputs(data, sequence_id)
        net_raw, angles = self._network_joints(data, raw, bounds)
        starts = self._sequence_starts(bounds, len(raw))
        if starts is not None:
            assert self._seqnet is not None
            x = self._x_norm
            d = (float(self._dlo[0]), float(self._dhi[0])) if len(self._dcols) else (0.0, 0.0)
            padded, windows = fk_padded_rows(net_raw, starts, self.ib, self.layout.n_tubes,
                                             self.layout.angle_encoding == "phase", self.layout.delta,
                                             x.lo, x.span, *d)
            y = fk_poses(seqnet_predict(self._seqnet, padded, windows), self._y_norm.lo, self._y_norm.span)
        else:
            feats = self._x_norm.transform(self.clip_deltas(sequence_features(
                self.layout, net_raw, bounds, self.play_columns(data, raw, bounds))))
            yn = self._batch_outputs(feats, bounds, data, raw, options)
            y = postprocess(self.layout, self._y_norm.inverse(yn))
        if self._prior is not None:
            y[:, :3] += self._prior_positions(data, bounds, angles)
        return y if self.frame is None or angles is None else self.frame.to_world(y, angles)

    def _prior_positions(self, data: Dataset | np.ndarray, bounds: list[tuple[int, int]],
                         angles: np.ndarray | None) -> np.ndarray:
        """(T, 3) mm the TCM prior's positions in the network's output frame: along the joints as
        given (a Dataset: its recorded runs; an array: each sequence from rest), taken to the outer
        frame with the rows' angles where the model learned in it."""
        assert self._prior is not None
        if isinstance(data, Dataset):
            poses = dataset_prior(self._prior, data)
        else:
            poses = prior_poses(self._prior, check_raw(self.layout, data), bounds)
        if self.frame is not None and angles is not None:
            poses = self.frame.to_local(poses, angles)
        return poses[:, :3]

    def _sequence_starts(self, bounds: list[tuple[int, int]], rows: int) -> np.ndarray | None:
        """(S + 1,) the first rows of the sequences `bounds` and the row count, where predict's
        one-pass features apply (`_chains_fast`, sequences that tile the rows); None otherwise."""
        if not self._chains_fast or not bounds or bounds[0][0] != 0 or bounds[-1][1] != rows:
            return None
        starts = np.array([a for a, _ in bounds] + [rows], dtype=np.int64)
        if any(b != starts[k + 1] for k, (_, b) in enumerate(bounds)):
            return None
        return starts

    def play_columns(self, data: Dataset | np.ndarray, raw: np.ndarray, bounds: list[tuple[int, int]]
                     ) -> np.ndarray | None:
        """(T, P) the play lags of a play layout along the joints as recorded (a Dataset: runs followed
        across sequences, glitch rows skipped; an array: each sequence from rest), None without."""
        if not self.layout.play:
            return None
        n = self.layout.n_tubes
        if isinstance(data, Dataset):
            return recorded_lags(data.frame, data.joints(), bounds, n).columns()
        return path_lags(raw, bounds, n).columns()

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

    def alpha_into_range(self, Q: np.ndarray) -> np.ndarray:
        """Joints Q (K, 2N) with each α moved by whole turns (the same configuration) to the
        representative nearest the middle of this model's trained α range."""
        return self._guard.nearest_turns(np.atleast_2d(np.asarray(Q, float)))

    # --- probing (the refined IK's inner loop) ---------------------------------------------------
    @property
    def probes(self) -> bool:
        """Whether probe / probe_tips apply (a SeqNet model: the engine evaluates candidates; not a
        model with a TCM prior)."""
        return self._engine is not None and self._prior is None

    def _probe_outputs(self, Q: np.ndarray, what: str
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """The engine's answers for K candidate next steps Q (K, 2N), nothing advanced: (Q shifted by
        the sequence's whole turns, de-normalised outputs (K, O), branch states (K,), the outer
        frame's angles (K,) or None without a frame). m_N follows αN as given, as in `step`."""
        if self._engine is None:
            raise ModelError(f"{what}() needs an FK model of the LSTM-MLP family")
        if self._prior is not None:
            raise ModelError(f"{what}() is not supported for a model trained with tcm_prior (the TCM "
                             "prior would have to be continued to every candidate); train without "
                             "--tcm-prior for the refined IK, the controller or the planner")
        Q = np.atleast_2d(np.asarray(Q, float))
        outer = Q[:, self.layout.n_tubes - 1].copy()
        lags = None if self._play is None else self._play.peek(Q)       # of the joints as given
        if len(Q):
            Q = Q - (self._shift if self._shift is not None else self._guard.shift(Q[0]))
        angles, net_q = None, Q
        if self.frame is not None:
            angles = self._probe_angles(Q, outer)
            net_q = self.frame.network_joints(Q, angles)
        prev = net_q if self._prev is None else np.broadcast_to(self._prev, Q.shape)
        xn = self._x_norm.transform(self.clip_deltas(pair_features(self.layout, net_q, prev, lags)))
        yn, states = self._engine.probe(xn, self._probe_states(Q, outer))
        return Q, self._y_norm.inverse(yn), states, angles

    def probe_tips(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tip positions (K, 3) and unit tangents (K, 3) in the tracker frame that `step` would give
        for each of K candidate joints Q (K, 2N); nothing is advanced (`probe` without the quaternion
        round trip)."""
        Q, y, _, angles = self._probe_outputs(Q, "probe_tips")
        if self.frame is not None and angles is not None:
            reg = self.frame.registration
            pos, tan = local_tips_to_world(y, angles, reg.rotation, reg.translation)
            return (pos, tan) if self.frame.field is None else (pos + self.frame.field(pos), tan)
        return local_tips_to_world(y, np.zeros(len(Q)), np.eye(3), np.zeros(3))

    def probe(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The poses (K, 6) and branch states (K,) that `step` would return for each of K candidate
        joints Q (K, 2N) as the next step of the current sequence; nothing is advanced."""
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
    def reset(self, outer_motion: int = 0, continue_run: bool = False) -> None:
        """Start a new sequence. outer_motion: the direction the outer tube last turned before it (+1,
        −1; 0: at rest since power-up), which shifts where a snap-aware model snaps and, for a frame
        with an outer lag, where the outer tube points; continue_run=True: the robot moved on from the
        previous sequence without a stop, so the branch and the outer tube's last rotation carry over."""
        if outer_motion not in (-1, 0, 1):
            raise ModelError(f"outer_motion must be -1, 0 or 1, got {outer_motion!r}")
        if not continue_run:
            self._gate_state, self._outer_motion, self._outer_prev = -1, int(outer_motion), math.nan
            if self._play is not None:
                self._play.reset()
            if self._prior_stream is not None:
                self._prior_stream.reset()          # the TCM starts again from a point-wise solve
        self._prev = None
        self._shift = None
        self.reset_stream()

    def step(self, x: np.ndarray, check: bool = True, strict: bool = False) -> np.ndarray:
        """One step: joints x (2N,) (deg, mm) -> the (6,) tip pose."""
        fused = self._fused
        if (fused is not None and type(x) is np.ndarray and x.dtype is _F64 and x.shape == self._raw_shape
                and x.flags.c_contiguous):
            # the fused step (ctrkin.models.fused) on this object's streaming state, inline: a control
            # loop's every step takes this path, and each Python call and attribute costs (issue 26)
            shift, prev = self._shift, self._prev
            if prev is None or shift is None:          # a sequence's first step fixes its whole turns
                shift = self._guard.step(x, None)[1]
            engine = fused.engine                        # self._engine, typed
            consts, weights, state, ints = fused._bufs
            gate_state, motion, outer_prev, branch = _fk_step(            # FusedFK.step, inline
                x, shift, fused._none if prev is None else prev, consts, weights, state, ints,
                prev is not None, engine._fresh, engine.state, self._gate_state, self._outer_motion,
                self._outer_prev, self._lag_at(x) if self._fused_lag else 0.0)
            if gate_state != DECLINED:
                self._shift, self._prev = shift, fused.prev
                self._gate_state, self._outer_motion, self._outer_prev = gate_state, motion, outer_prev
                engine._fresh, engine.state = False, branch
                y = fused._y.copy()
                return y if fused.field is None else fused.field.apply_one(y)
        raw = real_array(by_name(x, self.layout.raw_names, "joints"))
        if raw.shape != (self.layout.raw_width,):
            raise ModelError(f"step() expects shape ({self.layout.raw_width},), got {raw.shape}")
        outer = float(raw[self.layout.n_tubes - 1])     # as given: whole-turn shifts differ by sequence
        lags, play_out = (None, None) if self._play is None else self._play.after(raw)
        given = raw
        raw, self._shift = self._guard.step(raw, self._shift if self._prev is not None else None)
        prior = None if self._prior_stream is None else self._prior_stream.step(given)
        angle = math.nan if self.frame is None else self._step_angle(raw, outer)
        net_raw = raw
        if self.frame is not None and self.frame.lags_inputs:      # the network sees the frame's angle
            net_raw = raw.copy()
            net_raw[self.layout.n_tubes - 1] = angle
        feat = self._features(net_raw, lags)
        self._prev = net_raw
        if self._play is not None and play_out is not None:
            self._play.advance(play_out)
        if len(self._dcols):
            feat[self._dcols] = np.minimum(np.maximum(feat[self._dcols], self._dlo), self._dhi)
        xn = self._x_norm.transform(feat)
        yn = self.network_step(xn, self._state_before(raw, outer) if self._engine is not None else None)
        y = self._y_norm.inverse(yn)
        if prior is not None:           # the TCM's position under the network's residual
            if self.frame is not None:
                prior = self.frame.to_local(prior[None], np.array([angle]))[0]
            y[:3] += prior[:3]
        if self.frame is not None:
            if self.frame.has_lag and not self._follows_motion:    # m_N followed here, else by the gate
                self._outer_motion, self._outer_prev = self._motion_after(outer), outer
            return self.frame.to_world_one(y, angle)
        nq = math.sqrt(y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
        if nq > 1e-12:
            y[3:6] /= nq
        return y

    def _features(self, net_raw: np.ndarray, lags: np.ndarray | None = None) -> np.ndarray:
        """(F,) features of one step (step_features in scalar arithmetic where the encoding allows);
        lags (P,): a play layout's, appended."""
        if not self._fast:
            return step_features(self.layout, net_raw, self._prev, lags)
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
            k += 1
        if lags is not None:
            feat[k:] = lags
        return feat

    def _fused_rows(self, raw: np.ndarray) -> np.ndarray | None:
        """predict's short path: the rows (T, 2N) of one sequence through the fused step on a FusedFK
        of its own (the stream is not touched); None where the fast checks fail (the batch path then
        answers, or raises with its message)."""
        per_thread: dict[int, FusedFK | None] = self.__dict__.setdefault("_rows_fused", {})
        me = threading.get_ident()          # each thread its own buffers (threads may predict at once)
        rows = per_thread.get(me)
        if rows is None:
            assert self._seqnet is not None
            rows = FusedFK.build(self.bundle, StreamingEngine(self._seqnet), self._guard,
                                 Clip(self._dcols, self._dlo, self._dhi), self.frame, self._relay())
            if len(per_thread) >= MAX_ROW_THREADS:
                per_thread.clear()
            per_thread[me] = rows
        assert rows is not None
        return rows.rows(np.ascontiguousarray(raw))

    def _motion_after(self, a_n: float) -> int:
        """m_N after the outer motor reaches a_n (deg) as the next step."""
        if not math.isnan(self._outer_prev) and abs(a_n - self._outer_prev) > 1e-9:
            return 1 if a_n > self._outer_prev else -1
        return self._outer_motion

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

    # --- export ----------------------------------------------------------------------------------
    def export_onnx(self, path: Path, opset: int) -> None:
        self.check_exportable()
        write_onnx(self.bundle, self.net, path, opset, frame=self.frame)

    def check_exportable(self) -> None:
        """ModelError where the ONNX graph cannot hold what the model computes (equivariant inputs: the
        graph turns its poses by the window's αN column). Play lags are columns of the window the graph
        reads, as every feature is (Kinematics.feature_windows); a position field is in the graph."""
        if self._prior is not None:
            raise ModelError("this FK model was trained with tcm_prior: the calibrated TCM it adds to the "
                             "network's residual is not in the ONNX graph; it streams in ctrkin only")
        if self.layout.equivariant:
            raise ModelError("this FK model's equivariant inputs are not in the ONNX graph: it streams in "
                             "ctrkin only")
