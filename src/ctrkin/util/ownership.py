"""What ctrkin may replace: only a folder it wrote, of the same kind, holding nothing else.

Every output folder carries a marker, `ctrkin-output.json` ({"kind": ..., "ctrkin_version": ...}),
written into the build before it is swapped in (ctrkin.util.folders). A folder is replaced (by
`--overwrite`, or by the library's own save of the same kind) only if

- it is not `/`, a home folder, the working folder or one of its parents (whatever it holds);
- it is a ctrkin output of the same kind: its marker says so, or, for folders of ctrkin before 0.2
  (no marker), its content is recognised (a dataset by meta.json's format_version beside
  data.parquet, a model by config.json's "train" entry, a task path by meta.json's kind, a sweep,
  evaluation or reproduction by their result files);
- it holds nothing but what ctrkin writes there for that kind (so nothing of the user's is lost:
  a folder with other files is refused, and they are named);
- and it is not an input of the same command, nor inside one, nor holding one (checked by the
  command: `check_not_input`).

Otherwise the write is refused with one line saying why, before anything is touched.
"""

from __future__ import annotations

import json
import os
import pwd
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

MARKER = "ctrkin-output.json"
MARKER_VERSION = 1


def _json(path: Path) -> Any:
    try:
        with open(path, "rb") as f:
            return json.loads(f.read(1 << 20))
    except (OSError, ValueError):
        return None


def _has(folder: Path, *names: str) -> bool:
    return all(os.path.isfile(folder / n) for n in names)


def _meta_key(folder: Path, key: str) -> Any:
    meta = _json(folder / "meta.json")
    return meta.get(key) if isinstance(meta, dict) else None


def _is_model(folder: Path) -> bool:
    cfg = _json(folder / "config.json")
    return isinstance(cfg, dict) and "train" in cfg


def _model_names(folder: Path) -> set[str]:
    listed = _json(folder / "manifest.json")
    files = listed.get("files") if isinstance(listed, dict) else None
    return {str(k) for k in files} if isinstance(files, dict) else set()


@dataclass(frozen=True)
class Kind:
    """A kind of output folder: what it is called, the names ctrkin writes in it (regular
    expressions on the entry names), and how a folder of ctrkin before 0.2 (no marker) is recognised."""

    name: str
    own: tuple[str, ...]
    legacy: Callable[[Path], bool]
    more_own: Callable[[Path], set[str]] = lambda _f: set()


RIG_JOURNAL = ("rig_session.json", "readings.csv")   # acquisition.rig_recorder's SESSION_FILE, LOG_FILE


def _rig_journal(folder: Path) -> set[str]:
    """A dataset recorded on a rig (`collect --rig`) also holds its journal, from which it resumes."""
    return set(RIG_JOURNAL) if (folder / RIG_JOURNAL[0]).is_file() else set()


_EVAL_FILES = ("results.json", "tips.png", "error_vs_joints.png", "error_by_sequence.png")


def _evaluation_parts(folder: Path) -> set[str]:
    """The sub-folders of an evaluation of several predictors (named after them: `tcm`, `fk_x`,
    `tcm-2`; numbered before 0.2): each holds its own results.json."""
    try:
        return {e.name for e in os.scandir(folder)
                if e.is_dir(follow_symlinks=False) and os.path.isfile(os.path.join(e.path, "results.json"))}
    except OSError:
        return set()
KINDS: dict[str, Kind] = {k.name: k for k in [
    Kind("dataset", ("data.parquet", "meta.json", "split.json"),
         lambda f: _has(f, "data.parquet", "meta.json") and _meta_key(f, "format_version") is not None,
         _rig_journal),
    Kind("task path", ("targets.csv", "meta.json"),
         lambda f: _has(f, "targets.csv", "meta.json") and _meta_key(f, "kind") == "task_path"),
    Kind("model", ("config.json", "features.json", "normalization.json", "robot.json", "weights.pt",
                   "split.json", "metrics.json", "history.csv", "curves.png", "workspace.npz",
                   "frame.json", "fold_gate.json", "tcm_prior.toml", "checkpoint.pt", "manifest.json",
                   "refine.json", "fk"),
         _is_model, _model_names),
    Kind("sweep", ("sweep.csv", "sweep.png"), lambda f: _has(f, "sweep.csv")),
    Kind("plan", ("plan.csv", "plan.json", "plan.png"), lambda f: _has(f, "plan.csv", "plan.json")),
    Kind("reproduction", ("report.md", "results.json", "data", "models", "figures"),
         lambda f: _has(f, "results.json", "report.md") or (f / "data" / "paper").is_dir()),
    Kind("evaluation", (*_EVAL_FILES, r"\d+"),
         lambda f: _has(f, "results.json") or bool(_evaluation_parts(f)), _evaluation_parts),
]}


def write_marker(folder: Path, kind: str, **extra: object) -> None:
    """Mark `folder` as a ctrkin output of `kind` (extra: settings to keep with it)."""
    from ctrkin.version import __version__

    if kind not in KINDS:
        raise ValueError(f"unknown output kind {kind!r}")
    blob = {"kind": kind, "ctrkin_version": __version__, "marker_version": MARKER_VERSION, **extra}
    (folder / MARKER).write_text(json.dumps(blob, indent=2, default=str))


def read_marker(folder: Path) -> dict[str, Any] | None:
    """The marker of `folder` (None if it has none that reads as one)."""
    blob = _json(folder / MARKER)
    return blob if isinstance(blob, dict) and isinstance(blob.get("kind"), str) else None


def output_kind(folder: Path) -> str | None:
    """The kind of ctrkin output `folder` is (marker, else recognised content), or None."""
    marker = read_marker(folder)
    if marker is not None:
        return str(marker["kind"])
    for kind in KINDS.values():
        if kind.legacy(folder):
            return kind.name
    return None


def foreign_entries(folder: Path, kind: str) -> list[str]:
    """Entries of `folder` that ctrkin does not write for `kind` (sorted)."""
    names = os.listdir(folder)
    mine = _own_names(folder, kind, names)
    return sorted(n for n in names if n not in mine)


def looks_like_output(folder: Path) -> bool:
    """Whether `folder` holds nothing but what ctrkin writes into some kind of output (or nothing):
    the test a leftover build must pass before it is removed."""
    try:
        names = os.listdir(folder)
        return any(not [n for n in names if n not in _own_names(folder, k, names)] for k in KINDS)
    except OSError:         # gone meanwhile (a writer's own build, removed)
        return False


def _own_names(folder: Path, kind: str, names: list[str]) -> set[str]:
    """Those of `names` (the entries of `folder`) that ctrkin writes into an output of `kind`."""
    k = KINDS[kind]
    own = re.compile("|".join([re.escape(MARKER), *k.own]))
    return {n for n in names if own.fullmatch(n)} | k.more_own(folder)


def _identity(path: str | Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _ancestry(path: str | Path) -> list[tuple[int, int]]:
    """Identities (device, inode) of `path` (resolved) and of every folder above it that exists."""
    out = []
    p = Path(os.path.realpath(path))
    for q in [p, *p.parents]:
        ident = _identity(q)
        if ident is not None:
            out.append(ident)
    return out


def _homes() -> set[tuple[int, int]]:
    places = [os.path.expanduser("~"), os.environ.get("HOME", "")]
    try:
        places += [pw.pw_dir for pw in pwd.getpwall()]
    except OSError:
        pass
    return {i for i in (_identity(p) for p in places if p) if i is not None}


def protected_reason(path: str | Path) -> str | None:
    """Why `path` may never be written as an output folder (None if it may): the root, a home
    folder, the working folder or a folder above it."""
    ident = _identity(path)
    if ident is None:
        return None
    if os.path.realpath(path) == "/":
        return "the root folder"
    if ident in _homes():
        return "a home folder"
    try:
        cwd = _ancestry(os.getcwd())
    except OSError:
        cwd = []
    if cwd and ident == cwd[0]:
        return "the working folder"
    if ident in cwd:
        return "a folder above the working folder"
    return None


def check_replaceable(folder: Path, kind: str, error: type[Exception]) -> None:
    """Refuse (`error`, nothing touched) to replace `folder` unless it is absent, empty, or a ctrkin
    output of `kind` holding nothing else (module docstring). Protected places are refused even
    when empty."""
    reason = protected_reason(folder)
    if reason is not None:
        raise error(f"{folder} is {reason}: ctrkin never writes an output there; name a new "
                    "sub-folder as --out")
    if not os.path.lexists(folder):
        return
    if os.path.islink(folder):
        raise error(f"{folder} is a symbolic link: name the folder itself as --out (ctrkin replaces "
                    "folders it wrote, not links)")
    if not folder.is_dir():
        raise error(f"{folder} exists and is not a folder")
    try:
        empty = not os.listdir(folder)
    except OSError as e:
        raise error(f"{folder} cannot be read ({e.strerror}): ctrkin replaces only folders it "
                    "can check") from None
    if empty:
        return
    found = output_kind(folder)
    if found is None:
        raise error(f"{folder} is not a ctrkin output (no {MARKER}, and not recognised as one): "
                    "ctrkin replaces only folders it wrote; choose another --out, or move it away "
                    "yourself")
    if found != kind:
        raise error(f"{folder} holds a ctrkin {found}, not a {kind}: ctrkin replaces an output only "
                    "by one of the same kind; choose another --out")
    foreign = foreign_entries(folder, kind)
    if foreign:
        shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
        raise error(f"{folder} is a ctrkin {kind} but also holds {shown}, which ctrkin did not write: "
                    "replacing it would lose them; move them out or choose another --out")


def check_not_input(out: str | Path, inputs: Iterable[str | Path | None], error: type[Exception]
                    ) -> None:
    """Refuse an output that is an input of the same command, lies inside one or holds one
    (resolved paths and inode identities, both ways)."""
    out_up = _ancestry(out)
    out_id = _identity(out)
    for inp in inputs:
        if inp is None:
            continue
        in_id = _identity(inp)
        if in_id is None:
            continue
        if out_id == in_id:
            raise error(f"--out {out} is the input {inp} of this command: choose another --out")
        if in_id in out_up:
            raise error(f"--out {out} lies inside the input {inp} of this command: choose a folder "
                        "outside it")
        if out_id is not None and out_id in _ancestry(inp):
            raise error(f"--out {out} holds the input {inp} of this command: replacing it would "
                        "lose the input; choose another --out")


def _tail(path: Path, size: int = 1 << 20) -> bytes:
    with open(path, "rb") as f:
        f.seek(max(0, os.fstat(f.fileno()).st_size - size))
        return f.read()


def _is_predictions(path: Path) -> bool:
    """A table `ctrkin predict` wrote: csv, json or parquet with pred_* columns."""
    if path.suffix.lower() == ".parquet":
        try:
            import pyarrow.parquet as pq

            return any(n.startswith("pred_") for n in pq.read_schema(path).names)
        except Exception:  # pyarrow raises many types for a file that is not parquet
            return False
    with open(path, "rb") as f:
        head = f.read(1 << 16)
    return b"pred_" in head


def _is_onnx(path: Path) -> bool:
    """An ONNX file `ctrkin export` wrote (its metadata names ctrkin.task, after the graph)."""
    return b"ctrkin.task" in _tail(path)


def _is_robot(path: Path) -> bool:
    """A robot description (TOML with a tubes list), as `ctrkin calibrate` and `robot template` write."""
    import tomllib

    try:
        with open(path, "rb") as f:
            d = tomllib.loads(f.read(1 << 20).decode())
    except (OSError, ValueError, RecursionError):
        return False
    return isinstance(d.get("tubes"), list)


_SIGNATURES = {".png": (0, b"\x89PNG\r\n\x1a\n"), ".gif": (0, b"GIF8"), ".mp4": (4, b"ftyp")}


def _is_figure(path: Path) -> bool:
    """A picture or animation of the format its suffix names (`ctrkin show` writes .png, .gif, .mp4):
    its first bytes are that format's signature, so a data file named .png is never replaced."""
    sig = _SIGNATURES.get(path.suffix.lower())
    if sig is None:
        return False
    with open(path, "rb") as f:
        head = f.read(16)
    return head[sig[0]:sig[0] + len(sig[1])] == sig[1]


FILE_KINDS: dict[str, Callable[[Path], bool]] = {
    "predictions": _is_predictions, "ONNX model": _is_onnx, "robot description": _is_robot,
    "figure": _is_figure}


def check_file_replaceable(path: Path, kind: str, error: type[Exception]) -> None:
    """Refuse (`error`) to replace `path` unless it is a regular file (not a link, not a folder)
    that ctrkin writes as `kind` (FILE_KINDS)."""
    if os.path.islink(path):
        raise error(f"{path} is a symbolic link: name the file itself (ctrkin replaces files, not links)")
    if path.is_dir():
        raise error(f"{path} is a folder; name a file to write")
    if not path.is_file():
        raise error(f"{path} exists and is not a regular file")
    try:
        ours = FILE_KINDS[kind](path)
    except OSError as e:
        raise error(f"{path} cannot be read ({e.strerror}): ctrkin replaces only files it can "
                    "check") from None
    if not ours:
        raise error(f"{path} is not a {kind} file ctrkin wrote: ctrkin replaces only its own outputs; "
                    "choose another --out, or move it away yourself")
