"""The follow IK's features: what takes the robot from its current joints to the next target.

The paper's IK maps a target pose to joints. For a two-tube robot that map is not a function: the
relative rotation α0 and its mirror −α0, each with its own common rotation, put the tip at almost
the same pose (exactly the same for torsionally rigid tubes), and on a hysteresis loop one pose has a
joint solution on each branch. A regression net averages the solutions and the robot, driven to the
average, misses the target by millimetres. A controller always knows the joints the robot is at, and
the solution it wants is the one continuous with them, so the follow IK learns

    Δq = f(p_local(t), p_local(t) − p_local(t−1), sin/cos(αi − αN), β)        q(t) = q(t−1) + Δq

with p_local the target in the frame that turns with the current outer tube (ctrkin.models.frame:
rotation equivariance about the insertion axis), and the current joints q(t−1) as input. Trained
with the current joints perturbed (JOINT_NOISE) and the true next joints as target, the net learns a
contraction onto the solution nearest the current joints, not only the step along the path: applied
again at the same target it corrects its own error (the `settle` iterations), and a sequence may
start from the joints of the nearest training target.

Targets farther than the training steps apart are followed through intermediate targets
(`substeps`), as a path planner would interpolate them.

With the play lags (FeatureLayout.play; ctrkin.models.play_lags.target_lags) the inputs also hold
the play-operator lags of the target path's position (x, y, z at half widths of 0.3–10 mm, up to and
including this target): where the targets came from, which sets the friction state the robot will
be in when it gets there (on a hysteretic robot one pose and current joints are reached with other
joints after other histories). A follow IK has its targets exactly, so their lags carry none of its
own errors (the lags of the joints it answered did: measured no better). No friction law is assumed.
"""

from __future__ import annotations

import math

import numpy as np

from ctrkin.errors import ModelError
from ctrkin.geometry import POSE_COLUMNS, quat_from_tangent, tangent_from_quat
from ctrkin.models.features import FamilyLayout, FeatureLayout, register_layout
from ctrkin.models.frame import OuterFrame
from ctrkin.models.play_lags import target_play_names
from ctrkin.robots.robot import alpha_names, beta_names

# perturbation of the current joints in training: σ per level (deg for α, SIGMA_BETA_PER_DEG × σ mm
# for β), mixed with these probabilities (0: the exact path, large: a bad start to recover from)
JOINT_NOISE_DEG = (0.0, 1.0, 5.0, 20.0)
JOINT_NOISE_PROB = (0.25, 0.35, 0.25, 0.15)
SIGMA_BETA_PER_DEG = 0.1


LAYOUT = "follow"    # the follow IK's feature layout: FeatureLayout(family=LAYOUT)


def layout_names(layout: FeatureLayout) -> tuple[list[str], list[str]]:
    """(inputs, outputs) names of the follow IK's layout: the target in the current outer tube's
    frame, its step, sin/cos of each tube's angle to the outer one, the β; the joint change."""
    if layout.task != "ik" or layout.ib != 1:
        raise ModelError("the follow layout is an IK layout with input buffer 1 (ctrkin.families.follow)")
    n = layout.n_tubes
    local = [f"{p}_local" for p in POSE_COLUMNS]
    ins = local + [f"step_{p}" for p in local]
    ins += [f"{f}_alpha_{i + 1}{n}" for i in range(n - 1) for f in ("sin", "cos")] + beta_names(n)
    if layout.outer_angle:
        ins += [f"sin_alpha_{n}", f"cos_alpha_{n}"]
    if layout.play:
        ins += target_play_names()
    return ins, [f"step_{j}" for j in alpha_names(n) + beta_names(n)]


register_layout(LAYOUT, FamilyLayout(
    layout_names, "they depend on the current joints (follow_features, ctrkin.families.follow)", play=True,
    outer_angle=True))


def follow_features(frame: OuterFrame, n_tubes: int, target: np.ndarray, previous: np.ndarray,
                    joints: np.ndarray, lags: np.ndarray | None = None, outer_angle: bool = False
                    ) -> np.ndarray:
    """Inputs (M, 12 + 2(N−1) + N [+ 2] [+ P]) of the follow IK
    (FeatureLayout(family=LAYOUT).input_names).

    target, previous: (M, 6) tracker-frame poses of this and the previous target (equal at a start);
    joints: (M, 2N) the current joints (deg, mm), whose outer angle αN sets the local frame; lags:
    (M, P) a play layout's lags of the target path up to this target (appended as they are);
    outer_angle: sin/cos αN before the lags (FeatureLayout.outer_angle).
    """
    n = n_tubes
    q = np.asarray(joints, float)
    m = len(q)
    both = frame.to_local(np.concatenate([target, previous]), np.concatenate([q[:, n - 1], q[:, n - 1]]))
    local, local_prev = both[:m], both[m:]
    rel = np.radians(q[:, : n - 1] - q[:, n - 1: n])
    sc = np.stack([np.sin(rel), np.cos(rel)], axis=2).reshape(len(q), -1)
    parts = [local, local - local_prev, sc, q[:, n:]]
    if outer_angle:
        a_n = np.radians(q[:, n - 1: n])
        parts += [np.sin(a_n), np.cos(a_n)]
    return np.concatenate(parts if lags is None else [*parts, np.asarray(lags, float)], axis=1)


def joint_noise(rng: np.random.Generator, m: int, n_tubes: int) -> np.ndarray:
    """(m, 2N) perturbations of the current joints for training (JOINT_NOISE_*)."""
    level = rng.choice(np.array(JOINT_NOISE_DEG), size=(m, 1), p=np.array(JOINT_NOISE_PROB))
    scale = np.r_[np.ones(n_tubes), np.full(n_tubes, SIGMA_BETA_PER_DEG)]
    return rng.standard_normal((m, 2 * n_tubes)) * level * scale


def previous_rows(bounds: list[tuple[int, int]]) -> np.ndarray:
    """(T,) index of each row's previous row in its sequence (itself at a sequence start)."""
    total = bounds[-1][1] if bounds else 0
    prev = np.arange(total) - 1
    for a, _ in bounds:
        prev[a] = a
    return prev


def substeps(previous: np.ndarray, target: np.ndarray, max_step_mm: float) -> np.ndarray:
    """(K, 6) targets from just after `previous` (6,) to `target` (6,), K ≥ 1, consecutive ones at
    most max_step_mm apart: positions linear, tangents interpolated on the sphere (normalised lerp)."""
    dist = float(np.linalg.norm(target[:3] - previous[:3]))
    k = max(1, math.ceil(dist / max_step_mm)) if np.isfinite(dist) and max_step_mm > 0 else 1
    if k == 1:
        return np.asarray(target, float)[None]
    s = np.arange(1, k + 1)[:, None] / k
    pos = previous[:3] + s * (target[:3] - previous[:3])
    t0, t1 = tangent_from_quat(previous[3:6]), tangent_from_quat(target[3:6])
    return np.concatenate([pos, quat_from_tangent(t0 + s * (t1 - t0))], axis=1)
