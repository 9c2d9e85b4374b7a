"""A newcomer's experiment (issue 25, goal 2): adding an experiment to the report touches one
experiments module plus its figure. In a temporary copy of the package a toy experiment is added
beside the FK experiments (its function and its `Experiment` entry in evaluation/experiments_fk.py)
and its figure to viz/experiments.py; nothing else is edited. The copy then runs it on small trained
models (the table lists it in run order, its figure is drawn) and writes report.md from a tiny
reproduction's results with the toy's added: the report shows its figure under its title and caption.
"""

from __future__ import annotations

import filecmp
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import ctrkin

TINY_RESULTS = Path(__file__).with_name("tiny_results.json")

TOY_EXPERIMENT = '''

FIG_TOY = Figure("toy_errors", "Toy: learned FK error along the data",
                 "Position error (mm) against the measurement of each learned FK model at every tenth row "
                 "of the data, against the row.")


def toy(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    """A newcomer's experiment: the learned FK models' errors at every tenth row of the data."""
    ds = ctx.data.paper
    at = valid_rows(ds)[::10]
    preds, _ = fk_predictions(ctx, rows_, ds, at, "toy")
    measured = ds.poses()[at]
    fig.toy_figure({r.label: position_error(preds[r.name], measured) for r in rows_},
                   ctx.figures / f"{FIG_TOY.stem}.png")
    return {r.name: summary(preds[r.name], measured, None) for r in rows_}


EXPERIMENTS = (*EXPERIMENTS, Experiment("toy", "FK experiment: toy", toy, (FK_PAPER_ROW, FK_BRANCH_ROW),
                                        (FIG_TOY,)))
'''

TOY_FIGURE = '''

def toy_figure(errors: dict[str, np.ndarray], path: str | Path) -> None:
    """Position error (mm) per row of each model: errors label -> (K,) mm."""
    fig, ax = plt.subplots(figsize=(6, 3))
    for label, e in errors.items():
        ax.plot(e, label=label)
    ax.set_xlabel("row")
    ax.set_ylabel("position error (mm)")
    ax.legend()
    _save(fig, path)
'''

# runs in the copy: the toy from the typed table, on the small models, then report.md
RUN = '''
import json, sys, types
from pathlib import Path
import ctrkin
from ctrkin.data.dataset import Dataset
from ctrkin.evaluation.context import Context
from ctrkin.evaluation.experiments import EXPERIMENTS, FIGURES
from ctrkin.evaluation.report import write_report
from ctrkin.evaluation.results import ReproResults
from ctrkin.evaluation.scales import get_scale
from ctrkin.evaluation.table import FK_BRANCH, FK_PAPER
from ctrkin.inference import Kinematics

data, fk, branch, results, out = sys.argv[1:]
out = Path(out)
(out / "figures").mkdir(parents=True)
toy = next(e for e in EXPERIMENTS if e.name == "toy")
ctx = Context(data=types.SimpleNamespace(paper=Dataset.load(data)), tcm=None, tcm_cal=None,
              models={FK_PAPER: Kinematics.load(fk), FK_BRANCH: Kinematics.load(branch)},
              figures=out / "figures", scale=get_scale("tiny"))
tree = json.loads(Path(results).read_text())
tree["experiments"][toy.name] = toy.run(ctx, toy.rows)
write_report(ReproResults.from_dict(tree), out / "report.md")
print(json.dumps({"order": [e.name for e in EXPERIMENTS], "figures": [f.stem for f in FIGURES],
                  "toy": tree["experiments"][toy.name], "module": Path(ctrkin.__file__).parent.as_posix()}))
'''


def _changed(before: Path, after: Path) -> list[str]:
    """The .py files of `after` that are new or differ from `before`'s (relative paths)."""
    out = []
    for p in sorted(after.rglob("*.py")):
        rel = p.relative_to(after)
        if not (before / rel).is_file() or not filecmp.cmp(before / rel, p, shallow=False):
            out.append(rel.as_posix())
    return out


@pytest.mark.slow
def test_a_new_experiment_is_one_module_plus_its_figure(sweeps, model_dirs, tmp_path) -> None:
    package = Path(ctrkin.__file__).parent
    copy = tmp_path / "src" / "ctrkin"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    with (copy / "evaluation" / "experiments_fk.py").open("a", encoding="utf-8") as f:
        f.write(TOY_EXPERIMENT)
    with (copy / "viz" / "experiments.py").open("a", encoding="utf-8") as f:
        f.write(TOY_FIGURE)
    assert _changed(package, copy) == ["evaluation/experiments_fk.py", "viz/experiments.py"]

    data = tmp_path / "data"
    sweeps.save(data)
    out = tmp_path / "repro"
    env = {**os.environ, "PYTHONPATH": str(copy.parent), "CTRKIN_NO_PROGRESS": "1"}
    res = subprocess.run([sys.executable, "-c", RUN, str(data), str(model_dirs["fk"]),
                          str(model_dirs["fk_branch"]), str(TINY_RESULTS), str(out)],
                         env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    got = json.loads(res.stdout.splitlines()[-1])
    assert got["module"] == copy.as_posix()                         # the copy ran, not the package
    k = got["order"].index("toy")
    # in run order: the last of experiments_fk's own, before the next module's (Fig. 6, 9: training)
    assert got["order"][k - 1:k + 2] == ["snap_turns", "toy", "delta_overlaps"]
    assert "toy_errors" in got["figures"]
    for row in ("lstm_mlp_paper", "lstm_mlp_branch"):
        assert 0 < got["toy"][row]["position_rmse_mm"] < 1e3, row
    report = (out / "report.md").read_text()
    figures = report.split("## Figures", 1)[1]
    assert "### Toy: learned FK error along the data" in figures
    assert "![Toy: learned FK error along the data](figures/toy_errors.png)" in figures
    assert "*Position error (mm) against the measurement of each learned FK model" in figures
    assert (out / "figures" / "toy_errors.png").stat().st_size > 1000
