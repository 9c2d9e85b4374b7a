"""Tube description: validation names the field, stiffness formulas, sections."""

from __future__ import annotations

import math

import pytest

from ctrkin.errors import RobotDescriptionError
from ctrkin.robots import Section, Tube


def test_stiffness_formulas() -> None:
    t = Tube(od=1.0, id=0.6, straight_length=10, curved_length=5, curvature=0.02,
             youngs_modulus=50.0, poisson_ratio=0.3)
    i = math.pi * (1.0 - 0.6**4) / 64
    assert t.second_moment == pytest.approx(i)
    assert t.bending_stiffness == pytest.approx(50e3 * i)
    assert t.torsional_stiffness == pytest.approx(50e3 / 2.6 * 2 * i)
    assert t.length == 15
    assert t.sections == (Section(10.0, 0.0), Section(5.0, 0.02))


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"od": -1.0}, "od"),
    ({"id": 1.2}, "id"),
    ({"straight_length": -1.0}, "straight_length"),
    ({"curvature": -0.1}, "curvature"),
    ({"youngs_modulus": 0.0}, "youngs_modulus"),
    ({"poisson_ratio": 0.5}, "poisson_ratio"),
    ({"curvature": float("nan")}, "curvature"),
    ({"straight_length": 0.0, "curved_length": 0.0}, "length"),
])
def test_invalid_tube_names_the_field(kwargs: dict, field: str) -> None:
    base = {"od": 1.0, "id": 0.8, "straight_length": 10.0, "curved_length": 5.0, "curvature": 0.01}
    with pytest.raises(RobotDescriptionError, match=field):
        Tube(**{**base, **kwargs})


def test_zero_curvature_and_zero_lengths_allowed() -> None:
    assert Tube(1.0, 0.8, 0.0, 5.0, 0.01).sections == (Section(5.0, 0.01),)
    assert Tube(1.0, 0.8, 5.0, 0.0, 0.0).sections == (Section(5.0, 0.0),)


def test_piecewise_sections() -> None:
    t = Tube.from_sections(1.0, 0.8, [(20.0, 0.0), (5.0, 0.001), (10.0, 0.04), (3.0, 0.0)])
    assert t.straight_length == 20.0 and t.curved_length == 18.0 and t.curvature == 0.001
    assert len(t.sections) == 4
    assert Tube(**{k: v for k, v in t.to_dict().items() if k != "sections"},
                sections=t.sections) == t
