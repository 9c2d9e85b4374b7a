"""Model folders (issue 9 items 7, 10): built aside and swapped in, locked while training, resume keyed
on the split, loading refuses files that were not written together, byte-identical weights."""

from __future__ import annotations

import json
import shutil
import threading

import pytest

from ctrkin.data import Split
from ctrkin.errors import ModelError
from ctrkin.inference import Kinematics
from ctrkin.models.store import ModelBundle
from ctrkin.training import TrainConfig, train
from ctrkin.util.folders import folder_lock

SMALL = {"structure": "L16|D16"}


def _cfg(**kw):
    return TrainConfig(task="fk", max_epochs=1, patience=5, threads=1, options=SMALL, **kw)


def test_mixed_files_from_two_trainings_are_refused(quick_ds, tmp_path):
    """A kill during `train --overwrite` could leave new config and normalisation beside old weights,
    which loaded without error and predicted 1.9 mm off. Loading now checks the manifest."""
    train(quick_ds, _cfg(), tmp_path / "a", progress=False)
    train(quick_ds, _cfg(ib=3, split="random", split_seed=1, seed=2), tmp_path / "b", progress=False)
    Kinematics.load(tmp_path / "a")
    for name in ("normalization.json", "weights.pt", "features.json"):
        assert (tmp_path / "a" / name).read_bytes() != (tmp_path / "b" / name).read_bytes()
        mixed = tmp_path / f"mixed_{name}"
        shutil.copytree(tmp_path / "a", mixed)
        shutil.copy2(tmp_path / "b" / name, mixed / name)
        with pytest.raises(ModelError, match="not the file written with the rest"):
            Kinematics.load(mixed)
    bare = tmp_path / "bare"
    shutil.copytree(tmp_path / "a", bare)
    (bare / "manifest.json").unlink()
    with pytest.raises(ModelError, match=r"no manifest\.json"):
        ModelBundle.load(bare)


def test_overwrite_swaps_the_whole_folder(quick_ds, tmp_path):
    """The folder is replaced as a whole (a file the old model had and the new one does not write is
    gone); a file ctrkin did not write is never deleted: overwrite is refused until it is moved out
    (issue 27: one meaning of --overwrite, nothing of the user's lost)."""
    out = tmp_path / "m"
    train(quick_ds, _cfg(), out, progress=False)
    (out / "frame.json").write_text("{}")           # a model file the next model does not write
    (out / "notes.txt").write_text("mine")
    with pytest.raises(ModelError, match="notes.txt, which ctrkin did not write"):
        train(quick_ds, _cfg(ib=3), out, overwrite=True, progress=False)
    assert (out / "notes.txt").read_text() == "mine" and Kinematics.load(out).ib == 2
    (out / "notes.txt").unlink()
    train(quick_ds, _cfg(ib=3), out, overwrite=True, progress=False)
    assert not (out / "frame.json").exists()         # the folder was replaced, not written over
    assert Kinematics.load(out).ib == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m"]   # no build, old copy or lock left


def test_second_training_into_the_same_folder_is_refused(quick_ds, tmp_path):
    """Two trainings into one --out both exited 0 and one silently won. (The lock is held here by
    another thread: within one thread it is re-entrant.)"""
    out = tmp_path / "m"
    held, done = threading.Event(), threading.Event()

    def hold() -> None:
        with folder_lock(out, ModelError, "train"):
            held.set()
            done.wait(60)

    t = threading.Thread(target=hold)
    t.start()
    held.wait(60)
    try:
        with pytest.raises(ModelError, match="another process"):
            train(quick_ds, _cfg(), out, progress=False)
    finally:
        done.set()
        t.join()
    train(quick_ds, _cfg(), out, progress=False)     # the lock is released


def test_resume_refuses_a_changed_split(quick_ds, tmp_path):
    """Resume accepted a changed split.json: epochs trained on the old training rows leaked into the
    new test rows."""
    out = tmp_path / "m"
    ds = quick_ds
    old_split = ds.split
    try:
        ds.split = ds.get_split(seed=0)
        train(ds, _cfg(split="dataset"), out, progress=False)
        s = ds.split
        ds.split = Split(s.test, s.val, s.train, s.kind, s.seed, s.fractions, s.n_rows)
        with pytest.raises(ModelError, match="split differs"):
            train(ds, TrainConfig(task="fk", max_epochs=2, patience=5, threads=1, options=SMALL,
                                  split="dataset"), out, progress=False)
    finally:
        ds.split = old_split


def test_interrupted_build_resumes_and_old_model_survives(quick_ds, tmp_path):
    """A training killed mid-way leaves its checkpoint in .NAME.build and the previous model in
    place; running it again resumes from the build."""
    out = tmp_path / "m"
    train(quick_ds, _cfg(), out, progress=False)
    before = (out / "weights.pt").read_bytes()
    build = tmp_path / ".m.build"
    build.mkdir()
    shutil.copy2(out / "checkpoint.pt", build / "checkpoint.pt")    # as if killed after epoch 1 of 3
    Kinematics.load(out)
    assert (out / "weights.pt").read_bytes() == before
    res = train(quick_ds, TrainConfig(task="fk", max_epochs=3, patience=5, threads=1, options=SMALL),
                out, progress=False)
    assert [h["epoch"] for h in res.history] == [1, 2, 3] and not build.exists()


def test_seeded_training_saves_byte_identical_weights(quick_ds, tmp_path):
    """Seeded training gave bit-identical weights but byte-different weights.pt (the zip stored the
    random temp file name)."""
    train(quick_ds, _cfg(seed=3), tmp_path / "a", progress=False)
    train(quick_ds, _cfg(seed=3), tmp_path / "b", progress=False)
    for name in ("weights.pt", "normalization.json", "features.json", "robot.json", "split.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    hashes = [json.loads((tmp_path / m / "manifest.json").read_text())["files"]["weights.pt"] for m in "ab"]
    assert hashes[0] == hashes[1]
