"""The follow IK (`follow_mlp`, the recommended IK; docs/learned_kinematics.md: Follow IK): the
joint change from the joints the robot is at to the next target, so that its answer stays on the
solution continuous with where the robot is.

    features.py   its inputs (the target in the current outer tube's frame, its step, the joints),
                  the training perturbations and the intermediate targets
    stepper.py    its streaming step (the joints as state, the outer tube's play inverted), which
                  training rolls out and the predictor runs
    recipe.py     training: perturbed joints drawn anew each epoch, rollouts, no checkpoints
    predictor.py  in use: sequences followed from given or nearest training joints; no ONNX
"""

from __future__ import annotations

from ctrkin.families.follow.predictor import FollowPredictor
from ctrkin.families.follow.recipe import FollowRecipe
from ctrkin.models.base import KinematicsNet
from ctrkin.models.predictor import Family, ModelEntry, Opened, Predictor
from ctrkin.models.seqnet import SeqNet


def _build(n_inputs: int, n_outputs: int, ib: int, output_activation: str,
           structure: str = "|D256,D256,D256") -> KinematicsNet:
    return SeqNet(n_inputs, n_outputs, ib, structure, "flatten", output_activation)


def _load(opened: Opened) -> Predictor:
    return FollowPredictor(opened.bundle, opened.workspace)


FAMILY = Family(
    name="follow",
    title="follow IK",
    entries=(ModelEntry(
        "follow_mlp", "follow IK: the joint change from the current joints to the next target, target "
        "in the outer tube's frame, trained from perturbed joints (ctrkin.families.follow); IK only, "
        "MLP Dense 256 x 3", _build, {"structure": "|D256,D256,D256"},
        {"task": "ik", "ib": 1, "output_activation": "linear", "target_frame": "outer", "follow": True,
         "delta": True}),),
    load=_load,
    recipe=FollowRecipe,
    predictors=(FollowPredictor,),
)
