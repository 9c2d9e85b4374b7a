"""What a reproduction is of: the virtual robot's effects (`--set`) are part of its settings, so a
rerun with others is refused and its data are not reused; the default keeps the keys of earlier
reproductions (their folders are still reused)."""

from __future__ import annotations

import json

import pytest

from ctrkin.errors import OutputError
from ctrkin.evaluation.datasets import paper_key, virtual_overrides
from ctrkin.evaluation.repro_folder import claim
from ctrkin.evaluation.scales import get_scale
from ctrkin.robots import load_robot
from ctrkin.util.ownership import read_marker
from ctrkin.virtual.config import VirtualConfig


def test_the_default_effects_keep_the_key_of_earlier_reproductions() -> None:
    tiny, paper = get_scale("tiny"), load_robot("paper")
    before = "paper|quick|0|[('levels', '(4.0, 20.0)'), ('outer_step_deg', '90.0')]"   # main 0a0854f
    assert paper_key(tiny, 0, paper) == paper_key(tiny, 0, paper, VirtualConfig()) == before
    assert paper_key(tiny, 0, paper, VirtualConfig(noise_mm=0.4)) == before         # the default value
    assert paper_key(tiny, 0, paper, VirtualConfig(noise_mm=0.1)) == before + "|[('noise_mm', '0.1')]"
    assert virtual_overrides(VirtualConfig(noise_mm=0.1, gear_backlash_deg=1.0)) == {
        "gear_backlash_deg": 1.0, "noise_mm": 0.1}
    timclab = load_robot("timclab")               # another robot: its own levels (the paper's carried over)
    assert "(77.33, 132.5)" in paper_key(tiny, 0, timclab)


def test_a_folder_of_other_effects_is_refused_and_the_same_effects_are_kept(tmp_path) -> None:
    out, robot, tiny = tmp_path / "repro", load_robot("paper"), get_scale("tiny")
    claim(out, robot, tiny, 0, False, VirtualConfig(noise_mm=0.1))
    (out / "data").mkdir()                                             # something a run left
    assert read_marker(out)["virtual_settings"] == {"noise_mm": 0.1}
    claim(out, robot, tiny, 0, False, VirtualConfig(noise_mm=0.1))     # the same settings: kept
    assert (out / "data").is_dir()
    with pytest.raises(OutputError, match=r"virtual robot noise_mm=0\.1"):
        claim(out, robot, tiny, 0, False, VirtualConfig())
    claim(out, robot, tiny, 0, True, VirtualConfig())                  # --overwrite replaces it
    assert not (out / "data").exists() and read_marker(out)["virtual_settings"] == {}


def test_a_folder_recorded_with_the_defaults_of_an_earlier_version_is_refused(tmp_path) -> None:
    """The marker keeps only what --set changed from the defaults of its time, and the defaults
    moved (issue 20: the top of the published ranges): the paper dataset's own configuration tells
    a folder of the former defaults from one of today's."""
    out, robot, tiny = tmp_path / "repro", load_robot("paper"), get_scale("tiny")
    claim(out, robot, tiny, 0, False)
    (out / "data" / "paper").mkdir(parents=True)
    meta = out / "data" / "paper" / "meta.json"
    meta.write_text(json.dumps({"virtual_robot": {"config": VirtualConfig().to_dict()}}))
    claim(out, robot, tiny, 0, False)                                   # today's defaults: kept
    meta.write_text(json.dumps({"virtual_robot": {"config": VirtualConfig().central().to_dict()}}))
    with pytest.raises(OutputError, match="defaults of an earlier version"):
        claim(out, robot, tiny, 0, False)
    claim(out, robot, tiny, 0, True)                                    # --overwrite replaces it
    assert not (out / "data").exists()


def test_a_folder_whose_recommended_models_trained_on_the_paper_protocol_alone_is_refused(tmp_path) -> None:
    """Before the excitation protocol the recommended models trained on the paper protocol only: a
    rerun would find models of other training data, so the folder is another reproduction."""
    from ctrkin.evaluation.repro_folder import TRAINING_DATA
    from ctrkin.util.ownership import write_marker

    out, robot, tiny = tmp_path / "repro", load_robot("paper"), get_scale("tiny")
    claim(out, robot, tiny, 0, False)
    assert read_marker(out)["training_data"] == TRAINING_DATA == "paper+excitation"
    claim(out, robot, tiny, 0, False)                                  # the same: kept
    skip = ("training_data", "kind", "ctrkin_version", "marker_version")
    marker = {k: v for k, v in read_marker(out).items() if k not in skip}
    write_marker(out, "reproduction", **marker)                        # as a reproduction before it
    (out / "data").mkdir()
    with pytest.raises(OutputError, match="recommended models trained on paper"):
        claim(out, robot, tiny, 0, False)
    claim(out, robot, tiny, 0, True)
    assert read_marker(out)["training_data"] == TRAINING_DATA
