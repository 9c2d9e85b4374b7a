"""Issue 27, data loss and mixed reads at the folder level (items 1-3, 5, 7, 23, 24): public API
only, so that each test runs on the code before the fix too. Every path is built under tmp_path (and
HOME is pointed there where a test needs a home folder)."""

from __future__ import annotations

import multiprocessing
import os
import shutil
import stat
import time
import warnings
from pathlib import Path

import pandas as pd
import pytest

import ctrkin
from ctrkin.data import Dataset
from ctrkin.errors import CtrkinError, DatasetError
from tests.data.conftest import synthetic_frame

SPAWN = multiprocessing.get_context("spawn")    # no fork after threads (pyarrow, torch) were started


@pytest.fixture
def ds() -> Dataset:
    robot = ctrkin.paper_robot()
    return Dataset(frame=synthetic_frame(robot), robot=robot, meta={"protocol": "test"})


def _other(ds: Dataset, seed: int = 5) -> Dataset:
    return Dataset(frame=synthetic_frame(ds.robot, lengths=(7, 9), seed=seed), robot=ds.robot,
                   meta={"protocol": "other"})


def _same(a: pd.DataFrame, b: pd.DataFrame) -> bool:
    return a.shape == b.shape and bool((a.to_numpy() == b.to_numpy()).all())


def _load(folder: Path) -> pd.DataFrame:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Dataset.load(folder).frame


def test_saving_over_a_home_folder_is_refused_and_touches_nothing(tmp_path, monkeypatch, ds):
    """Item 1: `--out ~ --overwrite` moved the home folder aside and deleted it."""
    home = tmp_path / "home"
    home.mkdir()
    (home / ".bashrc").write_text("mine")
    monkeypatch.setenv("HOME", str(home))
    with pytest.raises(DatasetError, match="a home folder"):
        ds.save(home)
    assert sorted(p.name for p in home.iterdir()) == [".bashrc"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["home"]     # no build, no old copy


def test_a_symlinked_output_is_refused(tmp_path, ds):
    real = ds.save(tmp_path / "real")
    link = tmp_path / "link"
    link.symlink_to(real)
    with pytest.raises(DatasetError, match="symbolic link"):
        ds.save(link)
    assert link.is_symlink() and Dataset.load(real).frame.shape == ds.frame.shape


def test_task_path_and_dataset_do_not_replace_each_other(tmp_path, ds):
    """Item 5: `collect --protocol square --out <a dataset> --overwrite` left a folder that loaded as
    neither; and a failed task-path write left new targets beside old meta."""
    from ctrkin.acquisition.task_paths import TaskPath, load_targets
    from ctrkin.virtual import VirtualConfig, VirtualRobot

    folder = ds.save(tmp_path / "d")
    path = ctrkin.acquisition.task_paths.task_path(VirtualRobot(ctrkin.paper_robot(), VirtualConfig()),
                                                   "square")
    with pytest.raises(DatasetError, match="holds a ctrkin dataset, not a task path"):
        path.save(folder)
    assert Dataset.load(folder).frame.shape == ds.frame.shape
    sq = path.save(tmp_path / "sq")
    before = {p.name: p.read_bytes() for p in sq.iterdir()}

    broken = TaskPath(path.shape, path.poses + 1.0, path.corners, path.corner_joints,
                      {**path.meta, "bad": object()})                  # meta.json cannot be written
    with pytest.raises(TypeError):
        broken.save(sq)
    assert {p.name: p.read_bytes() for p in sq.iterdir()} == before     # the old folder, whole
    assert load_targets(sq)[0].shape == path.poses.shape
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d", "sq"]
    assert os.path.isdir(sq)


# --- item 2: a lock that cannot be redirected --------------------------------------------------------

def test_a_symlink_planted_at_the_lock_path_is_refused_and_its_target_untouched(tmp_path, ds):
    """Item 2: a symlink at `.NAME.lock` made ctrkin write its PID into the file it pointed to."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    (tmp_path / ".d.lock").symlink_to(victim)
    with pytest.raises(CtrkinError, match="symbolic link"):
        ds.save(tmp_path / "d")
    assert victim.read_text() == "precious" and not (tmp_path / "d").exists()


def test_a_hard_link_planted_at_the_lock_path_is_refused(tmp_path, ds):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    os.link(victim, tmp_path / ".d.lock")
    with pytest.raises(CtrkinError, match="not a lock file ctrkin made"):
        ds.save(tmp_path / "d")
    assert victim.read_text() == "precious"


# --- item 3: glob characters in names ----------------------------------------------------------------

def test_a_name_with_glob_characters_is_restored_after_a_kill_between_renames(tmp_path, ds):
    """Item 3: after a kill between the two renames, `exp[1]` was not restored (its old copy's name
    was read as a glob pattern)."""
    folder = ds.save(tmp_path / "exp[1]")
    folder.rename(tmp_path / ".exp[1].old-1a2b3c4d")
    assert _same(_load(folder), ds.frame)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exp[1]"]


def test_saving_a_glob_name_never_touches_the_copy_of_a_look_alike(tmp_path, ds):
    """Item 3: saving `exp[1]` while `exp1` was mid-swap deleted `exp1`'s only copy."""
    exp1 = ds.save(tmp_path / "exp1")
    exp1.rename(tmp_path / ".exp1.old-1a2b3c4d")              # exp1 killed between its renames
    _other(ds).save(tmp_path / "exp[1]")
    assert _same(_load(tmp_path / "exp[1]"), _other(ds).frame)
    assert _same(_load(exp1), ds.frame)                         # exp1's content is still there


# --- items 23, 24: leftovers of killed runs; permissions ---------------------------------------------

def test_leftovers_of_killed_writes_are_cleaned_by_the_next_write_and_read(tmp_path, ds):
    """Item 23: killed runs left `.NAME.xxxx` build folders that nothing cleaned."""
    folder = ds.save(tmp_path / "d")
    for name in (".d.tmp-0123456789abcdef", ".d.k2j4h5g6"):    # this version's and tempfile's names
        (tmp_path / name).mkdir()
        (tmp_path / name / "data.parquet").write_bytes(b"half")
    (tmp_path / ".d.old-00aa11bb").mkdir()                      # a superseded copy
    keep = [tmp_path / ".d.build", tmp_path / ".dx.tmp-0123456789abcdef", tmp_path / "e",
            tmp_path / ".d.backup01"]
    for p in keep:                     # train's resumable build; others'; the user's, named alike
        p.mkdir()
    (tmp_path / ".d.backup01" / "thesis.tex").write_text("mine")
    assert _same(_load(folder), ds.frame)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["d", *(p.name for p in keep)])
    (tmp_path / ".d.tmp-fedcba9876543210").mkdir()
    _other(ds).save(folder)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["d", *(p.name for p in keep)])


def test_datasets_and_model_folders_get_the_umask_permissions(tmp_path, ds):
    """Item 24: datasets were written readable by their owner only (0700), model folders 0755."""
    from ctrkin.training import TrainConfig, train
    from ctrkin.training.demo import sweep_dataset

    old = os.umask(0o022)
    try:
        folder = ds.save(tmp_path / "d")
        data = sweep_dataset(ds.robot, translations=(8, 16), outer_alphas=(0, 180), step_deg=12, seed=0)
        model = train(data, TrainConfig(task="fk", max_epochs=1, threads=1, options={"structure": "L4|D4"}),
                      tmp_path / "m", progress=False).out
    finally:
        os.umask(old)
    for p in (folder, model):
        assert stat.S_IMODE(p.stat().st_mode) == 0o755, p
    assert stat.S_IMODE((folder / "data.parquet").stat().st_mode) == 0o644


# --- item 7: concurrent readers and writers of one dataset -----------------------------------------

def _saver(folders: tuple[str, str, str], seconds: float, q) -> None:
    a, b = Dataset.load(folders[0]), Dataset.load(folders[1])
    failed = saves = 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            (a if saves % 2 else b).save(folders[2])
        except Exception:
            failed += 1
        saves += 1
    q.put(("saves", saves, failed))


def _loader(folders: tuple[str, str, str], seconds: float, q) -> None:
    frames = (Dataset.load(folders[0]).frame, Dataset.load(folders[1]).frame)
    loads = failed = mixed = 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            got = _load(Path(folders[2]))
            mixed += not any(_same(got, f) for f in frames)
        except Exception:
            failed += 1
        loads += 1
    q.put(("loads", loads, failed + mixed))


@pytest.mark.slow
def test_concurrent_saves_and_loads_of_one_dataset_never_fail_or_mix(tmp_path, ds):
    """Item 7: a dataset saved while other processes loaded it: some saves failed with
    FileNotFoundError (the new dataset discarded), some loads likewise. Readers see the old or the new
    dataset, never a mix or an error; writers never fail because of them."""
    a, b = ds.save(tmp_path / "a"), _other(ds).save(tmp_path / "b")
    shutil.copytree(a, tmp_path / "d")
    folders = (str(a), str(b), str(tmp_path / "d"))
    q = SPAWN.Queue()
    procs = [SPAWN.Process(target=_saver, args=(folders, 6.0, q)),
             *(SPAWN.Process(target=_loader, args=(folders, 6.0, q)) for _ in range(3))]
    for p in procs:
        p.start()
    results = [q.get(timeout=120) for _ in procs]
    for p in procs:
        p.join(timeout=60)
    saves = [r for r in results if r[0] == "saves"]
    loads = [r for r in results if r[0] == "loads"]
    assert saves[0][1] >= 10 and sum(r[1] for r in loads) >= 30, results
    assert saves[0][2] == 0 and all(r[2] == 0 for r in loads), results
