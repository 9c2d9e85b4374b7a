"""Every `ctrkin` command in the fenced bash blocks of README.md and docs/**/*.md runs, and the
figures the documents print are what the commands print.

Each document's commands run in order, in one temporary folder per document (later commands use
what earlier ones wrote), through click's CliRunner. A command runs as written, with only the size
options of TINY appended (click takes the last value of a repeated option, so `--scale full` becomes
`--scale tiny`); the commands of SKIP do not run, each for the reason given. The inputs a document
assumes (a user's log, the comet-lab logs under ../shared/realdata) are written by FIXTURES as
small synthetic files in the same formats and with the same names, so the test needs no data
outside the repository.

Printed figures: a ```text block right after the comment `<!-- output: tolerance TOL -->` shows
what the last command before it prints. Each of its lines must match a line of the command's
output, in order, with every number within TOL of the printed one (absolute, in the printed unit;
0: equal) and the words around the numbers equal; `...` in a line stands for any text (a timing).
Only outputs that do not depend on the run's size or the machine are shown this way (the
mechanics, the tiny recordings); figures of quick and full runs are quoted with the command (a
benchmark or `ctrkin reproduce`) that measured them.
"""

from __future__ import annotations

import glob
import re
import shlex
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomli_w
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from ctrkin.cli.main import cli
from ctrkin.mechanics import follow, solve
from ctrkin.robots import load_robot, paper_robot
from tests.lab_logs import configurations, ndi_lab_log, ndi_log, optitrack_log, to_ctrkin
from tests.small_models import six_sweeps, small_configs

REPO = Path(__file__).resolve().parents[2]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]

# options appended to a command (by its sub-command words) so that it runs at a tiny size
TINY: dict[tuple[str, ...], list[str]] = {
    ("collect",): ["--scale", "tiny", "--workers", "1"],
    ("train",): ["--epochs", "1", "--threads", "1"],
    ("sweep",): ["--step", "15"],
    ("calibrate",): ["--max-evaluations", "8"],
    ("show",): ["--frames", "4"],
}

# commands not run (matched by their first words), and why
SKIP: dict[str, str] = {
    "ctrkin reproduce --scale quick": "the README's main job, ~36 minutes on two cores",
    "ctrkin reproduce --scale full": "the paper's data size and training, ≈ 22 min on two cores",
    "ctrkin reproduce --scale tiny": "90 s (warm numba cache) to 147 s (cold) on the two-core dev "
    "machine, this test's whole budget; the same tiny pipeline runs in tests/evaluation/"
    "test_reproduce.py, the command's arguments in tests/cli/test_reproduce_cli.py",
    "ctrkin reproduce --robot my_robot.toml": "a quick reproduction on the user's robot, ~12-36 minutes; "
    "a three-tube robot file with --set runs through the same command at tiny scale in "
    "tests/evaluation/test_reproduce_other_robots.py",
    "ctrkin collect --rig examples/rigs/paper.toml": "drives the paper's EPOS4 motors and reads its "
    "Aurora; its dry run (paper_dry_run.toml, the same drives simulated) runs instead",
}

ENV = {"CTRKIN_NO_PROGRESS": "1"}


# --- inputs the documents assume -----------------------------------------------------------------
OPTITRACK_FILES = ("19_05_23-12_35_2-tubes_rotate", "19_05_23-13_08_2-tubes_rotate",
                   "19_05_23-13_23_2-tubes_rotate")
NDI_FILES = ("2023-10-7_03-06-44", "2023-10-9_02-10-58", "2023-11-20_03-33-12", "2023-11-21_01-41-07")


def _tips(robot_file: str, lab_q: np.ndarray) -> np.ndarray:
    """(n, 3) mm: TCM tips of the example robot, moved into a tracker frame."""
    robot = load_robot(str(REPO / "examples" / "robots" / robot_file))
    q = to_ctrkin(robot, lab_q)
    return np.array([solve(robot, qk).tip_pose[:3] for qk in q]) + np.array([20.0, -35.0, 110.0])


def comet_logs(root: Path) -> None:
    """../shared/realdata/comet-lab (docs/real_robot.md): the two lab formats, the lab's file names."""
    base = root.parent / "shared" / "realdata" / "comet-lab"
    for k, name in enumerate(OPTITRACK_FILES):
        lab_q = configurations(12, seed=k)
        optitrack_log(_mkdir(base / "optitrack-2tube") / f"{name}.csv", lab_q,
                      _tips("comet_nylon_optitrack.toml", lab_q), noise_mm=0.05, seed=k)
    rot = Rotation.from_euler("xyz", [30, -50, 120], degrees=True)
    for k, name in enumerate(NDI_FILES):
        lab_q = configurations(6, seed=10 + k)
        ndi_log(_mkdir(base / "ndi-2tube") / f"{name}.csv", lab_q, _tips("comet_nylon_ndi.toml", lab_q), rot,
                np.array([73.2, 91.3, -1295.6]))
    robot3 = load_robot(str(REPO / "examples" / "robots" / "comet_nylon_ndi_3tube.toml"))
    for k in range(3):          # three-tube logs (docs/real_robot.md: Three tubes), lab joints, 20 readings
        rng = np.random.default_rng(20 + k)
        travel = np.cumsum(np.column_stack([rng.integers(0, 41, 6), rng.integers(0, 46, 6),
                                            rng.integers(0, 46, 6)]), axis=1).astype(float)
        rot3 = rng.integers(-45, 46, (6, 3)).astype(float)
        q = np.column_stack([rot3[:, ::-1], travel[:, ::-1] - [250.0, 170.0, 90.0]])
        tips = np.array([solve(robot3, qk).tip_pose[:3] for qk in q])
        ndi_lab_log(_mkdir(base / "ndi-3tube") / f"2023-11-2{k}_01-00-00.csv", travel, rot3,
                    np.repeat(tips[:, None, :], 20, axis=1), rot, np.array([73.2, 91.3, -1295.6]))


def lab_logs(root: Path) -> None:
    """logs/*.csv (docs/data.md): OptiTrack logs with the lab's file names."""
    comet_logs(root)
    (root / "logs").symlink_to(root.parent / "shared" / "realdata" / "comet-lab" / "optitrack-2tube")


def user_log(root: Path) -> None:
    """robot_log.csv and my_robot.toml (docs/data.md): radians, metres, an x, y, z, w quaternion,
    five readings per sample, six runs."""
    robot = paper_robot()
    (root / "my_robot.toml").write_text(tomli_w.dumps(robot.to_dict()))
    rng = np.random.default_rng(0)
    parts = []
    for run in range(6):
        a = 4.0 * np.arange(30)
        Q = np.c_[a, np.full(30, 40.0 * run), np.full(30, -15.0), np.full(30, -5.0)]
        p = follow(robot, Q).tip_poses
        rep = np.repeat(np.arange(30), 5)
        parts.append(pd.DataFrame({
            "stamp": run * 100 + rep * 0.5 + np.tile(np.arange(5) * 0.01, 30), "run": run,
            "enc_rot_inner": np.radians(Q[rep, 0]), "enc_rot_outer": np.radians(Q[rep, 1]),
            "enc_lin_inner": Q[rep, 2] / 1000, "enc_lin_outer": Q[rep, 3] / 1000,
            **{c: (p[rep, k] + rng.normal(scale=0.02, size=len(rep))) / 1000
               for k, c in enumerate(("px", "py", "pz"))},
            "ox": p[rep, 4], "oy": p[rep, 5], "oz": 0.0, "ow": p[rep, 3]}))
    pd.concat(parts).to_csv(root / "robot_log.csv", index=False, float_format="%.12g")


def _mkdir(p: Path) -> Path:
    p.mkdir(parents=True, exist_ok=True)
    return p


def plan_targets(root: Path) -> None:
    """The targets.csv that docs/planning.md plans through (tips of the paper robot's point-wise
    solves at full curved overlap, β = −20, 0 mm, with α1 = 160..260° in steps of 20°, α2 = 0)."""
    robot = paper_robot()
    tips = np.array([solve(robot, [a, 0.0, -20.0, 0.0]).tip_position for a in range(160, 261, 20)])
    pd.DataFrame(tips, columns=["x", "y", "z"]).to_csv(root / "targets.csv", index=False)


def plan_model(root: Path) -> None:
    """models/fk_branch (docs/planning.md: `plan --model`): a small snap-aware FK trained for three
    epochs on six sweeps of the paper robot, as the tests' `fk_branch` model is."""
    from ctrkin.training import train

    train(six_sweeps(), small_configs()["fk_branch"], root / "models" / "fk_branch", progress=False)


FIXTURES: dict[str, list[Callable[[Path], None]]] = {
    "data.md": [user_log, lab_logs],
    "planning.md": [plan_targets, plan_model],
    "real_robot.md": [comet_logs],
    "tutorial.md": [comet_logs],
}


# --- commands ------------------------------------------------------------------------------------
FENCE = re.compile(r"^(?:<!-- output: tolerance (?P<tol>\S+) -->\n)?```(?P<lang>\w*)\n(?P<text>.*?)^```",
                   re.S | re.M)
NUMBER = r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?"


def blocks(doc: Path) -> list[tuple[str, str]]:
    """(language, text) of every fenced block; a printed output's language is `output TOL`."""
    return [(m["lang"] if m["tol"] is None else f"output {m['tol']}", m["text"])
            for m in FENCE.finditer(doc.read_text())]


def _line_pattern(line: str) -> tuple[re.Pattern[str], list[float]]:
    """A printed line as a regex (numbers captured, runs of blanks flexible, `...` any text) and
    the numbers it prints."""
    numbers: list[float] = []
    parts = []
    for piece in line.strip().split("..."):
        out = []
        for token in re.split(f"({NUMBER})", piece):
            if re.fullmatch(NUMBER, token):
                numbers.append(float(token))
                out.append(f"({NUMBER})")
            else:
                out.append(r"\s+".join(re.escape(w) for w in re.split(r"\s+", token)))
        parts.append("".join(out))
    return re.compile(".*?".join(parts)), numbers


def check_printed(shown: str, printed: str, tol: float) -> int:
    """Every line of `shown` matches a line of `printed` in order, numbers within tol; returns the
    number of figures compared."""
    lines = [ln.strip() for ln in printed.splitlines() if ln.strip()]
    k, compared = 0, 0
    for want in (ln for ln in shown.splitlines() if ln.strip()):
        pattern, numbers = _line_pattern(want)
        while k < len(lines) and not pattern.fullmatch(lines[k]):
            k += 1
        assert k < len(lines), f"no printed line matches {want!r} in:\n{printed}"
        got = [float(g) for g in pattern.fullmatch(lines[k]).groups()]  # type: ignore[union-attr]
        for w, g in zip(numbers, got, strict=True):
            assert abs(w - g) <= tol, f"{want!r}: the document prints {w}, the command {g} (tolerance {tol})"
        compared += len(numbers)
        k += 1
    return compared


def commands(text: str) -> list[tuple[dict[str, str], list[str]]]:
    """The shell lines of a bash block as (variables, words) for each `ctrkin` command, in order;
    `NAME=value` lines set variables for the lines after them; other programs are left out."""
    variables: dict[str, str] = {}
    found = []
    for line in text.replace("\\\n", " ").splitlines():
        for words in _shell_commands(line):
            if words and all(re.fullmatch(r"[A-Za-z_]\w*=.*", w) for w in words):
                variables.update(w.split("=", 1) for w in words)
                continue
            if "ctrkin" in words and (words[0] == "ctrkin" or "=" in words[0] or words[0].endswith("time")):
                words = words[words.index("ctrkin"):]
                assert not set(words) & {"|", ">", ">>", "<"}, f"redirects and pipes are not run: {words}"
                found.append((dict(variables), words))
    return found


def _shell_commands(line: str) -> list[list[str]]:
    """The words of each command of a shell line (split at && and ;), comments left out."""
    lex = shlex.shlex(line, posix=True, punctuation_chars=";&|")
    lex.whitespace_split = True
    lex.commenters = "#"
    parts: list[list[str]] = [[]]
    for token in lex:
        if token in ("&&", ";"):
            parts.append([])
        else:
            parts[-1].append(token)
    return [p for p in parts if p]


def skip_reason(words: list[str]) -> str | None:
    line = " ".join(words)
    return next((why for start, why in SKIP.items() if line.startswith(start)), None)


def expand(words: list[str], variables: dict[str, str]) -> list[str]:
    """$NAME and globs, as the shell does (sorted matches; a pattern without matches stays)."""
    out = []
    for w in words:
        w = re.sub(r"\$\{?(\w+)\}?", lambda m: variables.get(m.group(1), m.group(0)), w)
        out += sorted(glob.glob(w)) or [w] if any(c in w for c in "*?[") else [w]
    return out


def tiny(args: list[str]) -> list[str]:
    for key, extra in TINY.items():
        if tuple(args[:len(key)]) == key:
            return [*args, *extra]
    return args


def _all_commands() -> list[tuple[str, list[str]]]:
    return [(doc.name, words) for doc in DOCS for lang, text in blocks(doc) if lang == "bash"
            for _v, words in commands(text)]


def test_command_blocks_are_tagged_bash() -> None:
    """A block that shows ctrkin commands without the bash tag would escape this test."""
    for doc in DOCS:
        for lang, text in blocks(doc):
            if lang != "bash":
                assert not any(line.lstrip().startswith("ctrkin ") for line in text.splitlines()), \
                    f"{doc.name}: a ```{lang} block shows ctrkin commands; tag it ```bash"


def test_the_lists_are_not_stale() -> None:
    found = _all_commands()
    assert len(found) >= 30
    for start in SKIP:
        assert any(" ".join(w).startswith(start) for _d, w in found), f"no documented command {start!r}"
    assert {name for name in FIXTURES} <= {doc.name for doc in DOCS}


@pytest.mark.parametrize("doc", DOCS, ids=lambda d: d.name)
def test_documented_commands_run(doc: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    root = tmp_path / "work"
    root.mkdir()
    (root / "examples").symlink_to(REPO / "examples")
    for make in FIXTURES.get(doc.name, []):
        make(root)
    monkeypatch.chdir(root)
    runner = CliRunner()
    ran, skipped, figures = [], [], 0
    last: tuple[list[str], str] | None = None        # the last command run and what it printed
    for lang, text in blocks(doc):
        if lang.startswith("output "):
            assert last is not None, f"{doc.name}: a printed output with no command run before it"
            figures += check_printed(text, last[1], float(lang.split()[1]))
            last = None                                # one output block per command
            continue
        if lang != "bash":
            continue
        for variables, words in commands(text):
            why = skip_reason(words)
            if why is not None:
                skipped.append(f"{' '.join(words)}: {why}")
                continue
            args = tiny(expand(words[1:], variables))
            res = runner.invoke(cli, args, env=ENV)
            assert res.exit_code == 0, f"{doc.name}: `{' '.join(words)}` failed:\n{res.output}"
            if "--out" in args:
                assert Path(args[args.index("--out") + 1]).exists(), f"`{' '.join(words)}` wrote no --out"
            print(f"$ {' '.join(args)}\n{res.output}")
            ran.append(words)
            last = (words, res.output)
    if figures:
        print(f"{doc.name}: {figures} printed figures checked")
    if not ran:
        pytest.skip("; ".join(skipped) or "no ctrkin commands")


def test_printed_figures_are_compared() -> None:
    """The check itself: words equal, numbers within the tolerance, `...` any text, lines in order."""
    printed = ("robot paper: q = [0.0, 0.0]\ntip position (mm): 0.0000 -10.4599 53.7286\n"
               "wrote x; 2.0 s (2861/s)\n")
    assert check_printed("tip position (mm): 0.0000 -10.4597 53.7286", printed, 5e-4) == 3
    assert check_printed("robot paper: q = [0.0, 0.0]\nwrote x; ...", printed, 0) == 2
    with pytest.raises(AssertionError, match=r"prints -10\.459"):
        check_printed("tip position (mm): 0.0000 -10.459 53.7286", printed, 5e-4)
    with pytest.raises(AssertionError, match="no printed line"):
        check_printed("tip position (cm): 0.0000 -10.4599 53.7286", printed, 1.0)
    with pytest.raises(AssertionError, match="no printed line"):           # out of order
        check_printed("wrote x; ...\nrobot paper: q = [0.0, 0.0]", printed, 0)


def test_the_docs_print_figures_that_are_checked() -> None:
    shown = [(doc.name, lang) for doc in DOCS for lang, _ in blocks(doc) if lang.startswith("output ")]
    assert len(shown) >= 4 and {"tutorial.md", "shapes.md"} <= {name for name, _ in shown}
