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
    # issue 9 items 5, 6: physical bounds, the unit in the message (no hang, no OverflowError)
    ({"straight_length": 1e10}, "straight_length must be <= 10000 mm"),
    ({"od": 1e300, "id": 0.0}, r"od must be between .* mm"),
    ({"od": 1e-300, "id": 0.0}, r"od must be between .* mm"),
    ({"curvature": 610.0}, r"curvature must be between 0 and 10 1/mm"),
    ({"curvature": 1e300}, r"curvature .* 1/mm"),
    ({"youngs_modulus": 1e300}, r"youngs_modulus .* GPa"),
    ({"od": 10**400}, "od must be a finite number"),
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


def test_out_of_plane_section_round_trips() -> None:
    """A section [length, κx, κy] is precurvature leaving the tube's plane (issue 20); it survives
    the robot file and a planar section keeps its two-number form."""
    t = Tube.from_sections(0.4, 0.2, [[20.0, 0.0], [10.0, 0.03, 0.002], [5.0, 0.03]])
    assert t.sections[1].curvature_y == 0.002 and t.sections[1].curved
    assert t.to_dict()["sections"] == [[20.0, 0.0], [10.0, 0.03, 0.002], [5.0, 0.03]]
    assert Tube.from_sections(0.4, 0.2, t.to_dict()["sections"]) == t


@pytest.mark.parametrize(("sections", "message"), [
    ([[10.0]], r"sections\[0\] must be a pair"),
    ([[10.0, 0.1, 3.0, 1.0]], r"sections\[0\] must be a pair"),
    ([[10.0, 0.1, 20.0]], r"curvature_y must be within ±10 1/mm"),
    ([["a", 0.1]], r"sections\[0\]\.length must be a finite number"),
    ([[1e9 * 1e9, 0.0]], r"must be <= 10000 mm"),
    ([[10.0, -1e3]], r"curvature must be .*10 1/mm"),
    ([[10.0, 0.01], [5.0, -1e3]], r"sections\[1\]\.curvature must be within ±10 1/mm"),
    (5.0, "list of"),
])
def test_malformed_sections_are_clear_errors(sections: object, message: str) -> None:
    """Issue 9 item 6: `sections = [[10.0]]` gave an unpacking ValueError."""
    with pytest.raises(RobotDescriptionError, match=message):
        Tube.from_sections(1.0, 0.8, sections)  # type: ignore[arg-type]


def test_a_tube_of_absurdly_many_sections_is_refused_at_once() -> None:
    """Issue 27 item 18: a tube of 400,000 sections took 51 s for the tube and one solve (growing
    about quadratically), with no bound."""
    import time

    sections = [[0.001, 0.01 * (k % 2)] for k in range(400_000)]
    t0 = time.perf_counter()
    with pytest.raises(RobotDescriptionError, match="more than"):
        Tube.from_sections(1.0, 0.6, sections)
    with pytest.raises(RobotDescriptionError, match="more than"):
        Tube(1.0, 0.6, 0.0, 400.0, 0.01, sections=tuple(tuple(s) for s in sections))
    assert time.perf_counter() - t0 < 5.0


def test_a_precurvature_no_tube_can_hold_is_refused() -> None:
    """Issue 27's fuzz: a 0.68 mm tube coiled at 1.98 /mm (67 % wall strain) made follow spend its
    work bound on every step (11 s for 7 steps). Nitinol recovers about 8-10 %; beyond 20 % no tube
    exists, so the description is refused, naming the curvature this diameter allows."""
    Tube(od=1.0, id=0.8, straight_length=10.0, curved_length=10.0, curvature=0.4)       # 20 %: the bound
    with pytest.raises(RobotDescriptionError, match=r"strains its wall by 67%.*curvature <= 0\.586"):
        Tube(od=0.6822, id=0.41, straight_length=26.0, curved_length=111.0, curvature=1.978)
    with pytest.raises(RobotDescriptionError, match="strains its wall"):
        Tube.from_sections(od=1.0, id=0.8, sections=[(10.0, 0.0), (5.0, -0.5)])


def test_the_strain_bound_reads_the_whole_precurvature_magnitude() -> None:
    """A section's precurvature is û = (κx, κy, 0): its wall strain is √(κx² + κy²)·od/2. Two
    components each within the bound (0.3 /mm on 1 mm: 15 %) make 0.424 /mm, 21 %: refused; the same
    magnitude in one component is refused alike, and 0.28 + 0.28 (0.396 /mm, 19.8 %) passes."""
    Tube.from_sections(od=1.0, id=0.8, sections=[(10.0, 0.0), (5.0, 0.28, 0.28)])
    with pytest.raises(RobotDescriptionError, match="strains its wall by 21%"):
        Tube.from_sections(od=1.0, id=0.8, sections=[(10.0, 0.0), (5.0, 0.3, 0.3)])
    with pytest.raises(RobotDescriptionError, match="strains its wall by 21%"):
        Tube.from_sections(od=1.0, id=0.8, sections=[(10.0, 0.0), (5.0, 0.0, -0.4243)])
