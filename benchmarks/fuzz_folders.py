"""Areas of benchmarks/fuzz.py for the file system and concurrency (issue 27): what a second process, a
hostile folder or a full disk does to ctrkin's outputs.

    output        a command (sweep, collect square, dataset import, robot template) writing into a
                  drawn target: absent, empty, a folder of the user's, a fake home folder, the working
                  folder or the one above, the command's own input or the folder holding it, a ctrkin
                  output of another kind, of the same kind (clean or with a file of the user's), a
                  symbolic link to one, a plain file; with or without --overwrite. Oracle: exit 0 exactly
                  where the rule allows it (ctrkin.util.ownership), otherwise exit 1 and the target,
                  byte for byte, as it was; one line, never a traceback.
    fs            a dataset or model folder under adversity: a symbolic or hard link planted at the
                  lock's path, names with glob and odd characters (a save killed between its renames,
                  look-alike siblings mid-swap), leftovers of killed runs, a symlinked target, a
                  read-only parent, a full disk (RLIMIT_FSIZE in a forked child), a manifest naming
                  files outside its folder. Oracle: a clear refusal or the right content; the previous
                  content and everything outside the target intact.
    concurrency   one writer replacing a dataset or a model folder (alternately two versions) while
                  1-3 readers load it in threads. Oracle: every write succeeds, every read gives one
                  version or the other.

Outcomes beyond fuzz.py's: `lost` (content that was there before, or outside the target, changed or
vanished) and `mixed` (a read that gave neither version).
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import stat
import threading
import time
import uuid
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from click.testing import CliRunner

from ctrkin.cli.main import cli
from ctrkin.data import Dataset
from ctrkin.errors import CtrkinError, ModelError
from ctrkin.inference import Kinematics
from ctrkin.util.folders import folder_lock, swap_in


class Lost(Exception):
    """Content that was there before the call (or outside its target) changed or vanished."""


class Mixed(Exception):
    """A read gave content of neither version."""


class Crash(Exception):
    """A traceback or an unexpected exception where one line was due."""


class Silent(Exception):
    """A wrong answer without a flag (a write the rule forbids, or a refusal it does not call for)."""


ODD = ["exp[1]", "a*", "b?", "c d", "-dash", "ü€", "x.old-00000000", "'q'", "a..b", "[!x]", "{a,b}", "%s"]


def tree(folder: Path) -> dict[str, bytes | str]:
    """Everything under `folder` (links as their target), to compare before and after."""
    out: dict[str, bytes | str] = {}
    if not os.path.lexists(folder):
        return out
    if os.path.islink(folder) or folder.is_file():
        return {".": os.readlink(folder) if os.path.islink(folder) else folder.read_bytes()}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = Path(root) / name
            rel = str(p.relative_to(folder))
            if p.is_symlink():
                out[rel] = "->" + os.readlink(p)
            elif p.is_file():
                out[rel] = p.read_bytes()
            else:
                out[rel] = "/"
    return out


def fresh(ctx: dict[str, Any], name: str) -> Path:
    """An empty scratch folder for one input."""
    d = Path(ctx["tmp"]) / "fs" / name
    if d.exists():
        for p in d.rglob("*"):          # undo read-only folders of an earlier input
            if p.is_dir() and not p.is_symlink():
                p.chmod(0o755)
        d.chmod(0o755)
        shutil.rmtree(d)
    d.mkdir(parents=True)
    return d


def _same(a: Any, b: Any) -> bool:
    return a.shape == b.shape and bool((a.to_numpy() == b.to_numpy()).all())


def _load(folder: Path) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Dataset.load(folder).frame


# --- output: the --overwrite rule --------------------------------------------------------------------

COMMANDS = {
    "sweep": (["sweep", "--translations", "4", "--step", "90"], "folder"),
    "square": (["collect", "--protocol", "square"], "folder"),
    "import": (["dataset", "import", "{log}"], "folder"),
    "template": (["robot", "template"], "file"),
}
TARGETS = ("absent", "empty", "user", "home", "cwd", "parent", "input", "holds-input", "other-kind",
           "own", "own+user", "link-to-own", "file")


def _make_own(command: str, path: Path, ctx: dict[str, Any]) -> None:
    args, _ = COMMANDS[command]
    code, out = invoke([*_expand(args, ctx), "--out", str(path)])
    if code != 0:
        raise RuntimeError(f"could not make the {command} output: {out}")


def _expand(args: list[str], ctx: dict[str, Any]) -> list[str]:
    return [a.replace("{log}", str(ctx["log_file"])) for a in args]


def invoke(args: list[str], env: dict[str, str] | None = None) -> tuple[int, str]:
    res = CliRunner().invoke(cli, args, env={"CTRKIN_NO_PROGRESS": "1", **(env or {})})
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise Crash(f"{' '.join(args[:3])}: {type(res.exception).__name__}: {res.exception}")
    return res.exit_code, res.output


def case_output(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    command = str(rng.choice(list(COMMANDS)))
    target = str(rng.choice(TARGETS))
    overwrite = bool(rng.random() < 0.6)
    base = fresh(ctx, "output")
    work = base / "work"
    work.mkdir()
    home = base / "home"
    home.mkdir()
    (home / ".profile").write_text("mine")
    log = base / "logs" / "log.csv"
    log.parent.mkdir()
    shutil.copy2(ctx["log_file"], log)
    local = {**ctx, "log_file": log}
    args, shape = COMMANDS[command]
    other = "square" if command != "square" else "sweep"
    out = base / "out"
    folder = shape == "folder"
    if target == "empty":
        out.mkdir()
    elif target == "user":
        out.mkdir()
        (out / "thesis.tex").write_text("mine")
    elif target == "home":
        out = home
    elif target == "cwd":
        out = work
    elif target == "parent":
        out = base
    elif target == "input":
        out = log                       # the command's input (import) or a file of the user's
    elif target == "holds-input":
        out = log.parent
    elif target == "other-kind":
        _make_own(other if folder else "sweep", out, local)
    elif target in ("own", "own+user"):
        _make_own(command, out, local)
        if target == "own+user" and folder:
            (out / "notes.txt").write_text("mine")
        elif target == "own+user":      # a file of ours the user edited: still ours to replace
            with open(out, "a") as f:
                f.write("# my note\n")
    elif target == "link-to-own":
        _make_own(command, base / "real", local)
        out.symlink_to(base / "real")
    elif target == "file":
        out.write_text("my notes\n")
    allowed = (target == "absent" or (target == "empty" and folder)
               or (overwrite and (target == "own" or (target == "own+user" and not folder))))
    before = tree(base)
    cwd = os.getcwd()
    os.chdir(work)
    try:
        flags = ["--overwrite"] if overwrite else []
        code, text = invoke([*_expand(args, local), "--out", str(out), *flags], env={"HOME": str(home)})
    finally:
        os.chdir(cwd)
    if code not in (0, 1) or (code == 1 and (not text.startswith("Error: ") or text.count("\n") != 1)):
        raise Crash(f"{command} into {target}: exit {code}: {text[:200]}")
    after = tree(base)
    if code == 1:
        if after != before:
            raise Lost(f"{command} into {target} (overwrite={overwrite}) refused but changed files")
        if allowed:
            raise Silent(f"{command} into {target} (overwrite={overwrite}) refused: {text.strip()[:160]}")
        return "clear"
    if not allowed:
        raise Lost(f"{command} wrote into {target} (overwrite={overwrite}), which the rule forbids")
    kept = {k: v for k, v in before.items() if not k.startswith("out")}
    if {k: v for k, v in after.items() if not k.startswith("out")} != kept:
        raise Lost(f"{command} into {target} changed files outside its output")
    return "ok"


# --- fs: adversity at the folder level ----------------------------------------------------------------

def _forked(fn: Any, nobody: bool = False, limit_bytes: int | None = None, timeout: float = 60.0) -> str:
    """fn() in a forked child, as user nobody (root ignores permissions) and/or with files limited to
    limit_bytes (a full disk); its outcome string, "hang:..." if it does not finish in `timeout`."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(r)
        try:
            if limit_bytes is not None:
                resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
            if nobody:
                os.setgid(65534)
                os.setuid(65534)
            res = fn()
        except BaseException as e:
            res = f"crash:{type(e).__name__}: {e}"[:500]
        os.write(w, res.encode()[:4000])
        os._exit(0)
    os.close(w)
    deadline = time.monotonic() + timeout
    while os.waitpid(pid, os.WNOHANG)[0] == 0:
        if time.monotonic() > deadline:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
            os.close(r)
            return f"hang:killed after {timeout:g} s"
        time.sleep(0.005)
    data = os.read(r, 4096).decode()
    os.close(r)
    return data or "crash:the child died"


def _cli_outcome(args: list[str]) -> str:
    try:
        code, text = invoke(args)
    except Crash as e:
        return f"crash:{e}"
    if code == 1 and text.startswith("Error: ") and text.count("\n") == 1:
        return "clear"
    return "ok" if code == 0 else f"crash:exit {code}: {text[:200]}"


def case_fs(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    base = fresh(ctx, "adversity")
    a: Dataset = ctx["dataset"]
    b: Dataset = ctx["dataset_b"]
    kind = int(rng.integers(8))
    name = str(rng.choice(ODD)) + (str(rng.integers(100)) if rng.random() < 0.5 else "")
    target = base / name
    victim = base / "victim.txt"
    victim.write_text("precious")
    outcome = "ok"
    if kind in (0, 1):                                  # a link planted at the lock's path
        lock = base / f".{name}.lock"
        lock.symlink_to(victim) if kind == 0 else os.link(victim, lock)
        try:
            a.save(target)
            outcome = "silent"
        except CtrkinError:
            outcome = "clear"
        if victim.read_text() != "precious":
            raise Lost("a planted lock link redirected ctrkin's write")
        if outcome == "silent":
            raise Silent("a save went ahead through a planted link at its lock path")
        return outcome
    if kind == 2:                                       # killed between renames, look-alikes mid-swap
        a.save(target)
        target.rename(base / f".{name}.old-0a1b2c3d")
        look = base / (name.replace("[", "").replace("]", "").replace("*", "x").replace("?", "y") + "z")
        b.save(look)
        look.rename(base / f".{look.name}.old-4e5f6a7b")
        if not _same(_load(target), a.frame):
            raise Lost(f"{name!r}: the previous dataset was not restored after a killed swap")
        b.save(target)
        if not _same(_load(look), b.frame):
            raise Lost(f"saving {name!r} touched the copy of {look.name!r}")
        return "ok"
    if kind == 3:                                       # leftovers of killed runs
        a.save(target)
        for junk in (f".{name}.tmp-{uuid.uuid4().hex[:16]}", f".{name}.k3j4h5g6"):
            (base / junk).mkdir()
        others = [base / f".{name}x.tmp-0123456789abcdef", base / f".{name}.build"]
        for p in others:
            p.mkdir()
        if not _same(_load(target), a.frame):
            raise Lost("a dataset with leftovers beside it loaded other content")
        left = sorted(p.name for p in base.iterdir())
        want = sorted([name, "victim.txt", *(p.name for p in others)])
        if left != want:
            raise Silent(f"leftovers not cleaned or others' folders touched: {left}")
        return "ok"
    if kind == 4:                                       # a symlinked target
        real = a.save(base / "real")
        before = tree(real)
        target.symlink_to(real)
        try:
            b.save(target)
            outcome = "silent"
        except CtrkinError:
            outcome = "clear"
        if tree(real) != before or not target.is_symlink():
            raise Lost("saving to a symbolic link changed the folder it points to or the link")
        if outcome == "silent":
            raise Silent("a save replaced a symbolic link")
        return outcome
    if kind == 5:                                       # a read-only parent
        a.save(target)
        before = tree(base)
        for p in [base, *base.rglob("*")]:
            if p.is_dir() and not p.is_symlink():
                os.chmod(p, 0o755)
            elif not p.is_symlink():
                os.chmod(p, 0o644)
        os.chmod(base.parent, 0o777)
        base.chmod(0o555)
        args = ["collect", "--protocol", "square", "--out", str(target), "--overwrite"]
        root = os.geteuid() == 0
        res = _forked(lambda: _cli_outcome(args), nobody=True) if root else _cli_outcome(args)
        reader = _forked(lambda: "ok" if _same(_load(target), a.frame) else "mixed", nobody=root)
        base.chmod(0o755)
        if tree(base) != before:
            raise Lost("a write into a read-only folder changed it")
        if reader != "ok":
            _outcome(reader)
            raise Mixed("a dataset in a read-only folder loaded other content")
        return _outcome(res)
    if kind == 6:                                       # a full disk
        a.save(target)
        before = tree(base)
        limit = int(rng.integers(0, 20_000))
        res = _forked(lambda: _cli_outcome(["collect", "--protocol", "random-points", "--n-points", "3",
                                            "--workers", "1", "--seed", "9", "--out", str(target),
                                            "--overwrite"]), limit_bytes=limit)
        after = tree(base)
        if res == "ok":                                 # the limit was enough: the new dataset
            return "ok" if not _same(_load(target), a.frame) else "silent"
        if after != before:
            raise Lost(f"a full disk (limit {limit} B) changed the previous dataset or left files")
        return _outcome(res)
    model = base / "model"                              # a manifest naming files outside its folder
    shutil.copytree(ctx["fk_dir"], model)
    man = json.loads((model / "manifest.json").read_text())
    escape = str(rng.choice(["../victim.txt", str(victim), "sub/../../victim.txt", "link"]))
    if escape == "link":
        (model / "link").symlink_to(victim)
    from ctrkin.util.folders import file_hash

    man["files"][escape] = file_hash(victim)
    (model / "manifest.json").write_text(json.dumps(man))
    try:
        Kinematics.load(model)
    except CtrkinError:
        return "clear"
    raise Silent(f"a manifest naming {escape!r} loaded")


class Hang(Exception):
    pass


def _outcome(res: str) -> str:
    if res.startswith("crash:"):
        raise Crash(res[6:])
    if res.startswith("hang:"):
        raise Hang(res[5:])
    return res


# --- concurrency ---------------------------------------------------------------------------------------

def case_concurrency(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    base = fresh(ctx, "concurrency")
    models = rng.random() < 0.4
    readers = int(rng.integers(1, 4))
    seconds = float(rng.uniform(0.3, 1.0))
    target = base / "t"
    if models:
        versions = [Path(ctx["fk_dir"]), Path(ctx["fk_other_dir"])]
        probe = ctx["fk_probe"]
        answers = [Kinematics.load(v).predict(probe) for v in versions]
        shutil.copytree(versions[0], target)

        def write(k: int) -> None:
            with folder_lock(target, ModelError):
                build = target.with_name(f".{target.name}.tmp-{uuid.uuid4().hex[:16]}")
                shutil.copytree(versions[k % 2], build)
                swap_in(build, target, ModelError)

        def read() -> bool:
            got = Kinematics.load(target).predict(probe)
            return any(np.array_equal(got, x) for x in answers)
    else:
        sets = [ctx["dataset"], ctx["dataset_b"]]
        sets[0].save(target)

        def write(k: int) -> None:
            sets[k % 2].save(target)

        def read() -> bool:
            got = _load(target)
            return any(_same(got, s.frame) for s in sets)

    stop = threading.Event()
    problems: list[str] = []
    counts = [0, 0]

    def reader() -> None:
        while not stop.is_set():
            try:
                if not read():
                    problems.append("mixed")
            except Exception as e:  # every failure counts
                problems.append(f"{type(e).__name__}: {e}")
            counts[1] += 1

    threads = [threading.Thread(target=reader) for _ in range(readers)]
    for t in threads:
        t.start()
    end = time.monotonic() + seconds
    failures: list[str] = []
    try:
        while time.monotonic() < end:
            try:
                write(counts[0] + 1)
            except Exception as e:  # every failure counts
                failures.append(f"{type(e).__name__}: {e}")
            counts[0] += 1
    finally:
        stop.set()
        for t in threads:
            t.join()
    if failures:
        raise Lost(f"{len(failures)} of {counts[0]} writes failed with readers present: {failures[0][:160]}")
    if "mixed" in problems:
        raise Mixed(f"{problems.count('mixed')} of {counts[1]} reads gave neither version")
    if problems:
        raise Crash(f"{len(problems)} of {counts[1]} reads failed: {problems[0][:160]}")
    return "ok"


def setup(ctx: dict[str, Any], seed: int) -> None:
    """What these areas need beside fuzz.setup's: a second dataset and the CSV log as a file."""
    from ctrkin.training.demo import sweep_dataset

    tmp = Path(ctx["tmp"])
    b = sweep_dataset(ctx["robot"], translations=(12,), outer_alphas=(0, 90), step_deg=10, noise_mm=0.02,
                      seed=seed + 1)
    b.save(tmp / "dataset_b")
    ctx["dataset_b"] = Dataset.load(tmp / "dataset_b")
    ctx["log_file"] = tmp / "output_log.csv"      # not log.csv: case_csv rewrites that one
    ctx["log"].to_csv(ctx["log_file"], index=False)
    os.chmod(tmp, stat.S_IRWXU | stat.S_IRGRP | stat.S_IXGRP | stat.S_IROTH | stat.S_IXOTH)


CASES = {"output": case_output, "fs": case_fs, "concurrency": case_concurrency}
COUNTS = {"output": 400, "fs": 200, "concurrency": 40}    # inputs at scale 1
