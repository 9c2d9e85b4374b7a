"""The snap-aware FK in use: the paper's FK predictor (ctrkin.models.fk_predictor) with a branch
state carried through each sequence, set by the fold gate (ctrkin.families.snap_aware.fold_gate,
the default where the folder has one and its validation rows chose it, ctrkin.families.snap_aware.
gate_choice) or by the network's learned gate.

Batch prediction decodes the state along each sequence (BranchNet.decode, or the fold gate's relay
with m_N followed across the runs of a Dataset); `branch_states=S` replaces both with given states,
`snaps=F` with the states the training labels give for snap flags F (T,) (the TCM-gated ablation of
the report: the snaps of the continued TCM), `gate="learned"` uses the learned gate where the folder
has a fold gate, `gate="fold"` the folder's fold gate where validation chose the learned one.
Streaming keeps the state, m_N and the previous αN; `reset(outer_motion=±1)` says how the outer tube
last turned before a sequence.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch

from ctrkin.data.dataset import Dataset
from ctrkin.errors import ModelError
from ctrkin.families.snap_aware.fold_gate import FoldGate, slide_lags
from ctrkin.families.snap_aware.labels import branch_labels
from ctrkin.families.snap_aware.net import BranchNet
from ctrkin.models.batch import padded_rows, seqnet_trunk
from ctrkin.models.fk_predictor import FKPredictor
from ctrkin.models.fused import Relay
from ctrkin.models.motion import run_continues
from ctrkin.models.onnx_graph import write_onnx
from ctrkin.models.play_lags import PlayState, slide_operators
from ctrkin.models.store import ModelBundle

GATES = ("fold", "learned")


class SnapAwarePredictor(FKPredictor):
    """A snap-aware FK model (module docstring); fold_gate: its fold gate, None: the learned gate;
    gate_aside: a fold gate the model does not use (validation chose the learned gate), kept for
    `predict(..., gate="fold")`."""

    accepts: ClassVar[dict[str, frozenset[str]]] = {"predict": frozenset({"branch_states", "snaps", "gate"}),
                                                     "reset": frozenset({"outer_motion", "continue_run"})}

    def __init__(self, bundle: ModelBundle, fold_gate: FoldGate | None = None, fused: bool = True,
                 gate_aside: FoldGate | None = None) -> None:
        if not isinstance(bundle.net, BranchNet):
            raise ModelError(f"a snap-aware model needs its branch network, not {type(bundle.net).__name__}")
        self._branch_net: BranchNet = bundle.net
        self._fold_gate = fold_gate
        self._gate_aside = gate_aside
        self._slide_play: PlayState | None = None       # the gate's slide memory (_link_play)
        super().__init__(bundle, bundle.net, fused)

    @property
    def fold_gate(self) -> FoldGate | None:
        """The fold gate (None: the learned gate decides the branch)."""
        return self._fold_gate

    @fold_gate.setter
    def fold_gate(self, gate: FoldGate | None) -> None:
        self._fold_gate = gate
        self._rebuild_fused()                       # it holds the gate's tables

    def describe(self) -> str:
        if self._fold_gate is not None:
            return ", fold_gate"
        return ", learned gate (chosen on validation)" if self._gate_aside is not None else ""

    # --- batch -----------------------------------------------------------------------------------
    def _batch_outputs(self, feats: np.ndarray, bounds: list[tuple[int, int]], data: Dataset | np.ndarray,
                       raw: np.ndarray, options: dict[str, Any]) -> np.ndarray:
        gate, states = options.get("gate"), options.get("branch_states")
        fold = None if gate == "learned" else self._fold_gate
        if gate == "fold":
            fold = self._fold_gate or self._gate_aside
        if gate is not None and (gate not in GATES or (gate == "fold" and fold is None)):
            raise ModelError(f"gate={gate!r} needs a branch model (lstm_mlp_branch) and is 'learned' or "
                             "'fold' (where the model folder has fold_gate.json)")
        if options.get("snaps") is not None:
            states = self._snap_states(data, raw, bounds, np.asarray(options["snaps"]))
        net = self._branch_net
        h = seqnet_trunk(net, *padded_rows(feats, bounds, self.ib))   # the state: along each sequence
        if states is None and fold is not None:
            states = self._fold_states(fold, data, raw, bounds)
        if states is None:
            yn, _ = net.decode(h, bounds)
            return yn
        s = np.asarray(states, np.float32).reshape(-1)
        if s.shape != (len(raw),):
            raise ModelError(f"branch_states must have shape ({len(raw)},), got {s.shape}")
        with torch.inference_mode():
            return net.head_out(h, torch.from_numpy(s)).numpy()

    def _fold_states(self, fold: FoldGate, data: Dataset | np.ndarray, raw: np.ndarray,
                     bounds: list[tuple[int, int]]) -> np.ndarray:
        """(T,) branch states from fold gate `fold`, m_N as _recorded_motion."""
        n = self.layout.n_tubes
        motion, runs = self._recorded_motion(data, raw, bounds)
        slide = None
        if fold.slides:                    # the slide memory along the joints as recorded, as m_N
            slide = (slide_lags(data, data.joints(), bounds, n) if isinstance(data, Dataset)
                     else slide_lags(None, raw, bounds, n))
        return fold.states(raw[:, 0] - raw[:, n - 1], raw[:, n:], motion, bounds,
                           run_continues(bounds, runs), slide)

    def _snap_states(self, data: Dataset | np.ndarray, raw: np.ndarray, bounds: list[tuple[int, int]],
                     snaps: np.ndarray) -> np.ndarray:
        """(T,) the training labels' states for snap flags `snaps` (T,) along the joints as given."""
        if snaps.shape != (len(raw),):
            raise ModelError(f"snaps must have shape ({len(raw)},), got {snaps.shape}")
        q = data.joints() if isinstance(data, Dataset) else np.asarray(data, float)
        n = self.layout.n_tubes
        states, _ = branch_labels(q[:, 0] - q[:, n - 1], snaps, bounds)
        return states

    # --- streaming -------------------------------------------------------------------------------
    def _fold_step(self, raw: np.ndarray, outer: float | None = None
                   ) -> tuple[int, int, float, np.ndarray | None]:
        """The fold gate's (state, m_N, αN, its slide memory's operator outputs or None) after joints
        raw (2N,) as the next step, nothing changed. outer: αN as the caller gave it (default raw's)."""
        assert self._fold_gate is not None
        n = self.layout.n_tubes
        a_n = float(raw[n - 1]) if outer is None else outer
        motion = self._motion_after(a_n)
        lags, play_out = (None, None) if self._slide_play is None else self._slide_play.after(raw)
        state = self._fold_gate.step(self._gate_state, float(raw[0] - raw[n - 1]), raw[n:], motion, lags)
        return state, motion, a_n, play_out

    def _link_play(self) -> None:
        """The play states (FKPredictor._link_play) and the fold gate's slide memory, in the fused
        step's buffer where there is one (both paths share it), its values kept."""
        super()._link_play()
        gate, old = self.__dict__.get("_fold_gate"), self.__dict__.get("_slide_play")
        if gate is None or not gate.slides:
            self._slide_play = None
            return
        buf = self._fused.slide_state if self._fused is not None else None
        self._slide_play = PlayState(self.layout.n_tubes, buf, slide_operators())
        if old is not None:
            self._slide_play.buf[:] = old.buf

    def _state_before(self, raw: np.ndarray, outer: float) -> float | None:
        if self._fold_gate is None:
            return None
        self._gate_state, self._outer_motion, self._outer_prev, play_out = self._fold_step(raw, outer)
        if self._slide_play is not None and play_out is not None:
            self._slide_play.advance(play_out)
        return float(self._gate_state)

    def reset(self, outer_motion: int = 0, continue_run: bool = False) -> None:
        super().reset(outer_motion, continue_run)
        if not continue_run and self._slide_play is not None:
            self._slide_play.reset()            # a new run: the slide memory starts at rest

    def _probe_states(self, Q: np.ndarray, outer: np.ndarray) -> np.ndarray | None:
        if self._fold_gate is None:
            return None
        return np.array([self._fold_step(q, float(a))[0] for q, a in zip(Q, outer, strict=True)],
                        dtype=np.float64)

    @property
    def _follows_motion(self) -> bool:
        return self._fold_gate is not None

    def _relay(self) -> Relay | None:
        fg = self._fold_gate
        if fg is None:
            return None
        return Relay(fg.tables, fg.widen_deg, fg.outer_lag_deg, fg.band_deg, fg.slide_weights_deg)

    def export_onnx(self, path: Path, opset: int) -> None:
        self.check_exportable()
        write_onnx(self.bundle, self.net, path, opset, frame=self.frame, stateful=True)

    def export_downgrade(self) -> str | None:
        if self._fold_gate is None:
            return None
        return ("the fold gate (the nominal robot's folds, which predict and step use to switch branches) is "
                "not in the ONNX graph: it would switch branches by the network's learned gate instead, "
                "which finds snaps less reliably")
