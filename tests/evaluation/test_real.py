"""A learned model flags joints outside its training range instead of answering silently."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ctrkin.evaluation.real import out_of_range
from ctrkin.models.normalize import MinMax


def test_out_of_range_flags_per_joint_with_margin():
    names = ["alpha_1", "alpha_2", "beta_1", "beta_2"]
    kin = SimpleNamespace(bundle=SimpleNamespace(x_norm=MinMax(    # a folder from before data_hi
        lo=np.array([-90.0, 0.0, -160.0, -91.0, 0.0]), span=np.array([180.0, 1.0, 40.0, 1.0, 1.0]))),
        layout=SimpleNamespace(input_names=(*names, "alpha_0")))
    joints = np.array([[0.0, 0.5, -150.0, -90.5],     # inside
                       [95.0, 0.5, -150.0, -90.5],    # 5° beyond 90, margin 9°: inside
                       [100.0, 0.5, -150.0, -90.5],   # beyond the margin
                       [0.0, 0.5, -110.0, -90.5]])    # β1 beyond -120 + 2 mm
    flags = out_of_range(kin, joints, names)
    assert flags["rows"].tolist() == [False, False, True, True]
    assert flags["joints"]["alpha_1"]["count"] == 1 and flags["joints"]["beta_1"]["count"] == 1
    assert abs(flags["joints"]["alpha_1"]["margin"] - 9.0) < 1e-12


def _sincos_kin(sin_cos_ranges, beta_ranges):
    """A stand-in for a sin/cos-encoded FK model: its inputs and the MinMax fitted on rows that
    span the given (lo, hi) per input."""
    names, lo, hi = [], [], []
    for i, rng in enumerate(sin_cos_ranges):
        for f, (a, b) in zip(("sin", "cos"), rng, strict=True):
            names.append(f"{f}_alpha_{i + 1}")
            lo.append(a)
            hi.append(b)
    for i, (a, b) in enumerate(beta_ranges):
        names.append(f"beta_{i + 1}")
        lo.append(a)
        hi.append(b)
    norm = MinMax.fit(np.array([lo, hi]))
    return SimpleNamespace(bundle=SimpleNamespace(x_norm=norm),
                           layout=SimpleNamespace(input_names=tuple(names)))


def test_sincos_angles_are_checked_too():
    """Issue 22: a model trained with --angles sincos at one outer angle flagged nothing at −77..90°."""
    names = ["alpha_1", "alpha_2", "beta_1", "beta_2"]
    # α1 trained over −90..90° (sin −1..1, cos 0..1); α2 held at 0° (sin 0, cos 1: constant columns)
    kin = _sincos_kin([((-1.0, 1.0), (0.0, 1.0)), ((0.0, 0.0), (1.0, 1.0))],
                      [(-160.0, -120.0), (-91.0, -91.0)])
    joints = np.array([[0.0, 0.0, -150.0, -91.0],      # inside
                       [80.0, 0.5, -150.0, -91.0],     # α2 within the least margin (1°) of 0°
                       [0.0, -77.0, -150.0, -91.0],    # α2 far from its one trained angle
                       [0.0, 90.0, -150.0, -91.0],
                       [170.0, 0.0, -150.0, -91.0],    # α1 behind the trained half-turn
                       [0.0, 0.0, -150.0, -89.0]])     # β2 held at −91 in training
    flags = out_of_range(kin, joints, names)
    assert flags["rows"].tolist() == [False, False, True, True, True, True]
    a2 = flags["joints"]["alpha_2"]
    assert a2["count"] == 2 and -1.5 <= a2["lo"] <= -0.5 and 0.5 <= a2["hi"] <= 1.5   # about [−1°, 1°]
    a1 = flags["joints"]["alpha_1"]
    assert a1["count"] == 1 and -95 <= a1["lo"] <= -85 and 85 <= a1["hi"] <= 95
    b2 = flags["joints"]["beta_2"]
    assert (b2["lo"], b2["hi"]) == (-91.0, -91.0) and b2["margin"] == 0.5   # not [−91, −90]


def test_an_arc_across_the_half_turn_is_reported_continuous():
    """α trained over 150..210° (sin −0.5..0.5, cos −1..−0.87): the arc wraps past 180°."""
    kin = _sincos_kin([((-0.5, 0.5), (-1.0, float(np.cos(np.radians(150)))))], [(-10.0, 0.0)])
    flags = out_of_range(kin, np.array([[180.0, -5.0], [0.0, -5.0]]), ["alpha_1", "beta_1"])
    assert flags["rows"].tolist() == [False, True]
    a = flags["joints"]["alpha_1"]
    assert 145 <= a["lo"] <= 150 and 210 <= a["hi"] <= 215


def test_a_fitted_normaliser_keeps_the_data_range_through_its_file():
    norm = MinMax.fit(np.array([[0.0, 1.0], [0.0, 3.0]]))            # column 0 constant
    back = MinMax.from_dict(norm.to_dict())
    np.testing.assert_array_equal(back.trained_range()[1], [0.0, 3.0])
    np.testing.assert_array_equal(back.span, [1.0, 2.0])             # the transform is unchanged
    old = MinMax.from_dict({"lo": [0.0, 1.0], "span": [1.0, 2.0]})   # a folder from before 0.2
    np.testing.assert_array_equal(old.trained_range()[1], [1.0, 3.0])
