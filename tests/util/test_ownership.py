"""Issue 27 items 1, 5, 17: only a ctrkin output of the same kind, holding nothing else, is ever
replaced; never `/`, a home folder, the working folder or a folder above it, nor an input. Every
path here is built under tmp_path (HOME is pointed there too)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import ctrkin
from ctrkin.data import Dataset
from ctrkin.errors import OutputError
from ctrkin.util.ownership import (
    MARKER,
    check_file_replaceable,
    check_not_input,
    check_replaceable,
    output_kind,
    protected_reason,
)
from tests.data.conftest import synthetic_frame


@pytest.fixture
def ds() -> Dataset:
    robot = ctrkin.paper_robot()
    return Dataset(frame=synthetic_frame(robot), robot=robot, meta={"protocol": "test"})


def test_working_folder_and_those_above_it_are_protected_even_when_empty(tmp_path, monkeypatch):
    work = tmp_path / "a" / "work"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    assert protected_reason(Path(".")) == "the working folder"
    assert protected_reason(work) == "the working folder"
    assert protected_reason(Path("..")) == "a folder above the working folder"
    assert protected_reason(tmp_path) == "a folder above the working folder"
    assert protected_reason(Path("/")) == "the root folder"
    assert protected_reason(work / "new") is None
    (tmp_path / "beside").mkdir()
    assert protected_reason(tmp_path / "beside") is None
    with pytest.raises(OutputError, match="the working folder"):
        check_replaceable(Path("."), "dataset", OutputError)


def test_only_a_ctrkin_output_of_the_same_kind_is_replaceable(tmp_path, ds):
    folder = ds.save(tmp_path / "d")
    assert json.loads((folder / MARKER).read_text())["kind"] == "dataset"
    check_replaceable(folder, "dataset", OutputError)                   # its own kind: fine
    with pytest.raises(OutputError, match="holds a ctrkin dataset, not a model"):
        check_replaceable(folder, "model", OutputError)
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("x")
    with pytest.raises(OutputError, match="is not a ctrkin output"):
        check_replaceable(mine, "dataset", OutputError)
    (folder / "notes.txt").write_text("mine")                           # something of the user's
    with pytest.raises(OutputError, match=r"notes\.txt, which ctrkin did not write"):
        check_replaceable(folder, "dataset", OutputError)
    empty = tmp_path / "empty"
    empty.mkdir()
    check_replaceable(empty, "dataset", OutputError)
    check_replaceable(tmp_path / "absent", "dataset", OutputError)


def test_a_dataset_of_ctrkin_before_the_marker_is_recognised(tmp_path, ds):
    folder = ds.save(tmp_path / "d")
    (folder / MARKER).unlink()                                          # as ctrkin 0.1 wrote it
    assert output_kind(folder) == "dataset"
    ds.save(folder)                                                     # replaced, now marked
    assert (folder / MARKER).is_file()


def test_an_output_may_not_be_an_input_inside_one_or_around_one(tmp_path):
    """Item 1: `train --data D --out D --overwrite` deleted the dataset it was reading."""
    data = tmp_path / "data"
    (data / "sub").mkdir(parents=True)
    for out, words in ((data, "is the input"), (data / "sub", "lies inside the input"),
                       (tmp_path, "holds the input"), (tmp_path / "." / "data", "is the input")):
        with pytest.raises(OutputError, match=words):
            check_not_input(out, [data], OutputError)
    alias = tmp_path / "alias"
    alias.symlink_to(data)                                              # another name, same folder
    with pytest.raises(OutputError, match="is the input"):
        check_not_input(alias, [data], OutputError)
    check_not_input(tmp_path / "beside", [data, None, "tcm"], OutputError)


def test_file_outputs_replace_only_ctrkin_files_of_their_kind(tmp_path):
    toml = tmp_path / "r.toml"
    ctrkin.paper_robot().to_toml(toml)
    check_file_replaceable(toml, "robot description", OutputError)
    notes = tmp_path / "notes.toml"
    notes.write_text("title = 'mine'\n")
    with pytest.raises(OutputError, match="not a robot description file ctrkin wrote"):
        check_file_replaceable(notes, "robot description", OutputError)
    with pytest.raises(OutputError, match="is a folder"):
        check_file_replaceable(tmp_path, "robot description", OutputError)
    link = tmp_path / "l.toml"
    link.symlink_to(toml)
    with pytest.raises(OutputError, match="symbolic link"):
        check_file_replaceable(link, "robot description", OutputError)
    csv = tmp_path / "p.csv"
    csv.write_text("sequence_id,step,pred_x\n0,0,1.0\n")
    check_file_replaceable(csv, "predictions", OutputError)
    other = tmp_path / "data.csv"
    other.write_text("a,b\n1,2\n")
    with pytest.raises(OutputError, match="not a predictions file"):
        check_file_replaceable(other, "predictions", OutputError)


def test_a_leftover_that_vanishes_while_it_is_judged_is_no_error(tmp_path):
    """Found by benchmarks/bench_folder_races.py: a reader judging a writer's build as a leftover met
    a FileNotFoundError when the writer removed it meanwhile."""
    from ctrkin.util.ownership import looks_like_output

    assert looks_like_output(tmp_path / "gone") is False
    (tmp_path / "b").mkdir()
    assert looks_like_output(tmp_path / "b") is True                   # empty: a build just begun
    (tmp_path / "b" / "thesis.tex").write_text("x")
    assert looks_like_output(tmp_path / "b") is False


def test_a_figure_is_replaced_only_if_it_is_a_picture_of_its_suffix(tmp_path):
    """`ctrkin show --out F.png|gif|mp4 --overwrite`: a data file named like a figure is kept."""
    png = tmp_path / "shape.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(32))
    check_file_replaceable(png, "figure", OutputError)
    gif = tmp_path / "a.gif"
    gif.write_bytes(b"GIF89a" + bytes(32))
    check_file_replaceable(gif, "figure", OutputError)
    mp4 = tmp_path / "a.mp4"
    mp4.write_bytes(b"\x00\x00\x00\x20ftypisom" + bytes(32))
    check_file_replaceable(mp4, "figure", OutputError)
    fake = tmp_path / "notes.png"
    fake.write_text("my notes\n")
    with pytest.raises(OutputError, match="not a figure file"):
        check_file_replaceable(fake, "figure", OutputError)
    swapped = tmp_path / "b.gif"
    swapped.write_bytes(png.read_bytes())
    with pytest.raises(OutputError, match="not a figure file"):
        check_file_replaceable(swapped, "figure", OutputError)


def test_an_evaluation_with_predictor_named_parts_is_one(tmp_path):
    """`evaluate` with several predictors writes one sub-folder per predictor, named after it."""
    ev = tmp_path / "eval"
    for sub in ("tcm", "fk_x", "tcm-2"):
        (ev / sub).mkdir(parents=True)
        (ev / sub / "results.json").write_text("{}")
    assert output_kind(ev) == "evaluation"
    check_replaceable(ev, "evaluation", OutputError)
    (ev / "mine").mkdir()                   # a folder of the user's, without results.json
    with pytest.raises(OutputError, match="mine"):
        check_replaceable(ev, "evaluation", OutputError)


def test_a_rig_collection_counts_its_journal_as_its_own(tmp_path, ds):
    """`collect --rig` keeps its journal beside the dataset; --overwrite may replace the whole."""
    out = tmp_path / "rig"
    ds.save(out)
    (out / "rig_session.json").write_text("{}")
    (out / "readings.csv").write_text("x\n")
    check_replaceable(out, "dataset", OutputError)
    (out / "rig_session.json").unlink()     # without a session, readings.csv is a user's file
    with pytest.raises(OutputError, match=r"readings\.csv"):
        check_replaceable(out, "dataset", OutputError)
