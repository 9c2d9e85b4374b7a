"""The snap-aware FK (`lstm_mlp_branch`, the recommended FK; docs/learned_kinematics.md: Snap-aware
FK): the paper's LSTM trunk, one head per equilibrium branch and a branch state that a fold gate
(the nominal robot's folds) or a learned gate sets, so that a snap is a switch, not a smoothed ramp.

    net.py        BranchNet: trunk, two heads, the gate; BranchNet.decode carries the state in batch
    labels.py     which branch each training row is on, from the dataset's snap flags
    fold_gate.py  the fold gate: tabulated folds of the nominal robot, offsets fitted to the snaps
    gate_choice.py  which gate the model uses: the fold gate unless its validation rows clearly prefer
                  the learned one
    play.py       a candidate delay identified from the history (play operators), measured beside the
                  fold gate by benchmarks/bench_fold_gate.py; not the gate's form
    recipe.py     training: the paper's windows and MAE, the gate's cross-entropy, the fold gate
    predictor.py  in use: the paper's FK predictor with the branch state; ONNX with a state input
"""

from __future__ import annotations

from ctrkin.families.snap_aware.fold_gate import FOLD_GATE_FILE, FoldGate
from ctrkin.families.snap_aware.net import BranchNet
from ctrkin.families.snap_aware.predictor import SnapAwarePredictor
from ctrkin.families.snap_aware.recipe import BranchRecipe
from ctrkin.models.base import KinematicsNet
from ctrkin.models.predictor import Family, ModelEntry, Opened, Predictor


def _build(n_inputs: int, n_outputs: int, ib: int, output_activation: str, structure: str = "paper",
           gate_units: int = 32, heads: str = "separate") -> KinematicsNet:
    return BranchNet(n_inputs, n_outputs, ib, structure, output_activation, int(gate_units), str(heads))


def _load(opened: Opened) -> Predictor:
    folder = opened.folder
    gate = FoldGate.load(folder) if folder is not None and (folder / FOLD_GATE_FILE).is_file() else None
    if gate is not None and not gate.in_use:        # validation chose the learned gate (gate_choice)
        return SnapAwarePredictor(opened.bundle, None, opened.fused, gate_aside=gate)
    return SnapAwarePredictor(opened.bundle, gate, opened.fused)


FAMILY = Family(
    name="snap_aware",
    title="snap-aware FK (branch model)",
    entries=(ModelEntry(
        "lstm_mlp_branch", "snap-aware LSTM-MLP: a learned branch state (hysteron) selects one of two "
        "heads, so snaps are sharp (ctrkin.families.snap_aware); FK only, sin/cos α0 inputs, poses "
        "learned in the outer tube's frame (ctrkin.models.frame) unless --target-frame tracker",
        _build, {"structure": "paper", "gate_units": 32, "heads": "separate"},
        {"angle_encoding": "phase", "output_activation": "linear", "task": "fk"},
        {"target_frame": "outer"}),),
    load=_load,
    recipe=BranchRecipe,
    predictors=(SnapAwarePredictor,),
    files=(FOLD_GATE_FILE,),
)
