"""`ctrkin collect --scale`: the choices, default and training data of `ctrkin reproduce --scale`."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.data import Dataset


def test_scale_choices_and_default_match_reproduce() -> None:
    runner = CliRunner()
    for command in ("collect", "reproduce"):
        res = runner.invoke(cli, [command, "--help"])
        assert res.exit_code == 0
        text = " ".join(res.output.split())
        assert "--scale [full|quick|tiny]" in text and "default: quick" in text, command


def test_tiny_is_the_data_of_reproduce_tiny(tmp_path) -> None:
    out = tmp_path / "tiny"
    res = CliRunner().invoke(cli, ["collect", "--protocol", "paper", "--scale", "tiny", "--workers", "1",
                                   "--out", str(out)], env={"CTRKIN_NO_PROGRESS": "1"})
    assert res.exit_code == 0, res.output
    ds = Dataset.load(out)
    assert len(ds.frame) == 2 * 4 * 721          # as tests/evaluation/test_reproduce.py: 2 levels × 4 angles
    assert ds.meta["protocol_params"]["levels_mm"] == [4.0, 20.0]


class _Planned(Exception):
    def __init__(self, plan) -> None:
        self.plan = plan


def _collect_plan(scale: str, monkeypatch, tmp_path):
    """The plan `ctrkin collect --protocol paper --scale SCALE` records (the recording is skipped)."""
    import ctrkin.cli.collect as collect_module

    def planned(plan, *_a, **_k):
        raise _Planned(plan)

    monkeypatch.setattr(collect_module, "record", planned)
    res = CliRunner().invoke(cli, ["collect", "--protocol", "paper", "--scale", scale,
                                   "--out", str(tmp_path / scale)])
    assert isinstance(res.exception, _Planned), res.output
    return res.exception.plan


@pytest.mark.parametrize("scale", ["tiny", "quick", "full"])
def test_collect_records_what_reproduce_trains_on(scale, monkeypatch, tmp_path) -> None:
    """`collect --scale quick` recorded 8,652 samples while `reproduce --scale quick` trained on
    51,912 (issue 23): both now take the size from acquisition.protocols.PAPER_SIZES."""
    from ctrkin.acquisition import protocols
    from ctrkin.evaluation.scales import SCALES
    from ctrkin.robots import paper_robot

    plan = _collect_plan(scale, monkeypatch, tmp_path)
    repro = SCALES[scale]
    kw = {k: v for k, v in (("levels", repro.paper_levels), ("outer_step_deg", repro.paper_outer_step_deg))
          if v is not None}
    theirs = protocols.build("paper", paper_robot(), scale=repro.protocol_scale, **kw)  # type: ignore[arg-type]
    np.testing.assert_array_equal(plan.all_joints(), theirs.all_joints())
    assert plan.n_samples == theirs.n_samples == protocols.PAPER_SIZES[scale].n_samples()
    assert plan.n_samples == {"tiny": 5_768, "quick": 51_912, "full": 207_648}[scale]
