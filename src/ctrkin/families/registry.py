"""The model families by name: one line per family (FAMILIES), and what the rest of ctrkin asks of
them. Training (ctrkin.training) and inference (ctrkin.inference) reach a family only through here.

    from ctrkin.families.registry import MODELS, build_model, open_folder
    net = build_model("lstm_mlp", n_inputs=6, n_outputs=6, ib=2)               # paper default
    net = build_model("lstm_mlp", 6, 6, 3, options={"structure": "S3"})        # Table III grid
    predictor = open_folder("models/fk")                                       # Kinematics.load's

Each model name (`ctrkin train --model NAME`) is an entry of one family (ctrkin.models.predictor:
ModelEntry): its network, the options it takes and the training settings it fixes (the Δα0 ablation
of Fig. 5b is the LSTM-MLP without the delta feature; the snap-aware model uses the phase features
and a linear output). A model folder opens as the predictor of its model's family, and a family with
a marker file (the refined IK's refine.json) wraps the predictor of the folder it marks.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch

from ctrkin.errors import ModelError
from ctrkin.families import follow, refined, sequence, snap_aware
from ctrkin.models.base import KinematicsNet
from ctrkin.models.features import FeatureLayout
from ctrkin.models.predictor import Family, ModelEntry, Opened, Predictor
from ctrkin.models.recipe import Recipe, TrainSettings
from ctrkin.models.store import ModelBundle, ModelConfig
from ctrkin.models.workspace import WORKSPACE_FILE, Workspace

MAX_PARAMETERS = 20_000_000     # 80 MB of float32 weights: 200x the largest model ctrkin trains

FAMILIES: tuple[Family, ...] = (
    sequence.FAMILY,       # the paper's LSTM-MLP, its ablation and structures, and the baselines
    snap_aware.FAMILY,     # lstm_mlp_branch
    follow.FAMILY,         # follow_mlp
    refined.FAMILY,        # an IK folder refined on an FK folder (refine.json)
)

MODELS: dict[str, ModelEntry] = {e.name: e for f in FAMILIES for e in f.entries}
_FAMILY_OF: dict[str, Family] = {e.name: f for f in FAMILIES for e in f.entries}


def get_entry(name: str) -> ModelEntry:
    if name not in MODELS:
        raise ModelError(f"unknown model {name!r}; choose one of {sorted(MODELS)}")
    return MODELS[name]


def family_of(model: str) -> Family:
    """The family that trains model `model` (a registry name)."""
    get_entry(model)
    return _FAMILY_OF[model]


def resolve_options(name: str, options: dict[str, Any] | None) -> dict[str, Any]:
    """The entry's defaults updated by `options`; unknown options are an error naming the valid ones."""
    entry = get_entry(name)
    options = dict(options or {})
    unknown = sorted(set(options) - set(entry.options))
    if unknown:
        raise ModelError(f"model {name!r} takes options {sorted(entry.options)}, not {unknown}")
    return {**entry.options, **options}


def build_model(name: str, n_inputs: int, n_outputs: int, ib: int, output_activation: str = "relu",
                options: dict[str, Any] | None = None) -> KinematicsNet:
    """A fresh (randomly initialised, seed it with torch.manual_seed) network by registry name.

    The network is first built on torch's meta device (shapes only, no memory) and refused if it
    would hold more than MAX_PARAMETERS weights: a configuration or a model folder's config.json
    cannot make ctrkin allocate without bound (LSTM units, layers, widths, channels)."""
    entry = get_entry(name)
    opts = resolve_options(name, options)
    with torch.device("meta"):
        size = sum(p.numel() for p in entry.build(n_inputs, n_outputs, ib, output_activation,
                                                   **opts).parameters())
    if size > MAX_PARAMETERS:
        raise ModelError(f"model {name!r} with options {opts} would have {size:,} parameters, more than "
                         f"ctrkin's bound of {MAX_PARAMETERS:,} (the paper's LSTM-MLP has ~86,000); "
                         "choose smaller layers")
    net = entry.build(n_inputs, n_outputs, ib, output_activation, **opts)
    net.init_output_bias()
    return net


def build_net(config: ModelConfig, layout: FeatureLayout) -> KinematicsNet:
    """A fresh network for a model folder's configuration and layout (ModelBundle.create's `build`)."""
    return build_model(config.model, layout.n_inputs, layout.n_outputs, layout.ib, config.output_activation,
                       config.options)


def recipe(cfg: TrainSettings) -> Recipe:
    """The training recipe of the family of cfg.model (ctrkin.models.recipe)."""
    fam = family_of(cfg.model)
    if fam.recipe is None:
        raise ModelError(f"model {cfg.model!r} ({fam.title}) is not trained")
    return fam.recipe(cfg)


def open_bundle(folder: str | Path) -> ModelBundle:
    """The common contents of a model folder (ctrkin.models.store), its network built by name."""
    return ModelBundle.load(folder, build_net)


def predictor(opened: Opened) -> Predictor:
    """The predictor of the family of a bundle's model (no marker files are read)."""
    fam = family_of(opened.bundle.config.model)
    assert fam.load is not None
    return fam.load(opened)


def open_folder(path: str | Path, fused: bool = True) -> Predictor:
    """The predictor of a model folder (Kinematics.load): its model's family's, wrapped by each family
    whose marker file the folder holds. fused=False: FK steps take the reference path."""
    src = Path(path)
    bundle = open_bundle(src)
    ws = Workspace.load(src) if (src / WORKSPACE_FILE).is_file() else None
    if bundle.layout.task == "ik" and ws is None:
        raise ModelError(f"{src} is an IK model without {WORKSPACE_FILE}; retrain it with ctrkin train")
    pred = predictor(Opened(bundle, ws, src, fused))
    for fam in FAMILIES:
        if fam.marker is not None and fam.wrap is not None and (src / fam.marker).is_file():
            pred = fam.wrap(pred, src, open_folder)
    return pred


def refused_options(pred: Predictor, method: str, options: dict[str, Any]) -> str | None:
    """Why `pred` refuses keyword options of `method` ("predict", "reset") that it does not take
    (None-valued ones aside), naming the families that do; None if it takes them all."""
    given = sorted(k for k, v in options.items() if v is not None)
    extra = [k for k in given if k not in pred.accepts.get(method, frozenset())]
    if not extra:
        return None
    parts = []
    for key in extra:
        takers = [f for f in FAMILIES
                  if any(key in getattr(p, "accepts", {}).get(method, ()) for p in f.predictors)]
        where = "; ".join(f"a {f.title} ({', '.join(e.name for e in f.entries) or f.name})" for f in takers)
        parts.append(f"{method}({key}=...) applies to {where or 'no model'} only")
    return f"{'; '.join(parts)}; this is model {pred.bundle.config.model!r}"
