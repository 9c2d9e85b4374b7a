"""Folders written as one unit: lock, recovery, manifest, and kill tests (issue 9).

The kill tests start `ctrkin collect`, a dataset save and `ctrkin train --overwrite` in a (forked) process,
SIGKILL it at a seeded random moment of its work (10 trials each) and check that the folder then
holds the previous content or the new one, byte for byte, never a mix and never nothing; meanwhile
two reader processes load the folder over and over, and every read must give the previous content or
the new one, never an error (issue 27).
"""

from __future__ import annotations

import multiprocessing
import os
import shutil
import signal
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch._dynamo  # noqa: F401  (Adam imports it lazily, 3 s; imported once here, the forks share it)

import ctrkin.training  # noqa: F401
from ctrkin.cli.main import cli
from ctrkin.data import Dataset
from ctrkin.errors import CtrkinError, ModelError
from ctrkin.util.folders import check_manifest, folder_lock, recover, swap_in, write_manifest

TRIALS = 10
READERS = 2
FORK = multiprocessing.get_context("fork")   # children start without paying the imports again


def _cli(args: list[str]) -> None:
    os.environ["CTRKIN_NO_PROGRESS"] = "1"
    sys.stdout = sys.stderr = open(os.devnull, "w")
    cli.main(args, prog_name="ctrkin")


def _save(args: list[str]) -> None:
    Dataset.load(args[0]).save(args[1])


def _start(target, args: list[str]):
    p = FORK.Process(target=target, args=(args,))
    p.start()
    return p


def _timed(target, args: list[str]) -> float:
    """Seconds of one uninterrupted run."""
    t0 = time.perf_counter()
    p = _start(target, args)
    p.join(timeout=120)
    assert p.exitcode == 0, f"{args}: exit code {p.exitcode}"
    return time.perf_counter() - t0


def _reader(read, stop, q) -> None:
    """Call `read()` until `stop` is set; report (reads, failures and wrong answers, first problem)."""
    reads, bad, first = 0, 0, ""
    while not stop.is_set():
        try:
            ok = read()
        except Exception as e:  # every failure counts
            ok, first = False, first or f"{type(e).__name__}: {e}"
        bad += not ok
        first = first or ("" if ok else "content of neither version")
        reads += 1
    q.put((reads, bad, first))


def _kill_trials(target, args: list[str], work_s: float, seed: int, reset, check,
                 read=None) -> list[bool]:
    """Run `target(args)` TRIALS times in a forked child, each SIGKILLed after a seeded uniform delay in
    [0, 0.9 work_s] (or left to finish); `reset()` restores the previous content before each, `check()`
    judges the folder after. read: a reader (True if it read the old or the new version) run in
    READERS concurrent processes during each trial (issue 27: kill tests with concurrent readers);
    none of their reads may fail or see a mix."""
    rng = np.random.default_rng(seed)
    killed = []
    reads = 0
    for _ in range(TRIALS):
        reset()
        stop, q = FORK.Event(), FORK.Queue()
        readers = [FORK.Process(target=_reader, args=(read, stop, q)) for _ in range(READERS if read else 0)]
        for r in readers:
            r.start()
        p = _start(target, args)
        p.join(timeout=float(rng.uniform(0.0, 0.9 * work_s)))
        if p.is_alive():
            assert p.pid is not None
            os.kill(p.pid, signal.SIGKILL)
            p.join()
            killed.append(True)
        else:
            assert p.exitcode == 0, f"{args}: exit code {p.exitcode}"
            killed.append(False)
        stop.set()
        seen = [q.get(timeout=120) for _ in readers]
        for r in readers:
            r.join(timeout=60)
        assert all(bad == 0 for _, bad, _ in seen), seen
        reads += sum(n for n, _, _ in seen)
        check()
    assert reads >= TRIALS or not read, f"the readers read {reads} times"
    return killed


def _frame_of(folder: Path) -> pd.DataFrame:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # a recovered swap warns; recovery is what we test
        return Dataset.load(folder).frame


def _same(a: pd.DataFrame, b: pd.DataFrame) -> bool:
    return a.shape == b.shape and bool((a.to_numpy() == b.to_numpy()).all())


# --- units ------------------------------------------------------------------------------------------

def test_lock_refuses_a_second_writer_and_is_released(tmp_path):
    """A second writer (here another thread; the lock is re-entrant within one thread, so that a
    command can hold it from its first check to the library's save) is refused at once."""
    target = tmp_path / "m"
    errors: list[Exception] = []

    def second() -> None:
        try:
            with folder_lock(target, ModelError):
                pass
        except ModelError as e:
            errors.append(e)

    with folder_lock(target, ModelError):
        with folder_lock(target, ModelError):       # the same thread again: fine
            pass
        t = threading.Thread(target=second)
        t.start()
        t.join()
    assert len(errors) == 1 and f"pid {os.getpid()}" in str(errors[0])
    with folder_lock(target, ModelError):
        pass
    assert list(tmp_path.iterdir()) == []


def test_recover_and_swap(tmp_path):
    target, new = tmp_path / "d", tmp_path / ".d.build"
    new.mkdir()
    (new / "f").write_text("new")
    swap_in(new, target, CtrkinError)
    assert (target / "f").read_text() == "new" and recover(target) is None
    target.rename(tmp_path / ".d.old-00000000")
    assert "restored" in (recover(target) or "")
    assert (target / "f").read_text() == "new"


def test_manifest_detects_a_replaced_or_missing_file(tmp_path):
    (tmp_path / "a").write_text("1")
    (tmp_path / "b").write_text("2")
    write_manifest(tmp_path)
    check_manifest(tmp_path, ("a", "b"), ModelError)
    with pytest.raises(ModelError, match="does not list"):
        check_manifest(tmp_path, ("a", "c"), ModelError)
    (tmp_path / "b").write_text("3")
    with pytest.raises(ModelError, match="hash differs"):
        check_manifest(tmp_path, ("a",), ModelError)
    (tmp_path / "b").unlink()
    with pytest.raises(ModelError, match="lacks b"):
        check_manifest(tmp_path, ("a",), ModelError)


# --- kills --------------------------------------------------------------------------------------------

def _collect_args(seed: int, out: Path, overwrite: bool = False) -> list[str]:
    return ["collect", "--protocol", "random-points", "--n-points", "4", "--scale", "quick",
            "--workers", "1", "--seed", str(seed), "--out", str(out), *(["--overwrite"] if overwrite else [])]


@pytest.mark.slow
def test_kill_during_collect_leaves_old_or_new_dataset(tmp_path):
    old, new, out = tmp_path / "old", tmp_path / "new", tmp_path / "out"
    work = min(_timed(_cli, _collect_args(1, old)), _timed(_cli, _collect_args(2, new)))
    frames = (_frame_of(old), _frame_of(new))
    assert not _same(*frames)

    def reset():
        if out.exists():
            shutil.rmtree(out)
        shutil.copytree(old, out)

    def check():
        got = _frame_of(out)                     # never nothing: it loads
        assert any(_same(got, f) for f in frames), "the dataset is neither the previous nor the new one"

    def read() -> bool:
        got = _frame_of(out)
        return any(_same(got, f) for f in frames)

    killed = _kill_trials(_cli, _collect_args(2, out, overwrite=True), work, 11, reset, check, read)
    assert sum(killed) >= TRIALS // 2


@pytest.mark.slow
def test_kill_during_dataset_save_leaves_old_or_new_dataset(tmp_path):
    src = tmp_path / "src"
    _timed(_cli, _collect_args(3, src))
    base = _frame_of(src)
    parts = []
    for k in range(40):                          # a bigger frame, so the save takes a while
        part = base.copy()
        part["sequence_id"] += k * (int(base["sequence_id"].max()) + 1)
        parts.append(part)
    big = Dataset.load(src)
    big.frame = pd.concat(parts, ignore_index=True)
    new, old, out = tmp_path / "new", tmp_path / "old", tmp_path / "out"
    big.save(new)
    shutil.copytree(src, old)
    work = min(_timed(_save, [str(new), str(tmp_path / f"timing{k}")]) for k in range(2))
    frames = (_frame_of(old), _frame_of(new))

    def reset():
        if out.exists():
            shutil.rmtree(out)
        shutil.copytree(old, out)

    def check():
        got = _frame_of(out)
        assert any(_same(got, f) for f in frames), "the dataset is neither the previous nor the new one"

    def read() -> bool:
        got = _frame_of(out)
        return any(_same(got, f) for f in frames)

    killed = _kill_trials(_save, [str(new), str(out)], work, 12, reset, check, read)
    assert sum(killed) >= TRIALS // 2


@pytest.mark.slow
def test_kill_during_train_overwrite_leaves_old_or_new_model(tmp_path):
    from ctrkin.inference import Kinematics

    data = tmp_path / "data"
    _timed(_cli, _collect_args(4, data))

    def train_args(ib: int, out: Path, overwrite: bool) -> list[str]:
        return ["train", "--task", "fk", "--model", "lstm_mlp",
                "--data", str(data), "--out", str(out), "--structure", "L8|D8",
                "--epochs", "2", "--threads", "1", "--split", "random", "--ib", str(ib),
                *(["--overwrite"] if overwrite else [])]

    old, new, out = tmp_path / "old", tmp_path / "new", tmp_path / "out"
    work = min(_timed(_cli, train_args(2, old, False)), _timed(_cli, train_args(3, new, False)))
    weights = {2: (old / "weights.pt").read_bytes(), 3: (new / "weights.pt").read_bytes()}

    def reset():
        if out.exists():
            shutil.rmtree(out)
        shutil.copytree(old, out)

    def check():
        kin = Kinematics.load(out)               # never nothing, never files that do not belong together
        assert (out / "weights.pt").read_bytes() == weights[kin.ib], "weights of another training"

    probe = Dataset.load(data).joints()[:20]
    answers = {ib: Kinematics.load(p).predict(probe) for ib, p in ((2, old), (3, new))}

    def read() -> bool:
        kin = Kinematics.load(out)
        return bool(np.array_equal(kin.predict(probe), answers[kin.ib]))

    killed = _kill_trials(_cli, train_args(3, out, True), work, 13, reset, check, read)
    assert sum(killed) >= TRIALS // 2
