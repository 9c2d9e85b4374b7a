"""VirtualConfig: validation messages say what to change; round trip through the dataset meta; the
defaults and the central values (issue 20)."""

from __future__ import annotations

from pathlib import Path

import pytest

from ctrkin.errors import CtrkinError
from ctrkin.virtual import VirtualConfig, VirtualConfigError
from ctrkin.virtual.config import CENTRAL


def test_defaults_are_valid_and_round_trip():
    c = VirtualConfig()
    assert VirtualConfig.from_dict(c.to_dict()) == c
    assert c.readings_per_sample == 5  # the paper averaged five readings


@pytest.mark.parametrize(("name", "value", "words"), [
    ("precurvature_error", -0.1, ">= 0"),
    ("noise_mm", float("nan"), "finite"),
    ("glitch_rate", 0.9, "<= 0.5"),
    ("friction_deg_per_mm", True, "finite number"),
    ("residual_curvature", 0.5, "<= 0.01"),
])
def test_invalid_magnitudes_are_refused(name, value, words):
    with pytest.raises(VirtualConfigError, match=f"VirtualConfig.{name}.*") as e:
        VirtualConfig(**{name: value})
    assert words in str(e.value)
    assert isinstance(e.value, CtrkinError)


@pytest.mark.parametrize("n", [0, 2.5, True])
def test_readings_must_be_a_positive_integer(n):
    with pytest.raises(VirtualConfigError, match="readings_per_sample"):
        VirtualConfig(readings_per_sample=n)


def test_unknown_setting_names_the_allowed_ones():
    with pytest.raises(VirtualConfigError, match=r"allowed: .*noise_mm"):
        VirtualConfig.from_dict({"noise": 0.1})


def test_ideal_switches_everything_off():
    """Every effect 0; the EM warp's length scale and the contacts' elastic slip (shapes that switch
    nothing) are kept."""
    c = VirtualConfig().ideal()
    d = c.to_dict()
    assert d.pop("readings_per_sample") == 1
    assert d.pop("em_distortion_length_mm") == VirtualConfig().em_distortion_length_mm
    assert d.pop("presliding_mm") == VirtualConfig().presliding_mm
    assert all(v == 0.0 for v in d.values())


DOCS = Path(__file__).parents[2] / "docs" / "virtual_robot.md"


def _documented_set_line() -> dict[str, float]:
    """The `--set` line of the central values in docs/virtual_robot.md (Effects and default
    magnitudes), as VirtualConfig fields."""
    lines = [ln for ln in DOCS.read_text().splitlines() if ln.strip().startswith("--set ")]
    assert len(lines) == 1, lines
    pairs = (item.split("=", 1) for item in lines[0].split("--set")[1:])
    return {k.strip(): float(v) for k, v in pairs}


def test_the_defaults_are_the_top_of_the_ranges_and_the_documented_line_gives_the_central_values():
    """Issue 20: the defaults are every effect at the top of its published range; the central
    values (the defaults before) are one documented --set line away, and `central()` is that line.
    Each central value is below its default (a top is an upper end)."""
    central = VirtualConfig().central()
    assert set(CENTRAL) == set(_documented_set_line())
    assert VirtualConfig(**_documented_set_line()) == central
    default = VirtualConfig().to_dict()
    changed = {k for k, v in central.to_dict().items() if default[k] != v}
    assert changed == set(CENTRAL)
    assert all(CENTRAL[k] < default[k] for k in CENTRAL)
    assert (default["tube_friction"], default["sensor_offset_mm"], default["precurvature_error"]) == (
        0.69, 6.5, 0.20)
