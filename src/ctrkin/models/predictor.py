"""What every model family gives the rest of ctrkin: a predictor in use, and a registry entry
(docs/design.md: Model families).

A family lives in one folder, ctrkin/families/<name>/, and is one line of the registry
(ctrkin.families.registry). The registry reads its `Family`: which model names it trains (their
networks and fixed settings, `ModelEntry`), how to open a model folder of one of them as a
`Predictor`, and its training `Recipe` (ctrkin.models.recipe). `ctrkin.Kinematics` is the face users
see: it opens a folder through the registry and hands every call to the family's predictor, so no
code outside a family's folder asks which kind of model it holds.

A predictor is LeRobot's policy split (batch `forward`, streaming `reset` / `select_action`) for
kinematics:

    predict(data, sequence_id, strict, **options)  every step of one or more sequences, with history
    reset(**options)                                the next step starts a sequence
    step(x, check, strict)                          one step; the predictor keeps its history itself
    export_onnx(path, opset)                        the network as an ONNX graph (or a ModelError)

with `accepts[method]`, the keyword options each of predict and reset takes beyond these (a snap-aware
FK's `gate`, a follow IK's start `joints`); the face refuses any other, naming the families that take
it. What a family saves beside the common model folder (ctrkin.models.store: network, layout,
normalisation, robot, configuration, IK workspace) it writes in its recipe's `finish` and reads in its
`load`; `Family.files` names those files.

Room for what comes next, without a change here: a predictor may carry any state between steps (its
own reset options say how a sequence starts); it may offer more than the protocol (a capability is a
small protocol of its own, such as `Probing`, the tip positions and tangents of candidate next joints
that the refined IK differentiates, or a Jacobian); predict and step may return richer results (an
uncertainty beside the pose) as long as the task's arrays stay where callers read them; and a family
may wrap the predictor of another model folder (`Family.wrap`, as the refined IK wraps a direct IK
and holds an FK model).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from ctrkin.data.dataset import Dataset
    from ctrkin.models.base import KinematicsNet
    from ctrkin.models.recipe import Recipe, TrainSettings
    from ctrkin.models.store import ModelBundle
    from ctrkin.models.workspace import Workspace


class Predictor(Protocol):
    """A trained model in use (module docstring). bundle: the common model folder's contents;
    workspace: the IK workspace (None for FK)."""

    accepts: ClassVar[dict[str, frozenset[str]]]
    bundle: ModelBundle
    workspace: Workspace | None

    def predict(self, data: Dataset | np.ndarray, sequence_id: np.ndarray | None = None,
                strict: bool = False, **options: Any) -> Any:
        """Every step of the sequences of `data` (a Dataset of the model's robot, or an array (T, 2N)
        joints / (T, 6) poses, one sequence unless `sequence_id` (T,) splits it)."""
        ...

    def reset(self, *args: Any, **options: Any) -> None:
        """Start a new sequence: the next step() is its first (each family its own options)."""
        ...

    def step(self, x: np.ndarray, check: bool = True, strict: bool = False) -> Any:
        """One step of the current sequence: x (2N,) joints (FK) or (6,) target pose (IK)."""
        ...

    def export_onnx(self, path: Path, opset: int) -> None:
        """Write the network as an ONNX graph (ctrkin.models.onnx_graph), or raise ModelError."""
        ...

    def export_downgrade(self) -> str | None:
        """What the ONNX graph of export_onnx would lose against predict/step (the fold gate, a
        refinement outside the network), in words; None if it computes what they compute."""
        ...

    def describe(self) -> str:
        """What this predictor adds to the face's repr (", fold_gate"), or ""."""
        ...

    def stream_twin(self) -> Predictor:
        """The same model with a stream state of its own, at a sequence start (a batch that steps runs
        on one, so that predict never disturbs the stream; a second thread streams one)."""
        ...


@runtime_checkable
class Probing(Protocol):
    """An FK predictor that answers "where would the tip be if the next joints were these?" without
    advancing (the refined IK's residual, ctrkin.families.refined)."""

    def probe_tips(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tip positions (K, 3) mm and unit tangents (K, 3) for K candidate next joints Q (K, 2N)."""
        ...

    def alpha_into_range(self, Q: np.ndarray) -> np.ndarray:
        """Q (K, 2N) with each α moved by whole turns into the trained range."""
        ...

    def step(self, x: np.ndarray, check: bool = True, strict: bool = False) -> Any:
        ...

    def reset(self, *args: Any, **options: Any) -> None:
        ...

    def stream_twin(self) -> Any:
        ...


@dataclass(frozen=True)
class ModelEntry:
    """A registry name (`ctrkin train --model NAME`): description; build(n_inputs, n_outputs, ib,
    output_activation, **options) -> a fresh network; options: option -> default; forced: the
    TrainConfig fields it fixes (the Δα0 ablation's delta = False); defaults: the TrainConfig fields
    it sets where the configuration leaves them None (the snap-aware FK's target_frame = "outer")."""

    name: str
    description: str
    build: Callable[..., KinematicsNet]
    options: dict[str, Any]
    forced: dict[str, Any] = field(default_factory=dict)
    defaults: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Opened:
    """What every model folder gives its family's `load`: the common contents (ctrkin.models.store),
    the IK workspace, the folder (None: a bundle in memory, no family files) and whether FK steps
    may take the fused path (ctrkin.models.fused)."""

    bundle: ModelBundle
    workspace: Workspace | None = None
    folder: Path | None = None
    fused: bool = True


OpenFolder = Callable[[Path], Predictor]      # the registry's: opens any model folder


@dataclass(frozen=True)
class Family:
    """A model family as the registry knows it (module docstring).

    name: its folder under ctrkin/families; title: what users call it, in messages ("follow IK");
    entries: the model names it trains; load: a predictor for a folder of one of them; recipe: its
    training recipe for a configuration (None: not trained, assembled from other folders);
    predictors: its predictor classes (their `accepts` name the options messages point to);
    marker, wrap: a family that recognises a folder by a file of its own (`marker`, whatever model
    the folder holds) and wraps that model's predictor: wrap(inner, folder, open) (the refined IK);
    files: the files it writes beside the common model folder."""

    name: str
    title: str
    entries: tuple[ModelEntry, ...] = ()
    load: Callable[[Opened], Predictor] | None = None
    recipe: Callable[[TrainSettings], Recipe] | None = None
    predictors: tuple[type, ...] = ()
    marker: str | None = None
    wrap: Callable[[Predictor, Path, OpenFolder], Predictor] | None = None
    files: tuple[str, ...] = ()
