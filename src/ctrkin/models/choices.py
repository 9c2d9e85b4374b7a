"""The named choices a model's setup is made of, as Literal types and their values.

A light module (no torch, numba or scipy): `TrainConfig` and the command line that is generated from
it (`ctrkin train --help`) read these without importing the networks.
"""

from __future__ import annotations

from typing import Literal, get_args

Task = Literal["fk", "ik"]                              # joints -> tip pose, or tip poses -> joints
AngleEncoding = Literal["minmax", "sincos", "phase"]    # FK inputs (ctrkin.models.features)
OutputActivation = Literal["relu", "linear"]            # paper eq. 7: relu (ctrkin.models.base)
TargetFrame = Literal["tracker", "outer"]               # FK targets' frame (ctrkin.models.frame)

ANGLE_ENCODINGS: tuple[str, ...] = get_args(AngleEncoding)
OUTPUT_ACTIVATIONS: tuple[str, ...] = get_args(OutputActivation)
FRAMES: tuple[str, ...] = get_args(TargetFrame)
