"""Per-step features and input-buffer windows (paper III.B, eq. 1-2; docs/learned_kinematics.md: Features).

Forward kinematics (FK), N tubes, per step n:
    (α1..αN, β1..βN, α0, Δα0)      α0(n) = α1(n) − αN(n)             (eq. 1)
                                   Δα0(n) = α0(n) − α0(n−1), 0 at a sequence start   (eq. 2)
For the paper's two tubes this is exactly (α1, α2, β1, β2, α0, Δα0). Angles are the unwrapped degrees
of the dataset (min-max on unwrapped angles is the paper's choice); `angle_encoding="sincos"` replaces
each angle αi and α0 by (sin, cos) — Δα0 stays in degrees; `angle_encoding="phase"` keeps the paper's
features and adds (sin α0, cos α0): the relative rotation modulo a turn, which is what decides where a
two-tube pair's bistable band lies (centred at α0 = 180°, docs/mechanics.md: Model), whatever the
unwrapped α0 of the sequence. `equivariant=True` drops the absolute angles α1..αN (the middle tubes'
αi − αN take their place): the inputs are then unchanged when every tube turns by the same angle, so
a model in the outer tube's frame is rotation-equivariant by construction, and whatever depends on
where the tip is in space (a tracker's field distortion) is left to a field of the position
(ctrkin.models.field).

Inverse kinematics (IK), per step: the tip pose (x, y, z, q0, qx, qy) and, by default, its step change
(Δx .. Δqy, 0 at a sequence start): the IK analogue of Δα0, it tells the model which way the robot is
moving, which is what disambiguates a hysteresis loop.

A window of IB steps holds the current step and the IB−1 previous ones, oldest first. Windows never
cross a sequence boundary: the start of a sequence is padded by repeating its first step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ctrkin.errors import ModelError
from ctrkin.geometry import POSE_COLUMNS
from ctrkin.models.choices import ANGLE_ENCODINGS, AngleEncoding, Task
from ctrkin.models.play_lags import path_lags, play_names
from ctrkin.robots.robot import alpha_names, beta_names

POSE_NAMES = POSE_COLUMNS    # the pose features are named as the dataset's pose columns
MAX_TUBES = 64               # bounds what a stored feature layout can make ctrkin allocate


@dataclass(frozen=True)
class FamilyLayout:
    """A feature layout a model family defines for itself (register_layout), where its features are
    not a function of the raw steps alone (the follow IK's depend on the robot's current joints).

    names: (inputs, outputs) names of a FeatureLayout of this kind, ModelError where its other
    settings do not suit it; why: why the shared feature functions refuse it (their message); play:
    whether a layout of this kind may take play lags (FeatureLayout.play; the family names and
    computes its own, e.g. the follow IK's of its target path); outer_angle: whether it may take the
    outer tube's absolute angle (FeatureLayout.outer_angle)."""

    names: Callable[[FeatureLayout], tuple[list[str], list[str]]]
    why: str
    play: bool = False
    outer_angle: bool = False


# name -> a family's own layout; a family registers it when it is imported (ctrkin.families.registry
# imports them all), so models/ names no family
FAMILY_LAYOUTS: dict[str, FamilyLayout] = {}


def register_layout(name: str, layout: FamilyLayout) -> None:
    """Register a family's own feature layout under `name` (FeatureLayout(family=name))."""
    FAMILY_LAYOUTS[name] = layout


@dataclass(frozen=True)
class FeatureLayout:
    """What goes into and comes out of a model, per step.

    task: "fk" (joints -> tip pose) or "ik" (tip poses -> joints); n_tubes: N; ib: input buffer length
    (current + IB−1 previous steps, 1..5 in the paper); delta: include Δα0 (FK) or the pose deltas (IK);
    angle_encoding: "minmax" (paper), "sincos" or "phase" (FK inputs only; module docstring);
    family: a layout a model family registered for itself (FAMILY_LAYOUTS, register_layout): its
    names are the family's and its features are computed by the family (e.g. "follow", the follow
    IK of ctrkin.families.follow.features); None: the paper's FK or IK layout above.
    equivariant: an FK's inputs without the absolute angles α1..αN (module docstring).
    play: an FK's inputs end with the play-operator lags of α1, αN and βN − β1
    (ctrkin.models.play_lags): a memory of the joint path beyond the window, which the features of a
    step cannot hold, so `sequence_features` and `step_features` are then given them; a family's
    layout that takes them (FamilyLayout.play: the follow IK's) computes them itself.
    outer_angle: a family's inputs also hold sin/cos of the outer tube's absolute angle αN, for what
    is not rotation-equivariant about the insertion axis (the tracker's field, a registration error);
    only layouts whose family takes it (FamilyLayout.outer_angle: the follow IK's, otherwise
    equivariant by construction).
    """

    task: Task = "fk"
    n_tubes: int = 2
    ib: int = 2
    delta: bool = True
    angle_encoding: AngleEncoding = "minmax"
    family: str | None = None
    play: bool = False
    equivariant: bool = False
    outer_angle: bool = False
    input_names: tuple[str, ...] = field(init=False)
    output_names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        if self.task not in ("fk", "ik"):
            raise ModelError(f"task must be 'fk' or 'ik', got {self.task!r}")
        if not isinstance(self.n_tubes, int) or not 1 <= self.n_tubes <= MAX_TUBES:
            raise ModelError(f"n_tubes must be an integer in 1..{MAX_TUBES}, got {self.n_tubes!r}")
        if not isinstance(self.ib, int) or not 1 <= self.ib <= 32:
            raise ModelError(f"input buffer ib must be an integer in 1..32 (paper: 1..5), got {self.ib!r}")
        if self.angle_encoding not in ANGLE_ENCODINGS:
            raise ModelError(f"angle_encoding must be one of {ANGLE_ENCODINGS}, got {self.angle_encoding!r}")
        if self.task == "ik" and self.angle_encoding != "minmax":
            raise ModelError(f"angle_encoding={self.angle_encoding!r} applies to FK inputs only; use "
                             "'minmax' for IK")
        if self.play and (self.task != "fk" if self.family is None else not family_layout(self.family).play):
            raise ModelError("play lags are inputs of the paper's FK layout and of the families' layouts "
                             "that take them (the follow IK's) only")
        if self.outer_angle and (self.family is None or not family_layout(self.family).outer_angle):
            raise ModelError("the outer tube's absolute angle is an input of the families' layouts that "
                             "take it (the follow IK's) only")
        if self.equivariant and (self.task != "fk" or self.family is not None
                                 or self.angle_encoding == "sincos"):
            raise ModelError("equivariant inputs are an FK layout's with the minmax or phase encoding")
        n = self.n_tubes
        alphas, betas = alpha_names(n), beta_names(n)
        if self.task == "fk" and self.family is None:
            if self.angle_encoding == "sincos":
                ins = [f"{f}_{a}" for a in alphas for f in ("sin", "cos")] + betas
                ins += ["sin_alpha_0", "cos_alpha_0"]
            else:
                ins = [*([f"{a}_rel" for a in alphas[1:n - 1]] if self.equivariant else alphas), *betas,
                       "alpha_0"]
                if self.angle_encoding == "phase":
                    ins += ["sin_alpha_0", "cos_alpha_0"]
            if self.delta:
                ins.append("delta_alpha_0")
            if self.play:
                ins += play_names(n)
            outs = list(POSE_NAMES)
        elif self.family is not None:
            ins, outs = family_layout(self.family).names(self)
        else:
            ins = list(POSE_NAMES) + ([f"delta_{p}" for p in POSE_NAMES] if self.delta else [])
            outs = alphas + betas
        object.__setattr__(self, "input_names", tuple(ins))
        object.__setattr__(self, "output_names", tuple(outs))

    @property
    def n_inputs(self) -> int:
        return len(self.input_names)

    @property
    def n_outputs(self) -> int:
        return len(self.output_names)

    @property
    def raw_width(self) -> int:
        """Columns of the raw per-step input: joints (2N) for FK, poses (6) for IK."""
        return 2 * self.n_tubes if self.task == "fk" else 6

    @property
    def raw_names(self) -> tuple[str, ...]:
        """Names of the raw per-step input's columns, in order: the dataset's joint columns
        (alpha_1..alpha_N, beta_1..beta_N) for FK, its pose columns (x, y, z, q0, qx, qy) for IK."""
        n = self.n_tubes
        return (*alpha_names(n), *beta_names(n)) if self.task == "fk" else tuple(POSE_NAMES)

    def to_dict(self) -> dict[str, object]:
        return {"task": self.task, "n_tubes": self.n_tubes, "ib": self.ib, "delta": self.delta,
                "angle_encoding": self.angle_encoding, "family": self.family, "play": self.play,
                "equivariant": self.equivariant, "outer_angle": self.outer_angle,
                "input_names": list(self.input_names),
                "output_names": list(self.output_names)}

    @classmethod
    def from_dict(cls, d: dict) -> FeatureLayout:
        """The layout of a model folder's features.json. Folders written before the families' own
        layouts were registered name one as a flag of its own (`"follow": true`): read as that
        family's layout."""
        family = d.get("family")
        if family is None:
            flags = [k for k, v in d.items() if v is True and k not in _LAYOUT_KEYS]
            family = flags[0] if len(flags) == 1 else None
        try:
            layout = cls(task=d["task"], n_tubes=int(d["n_tubes"]), ib=int(d["ib"]),
                         delta=bool(d["delta"]), angle_encoding=d["angle_encoding"],
                         family=None if family is None else str(family), play=bool(d.get("play", False)),
                         equivariant=bool(d.get("equivariant", False)),
                         outer_angle=bool(d.get("outer_angle", False)))
        except KeyError as e:
            raise ModelError(f"feature layout lacks {e}") from None
        if "input_names" in d and tuple(d["input_names"]) != layout.input_names:
            raise ModelError(f"stored feature names {d['input_names']} differ from this ctrkin's "
                             f"{list(layout.input_names)}: the model was made by another version")
        return layout

    def describe_difference(self, other: FeatureLayout) -> list[str]:
        """Human-readable list of what differs between two layouts (empty if equal)."""
        diffs = []
        for k in ("task", "n_tubes", "ib", "delta", "angle_encoding", "family", "play", "equivariant",
                  "outer_angle"):
            a, b = getattr(self, k), getattr(other, k)
            if a != b:
                diffs.append(f"{k}: {a!r} vs {b!r}")
        return diffs


_LAYOUT_KEYS = ("task", "n_tubes", "ib", "delta", "angle_encoding", "family", "play", "equivariant",
                "outer_angle", "input_names", "output_names")


def family_layout(name: str) -> FamilyLayout:
    """The registered layout of a family (ModelError if no family registered one by that name)."""
    try:
        return FAMILY_LAYOUTS[name]
    except KeyError:
        raise ModelError(f"feature layout {name!r} is not one a model family registered (registered: "
                         f"{sorted(FAMILY_LAYOUTS)}; ctrkin.families.registry imports every family)"
                         ) from None


def step_features(layout: FeatureLayout, raw: np.ndarray, prev_raw: np.ndarray | None,
                  lags: np.ndarray | None = None) -> np.ndarray:
    """Features of one step (the streaming path; must equal `sequence_features` row by row).

    raw: (2N,) joints (deg, mm) for FK or (6,) pose for IK; prev_raw: the previous step of the same
    sequence, or None at its start; lags (P,): a play layout's lags at this step
    (ctrkin.models.play_lags.PlayState). Returns (F,).
    """
    cur = np.asarray(raw, dtype=np.float64)[None, :]
    prev = cur if prev_raw is None else np.asarray(prev_raw, dtype=np.float64)[None, :]
    return _with_play(layout, _features(layout, cur, prev), None if lags is None else lags[None])[0]


def sequence_features(layout: FeatureLayout, raw: np.ndarray, bounds: list[tuple[int, int]],
                      lags: np.ndarray | None = None) -> np.ndarray:
    """Features of every row. raw: (T, 2N) joints or (T, 6) poses; bounds: [(start, stop)) of the
    sequences (deltas are 0 at each start); lags (T, P): a play layout's lags along the rows (default:
    each sequence from rest, ctrkin.models.play_lags.path_lags of raw). Returns (T, F) float64."""
    raw = check_raw(layout, raw)
    prev = np.empty_like(raw)
    prev[1:] = raw[:-1]
    for a, _ in bounds:
        prev[a] = raw[a]
    if layout.play and lags is None:
        lags = path_lags(raw, bounds, layout.n_tubes).columns()
    return _with_play(layout, _features(layout, raw, prev), lags)


def pair_features(layout: FeatureLayout, cur: np.ndarray, prev: np.ndarray, lags: np.ndarray | None = None
                  ) -> np.ndarray:
    """Features (K, F) of K candidate steps cur (K, 2N | 6) that would follow prev (K, 2N | 6); lags
    (K, P): a play layout's lags after each (PlayState.peek)."""
    cur2, prev2 = np.atleast_2d(np.asarray(cur, float)), np.atleast_2d(np.asarray(prev, float))
    return _with_play(layout, _features(layout, cur2, prev2), lags)


def _with_play(layout: FeatureLayout, feats: np.ndarray, lags: np.ndarray | None) -> np.ndarray:
    """feats (T, F − P) with a play layout's lags (T, P) appended (ModelError where none are given)."""
    if not layout.play:
        return feats
    if lags is None:
        raise ModelError("a play layout's features need the play lags along the path "
                         "(ctrkin.models.play_lags.PlayState)")
    lags = np.asarray(lags, float)
    if lags.shape != (len(feats), layout.n_inputs - feats.shape[1]):
        raise ModelError(f"play lags must have shape ({len(feats)}, {layout.n_inputs - feats.shape[1]}), "
                         f"got {lags.shape}")
    return np.concatenate([feats, lags], axis=1)


def delta_columns(layout: FeatureLayout) -> np.ndarray:
    """Indices of the step-change features (Δα0, Δx..Δqy): the model only knows the step sizes of its
    training data, so callers clip these to the trained range (direction kept, size bounded)."""
    return np.array([i for i, n in enumerate(layout.input_names) if n.startswith("delta_")], dtype=np.int64)


def _features(layout: FeatureLayout, cur: np.ndarray, prev: np.ndarray) -> np.ndarray:
    if layout.family is not None:
        raise ModelError(f"the {layout.family} layout's features are its family's: "
                         f"{family_layout(layout.family).why}")
    n = layout.n_tubes
    if layout.task == "ik":
        cols = [cur] + ([cur - prev] if layout.delta else [])
        return np.concatenate(cols, axis=1)
    alpha, beta = cur[:, :n], cur[:, n:]
    a0 = alpha[:, 0] - alpha[:, n - 1]                      # eq. (1)
    cols_: list[np.ndarray]
    if layout.angle_encoding == "sincos":
        ang = np.radians(np.concatenate([alpha, a0[:, None]], axis=1))
        sc = np.stack([np.sin(ang), np.cos(ang)], axis=2).reshape(len(cur), -1)
        cols_ = [sc[:, : 2 * n], beta, sc[:, 2 * n:]]
    else:
        cols_ = [alpha[:, 1:n - 1] - alpha[:, n - 1:n] if layout.equivariant else alpha, beta, a0[:, None]]
        if layout.angle_encoding == "phase":
            r = np.radians(a0)[:, None]
            cols_ += [np.sin(r), np.cos(r)]
    if layout.delta:
        a0_prev = prev[:, 0] - prev[:, n - 1]
        cols_.append((a0 - a0_prev)[:, None])                # eq. (2)
    return np.concatenate(cols_, axis=1)


def real_array(x: Any) -> np.ndarray:
    """x as a float64 array; complex values are refused (ModelError), not truncated to their real part,
    and so is anything that is not an array of numbers (a ragged list)."""
    try:
        complex_ = bool(np.iscomplexobj(x))
        arr = None if complex_ else np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ModelError(f"model inputs must be an array of numbers (equal-length rows): {e}") from None
    if arr is None:
        raise ModelError("model inputs must be real numbers, got complex values")
    return arr


def by_name(x: Any, names: tuple[str, ...], what: str) -> Any:
    """x with its columns in the order `names` where x labels them (a pandas DataFrame's column
    names, a Series' index: `df.iloc[t]`), so that labelled inputs are read by name, never by
    position; x unchanged where it carries no text labels (an array, a list, a frame built from an
    array). A labelled x that lacks some of `names` is refused (ModelError naming them)."""
    if type(x).__module__.partition(".")[0] != "pandas":
        return x
    labels = list(x.columns if getattr(x, "ndim", 1) == 2 else x.index)
    if not labels or not all(isinstance(c, str) for c in labels):
        return x
    missing = [c for c in names if c not in labels]
    if missing:
        raise ModelError(f"the {what} lack the column(s) {missing} (got {labels}); a model reads its "
                         f"inputs {list(names)} by name")
    return x[list(names)]


def check_raw(layout: FeatureLayout, raw: Any) -> np.ndarray:
    """Validate a raw (T, 2N) joint or (T, 6) pose array for this layout (a pandas DataFrame is read
    by its column names, `by_name`)."""
    what = f"joints (α1..α{layout.n_tubes} deg, β1..β{layout.n_tubes} mm)" if layout.task == "fk" \
        else "tip poses (x, y, z mm, q0, qx, qy)"
    arr = real_array(by_name(raw, layout.raw_names, what))
    if arr.ndim != 2 or arr.shape[1] != layout.raw_width:
        raise ModelError(f"this {layout.task.upper()} model expects {what}: an array (T, "
                         f"{layout.raw_width}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"input {what} contain NaN or inf at row {int(np.argmax(~np.isfinite(arr).all(1)))}")
    return arr


def window_index(bounds: list[tuple[int, int]], ib: int) -> np.ndarray:
    """(T, IB) row indices of the window ending at each row, oldest first, clamped to the start of
    the row's sequence (the start is padded by repeating the first step)."""
    total = bounds[-1][1] if bounds else 0
    start = np.empty(total, dtype=np.int64)
    for a, b in bounds:
        start[a:b] = a
    rows = np.arange(total)[:, None] + np.arange(-ib + 1, 1)[None, :]
    return np.maximum(rows, start[:, None])


def windows(features: np.ndarray, bounds: list[tuple[int, int]], ib: int) -> np.ndarray:
    """features: (T, F) -> (T, IB, F) input buffers that never cross a sequence boundary."""
    return features[window_index(bounds, ib)]


def postprocess(layout: FeatureLayout, y: np.ndarray) -> np.ndarray:
    """Denormalised outputs (..., O) -> user outputs: FK quaternions (q0, qx, qy) rescaled to unit
    length (the network predicts them component-wise); IK joints unchanged."""
    if layout.task != "fk":
        return y
    y = np.array(y, dtype=np.float64, copy=True)
    q = y[..., 3:6]
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    y[..., 3:6] = q / np.where(n > 1e-12, n, 1.0)
    return y
