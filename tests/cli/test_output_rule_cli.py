"""Issue 27 at the command line (items 1, 5, 8, 17, 19): one meaning of --overwrite, refused outputs
and bad values as one line with one exit status per class (1 wrong input, 2 usage), never a
traceback. Every path is built under tmp_path; HOME and the working folder are pointed there."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.util.locks import lock_path

ENV = {"CTRKIN_NO_PROGRESS": "1"}


def _run(args: list[str], **kw) -> tuple[int, str]:
    res = CliRunner().invoke(cli, args, env=ENV, **kw)
    assert not (res.exception and not isinstance(res.exception, SystemExit)), \
        f"{args}: {type(res.exception).__name__}: {res.exception}"            # never a traceback
    return res.exit_code, res.output


def _collect(out: Path, *extra: str) -> tuple[int, str]:
    return _run(["collect", "--protocol", "random-points", "--n-points", "3", "--workers", "1",
                 "--out", str(out), *extra])


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("cli27") / "data"
    assert _collect(out)[0] == 0
    return out


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# --- item 1 and 17: what --overwrite may replace ------------------------------------------------------

def test_evaluate_into_the_home_folder_is_refused(tmp_path, monkeypatch, data):
    """Item 1: `ctrkin evaluate … --out ~ --overwrite` moved the home folder aside and deleted it."""
    home = tmp_path / "home"
    home.mkdir()
    (home / ".profile").write_text("mine")
    monkeypatch.setenv("HOME", str(home))
    code, out = _run(["evaluate", "--data", str(data), "--predictor", "tcm", "--out", str(home),
                      "--overwrite"])
    assert code == 1 and "home folder" in out, out
    assert _tree(home) == {".profile": b"mine"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["home"]


def test_train_never_replaces_its_own_input(tmp_path, data):
    """Item 1: `ctrkin train --data D --out D --overwrite` deleted the dataset it was reading."""
    d = tmp_path / "d"
    d.mkdir()
    for p in data.iterdir():
        (d / p.name).write_bytes(p.read_bytes())
    before = _tree(d)
    code, out = _run(["train", "--task", "fk", "--data", str(d), "--out", str(d), "--overwrite"])
    assert code == 1 and "is the input" in out, out
    assert _tree(d) == before


def test_the_working_folder_and_its_parent_are_never_outputs(tmp_path, monkeypatch):
    """Item 17: `--out .` crashed with a traceback and `--out "$PWD" --overwrite` emptied the working
    folder; item 19: `--out ..` was an OS error with a traceback."""
    work = tmp_path / "work"
    work.mkdir()
    (work / "keep.txt").write_text("mine")
    monkeypatch.chdir(work)
    for out, words in ((".", "the working folder"), (str(work), "the working folder"),
                       ("..", "a folder above the working folder")):
        for extra in ([], ["--overwrite"]):
            code, text = _run(["sweep", "--translations", "4", "--step", "90", "--out", out, *extra])
            assert code == 1 and words in text and text.count("\n") == 1, (out, text)
    assert _tree(work) == {"keep.txt": b"mine"} and sorted(os.listdir(tmp_path)) == ["work"]


def test_overwrite_has_one_meaning_for_every_command(tmp_path, data):
    """Item 17: --overwrite kept other files for sweep/collect but deleted them for evaluate/train.
    Now for every command: a ctrkin output of the same kind is replaced whole; one that also holds a
    file ctrkin did not write is refused, and the file kept."""
    cases = {
        "sweep": ["sweep", "--translations", "4", "--step", "90"],
        "collect": ["collect", "--protocol", "square"],
        "evaluate": ["evaluate", "--data", str(data), "--predictor", "tcm"],
        "train": ["train", "--task", "fk", "--data", str(data), "--structure", "L4|D4", "--epochs", "1",
                  "--threads", "1", "--split", "random"],
    }
    for name, args in cases.items():
        out = tmp_path / name
        assert _run([*args, "--out", str(out)])[0] == 0, name
        (out / "notes.txt").write_text("mine")
        code, text = _run([*args, "--out", str(out), "--overwrite"])
        assert code == 1 and "notes.txt, which ctrkin did not write" in text, (name, text)
        assert (out / "notes.txt").read_text() == "mine"
        (out / "notes.txt").unlink()
        code, text = _run([*args, "--out", str(out), "--overwrite"])
        assert code == 0, (name, text)


def test_an_output_of_another_kind_is_not_replaced(tmp_path, data):
    """Item 5: `collect --protocol square --out <a dataset> --overwrite` left a folder that loaded as
    neither a dataset nor a task path."""
    before = _tree(data)
    code, text = _run(["collect", "--protocol", "square", "--out", str(data), "--overwrite"])
    assert code == 1 and "not a task path" in text, text
    assert _tree(data) == before


# --- item 8: two writers ----------------------------------------------------------------------------

def test_two_collects_into_one_folder_one_is_refused(tmp_path):
    """Item 8: two `collect` runs into one --out started together; one replaced the other's recording.
    Now the second is refused at once (exit 1), the first's recording stands."""
    out = tmp_path / "out"
    env = {**os.environ, **ENV}
    cmd = [sys.executable, "-m", "ctrkin.cli.main", "collect", "--protocol", "random-points",
           "--n-points", "150", "--workers", "1", "--out", str(out)]
    first = subprocess.Popen([*cmd, "--seed", "1"], env=env, cwd=tmp_path, stderr=subprocess.PIPE,
                             text=True)
    # the second starts once the first holds the folder's writer lock (a loaded machine may take
    # seconds to import); the first then records for several seconds (150 points, one worker)
    deadline = time.monotonic() + 120
    while not lock_path(out).exists() and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    second = subprocess.Popen([*cmd, "--seed", "2"], env=env, cwd=tmp_path, stderr=subprocess.PIPE,
                              text=True)
    runs = [(p.wait(timeout=600), p.stderr.read() if p.stderr else "") for p in (first, second)]
    codes = sorted(c for c, _ in runs)
    assert codes == [0, 1], runs
    refused = next(err for c, err in runs if c == 1)
    assert "being written by another process" in refused and refused.count("\n") == 1
    seed = 1 if runs[0][0] == 0 else 2
    ref = tmp_path / "ref"
    assert _run(["collect", "--protocol", "random-points", "--n-points", "150", "--workers", "1",
                 "--seed", str(seed), "--out", str(ref)])[0] == 0
    got = pd.read_parquet(out / "data.parquet")
    want = pd.read_parquet(ref / "data.parquet")
    pd.testing.assert_frame_equal(got, want)


# --- item 17: values, exit statuses, split, reproduce -----------------------------------------------

def test_bad_values_are_usage_errors_not_tracebacks(tmp_path, data):
    """Item 17: tracebacks for --max-evaluations 0, --step 0, --n-points -3, square --n-points 1; and
    `--n-points 0` recorded 20 points."""
    cases = [
        ["calibrate", "--data", str(data), "--out", str(tmp_path / "c.toml"), "--max-evaluations", "0"],
        ["sweep", "--translations", "4", "--step", "0", "--out", str(tmp_path / "s")],
        ["collect", "--protocol", "random-points", "--n-points", "-3", "--out", str(tmp_path / "r")],
        ["collect", "--protocol", "random-points", "--n-points", "0", "--out", str(tmp_path / "r0")],
        ["collect", "--protocol", "square", "--n-points", "1", "--out", str(tmp_path / "sq")],
    ]
    for args in cases:
        code, text = _run(args)
        assert code == 2 and "Traceback" not in text, (args, text)
    assert sorted(os.listdir(tmp_path)) == []


def test_a_missing_input_exits_1_whatever_the_argument(tmp_path):
    """Item 17: a missing file exited 2 for some arguments and 1 for others."""
    gone = str(tmp_path / "gone")
    cases = [
        ["dataset", "info", gone], ["dataset", "split", gone],
        ["dataset", "import", gone + ".csv", "--out", str(tmp_path / "o")],
        ["train", "--task", "fk", "--data", gone, "--out", str(tmp_path / "m")],
        ["evaluate", "--data", gone, "--predictor", "tcm"],
        ["predict", gone, "--data", gone], ["export", gone, "--out", str(tmp_path / "x.onnx")],
        ["solve", "--robot", gone + ".toml", "--q", "0,0,-15,-5"],
    ]
    for args in cases:
        code, text = _run(args)
        assert code == 1 and text.startswith("Error:") and text.count("\n") == 1, (args, text)


def test_dataset_split_does_not_replace_a_saved_split_silently(tmp_path, data):
    """Item 17: `dataset split` replaced a saved split silently."""
    d = tmp_path / "d"
    d.mkdir()
    for p in data.iterdir():
        (d / p.name).write_bytes(p.read_bytes())
    assert _run(["dataset", "split", str(d), "--seed", "1"])[0] == 0
    saved = (d / "split.json").read_bytes()
    assert _run(["dataset", "split", str(d), "--seed", "1"])[0] == 0          # the same split: fine
    code, text = _run(["dataset", "split", str(d), "--kind", "random", "--seed", "2"])
    assert code == 1 and "--overwrite" in text, text
    assert (d / "split.json").read_bytes() == saved
    code, text = _run(["dataset", "split", str(d), "--kind", "random", "--seed", "2", "--overwrite"])
    assert code == 0 and (d / "split.json").read_bytes() != saved


def test_reproduce_refuses_a_folder_of_other_settings_before_any_work(tmp_path, monkeypatch, data):
    """Item 17: `reproduce --scale quick` into a tiny run's folder overwrote the data, then failed
    asking for --overwrite, which reproduce did not have."""
    import ctrkin.evaluation.reproduce as rep
    from ctrkin.evaluation.datasets import _key
    from ctrkin.evaluation.scales import get_scale

    def no_work(*_a, **_k):
        raise RuntimeError("reproduce started recording")

    monkeypatch.setattr(rep, "collect_training_data", no_work)
    out = tmp_path / "tiny_run"
    (out / "data").mkdir(parents=True)
    paper = out / "data" / "paper"
    for p in data.iterdir():
        paper.mkdir(exist_ok=True)
        (paper / p.name).write_bytes(p.read_bytes())
    meta = (paper / "meta.json").read_text()
    tiny = get_scale("tiny")
    kw = {"levels": tiny.paper_levels, "outer_step_deg": tiny.paper_outer_step_deg}
    key = _key("paper", tiny, 0, {k: v for k, v in kw.items() if v is not None})
    (paper / "meta.json").write_text(meta.replace('"protocol":', f'"reproduce_key": "{key}", "protocol":', 1))
    before = _tree(out)
    code, text = _run(["reproduce", "--scale", "quick", "--out", str(out)])
    assert code == 1 and "--overwrite" in text and "Traceback" not in text, text
    assert _tree(out) == before
    assert "--overwrite" in _run(["reproduce", "--help"])[1]


# --- item 19: the system's refusals -------------------------------------------------------------------

def test_a_full_disk_is_one_line_and_the_previous_dataset_stays(tmp_path, data):
    """Item 19: a full disk gave a traceback in 13 of 21 runs. The disk is filled by a file size
    limit (RLIMIT_FSIZE) on the child process: its writes beyond 16 KB fail with EFBIG."""
    out = tmp_path / "out"
    out.mkdir()
    for p in data.iterdir():
        (out / p.name).write_bytes(p.read_bytes())
    before = _tree(out)

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (16 << 10, 16 << 10))

    run = subprocess.run([sys.executable, "-m", "ctrkin.cli.main", "collect", "--protocol", "random-points",
                          "--n-points", "8", "--seed", "5", "--workers", "1", "--out", str(out),
                          "--overwrite"], env={**os.environ, **ENV}, cwd=tmp_path, capture_output=True,
                         text=True, timeout=600, preexec_fn=limit)
    assert run.returncode == 1, run.stderr
    assert run.stderr.startswith("Error: ") and len(run.stderr.strip().splitlines()) == 1, run.stderr
    assert "Traceback" not in run.stderr
    assert _tree(out) == before
    assert sorted(os.listdir(tmp_path)) == ["out"]                       # no build left behind
