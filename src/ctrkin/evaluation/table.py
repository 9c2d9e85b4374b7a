"""The report's predictors and experiments as one typed table: each row a predictor (its results key,
its label in figures and report.md, where its predictions come from), each experiment its results
key, its stage, the rows it compares and its figures with their captions.

    ROWS             every predictor of the report, FK and IK (this module)
    Experiment       one of the paper's experiments (or ours): the experiments modules declare theirs
                     beside their code, ctrkin.evaluation.experiments lists them in run order

Adding a predictor is a Row here (the calibrated TCM: kind "tcm" with its own `predict_at`); adding an
experiment is an Experiment beside its function in an experiments module, plus its figure in
ctrkin.viz.experiments. The results keep their keys: a row's `name` is its key in results.json.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

if TYPE_CHECKING:
    import numpy as np

    from ctrkin.data.dataset import Dataset
    from ctrkin.evaluation.context import Context

Task = Literal["fk", "ik"]
# the model folders of a reproduction (models/<name>; ctrkin.evaluation.training_runs trains them)
FK_PAPER, FK_BRANCH = "fk_lstm_mlp", "fk_lstm_mlp_branch"
IK_PAPER, IK_REFINED, IK_FOLLOW = "ik_lstm_mlp", "ik_lstm_mlp_refined", "ik_follow_mlp"
BASELINES = ("mlp", "lstm", "cnn", "tcn", "resnet")     # the registry names of Fig. 5a's baselines
ABLATION = "lstm_mlp_no_delta"                          # Fig. 5b
HEADLINE = "lstm_mlp"      # the recommended model's figures again under this key (results.json keeps it)
TCM_COLOUR, MODEL_COLOUR = "k", "tab:blue"   # the paper's colours: TCM black, learned model blue


class Curve(NamedTuple):
    """How a row's T(L) is drawn in the turn figures (ctrkin.viz.experiments.sweeps_figure): colour;
    kind "points" (markers, filled forward, open backward) or "line" (solid forward, dashed back);
    marker size or line width."""

    colour: str
    kind: str
    size: float


@dataclass(frozen=True)
class Row:
    """A predictor of the report.

    name: its key in results.json (within its task's tables); label: in figures and report.md;
    task: "fk" or "ik"; kind: "model" (a trained folder, models/<folder>), "tcm" (the point-wise
    TCM, evaluated on the experiment's rows only and timed) or "tcm_continued" (the TCM followed
    along each sequence); predict: an FK row's predictions (T, 6) over a dataset from the context,
    where it is not a plain model folder (the gate ablations; the calibrated TCM continued); predict_at:
    a point-wise row's predictions (len(at), 6) at rows `at` of a dataset only (the calibrated TCM, as
    the "tcm" kind solves only the experiment's rows); curve: drawn in the turn
    figures (None: scored only); bars: in Fig. 5a's bars; heldout_sequences: an IK row evaluated on
    the first k held-out sequences only (a step-by-step solver); from_robot_start: an IK row also
    started from the robot's joints (the follow IK); flat: the results.json sections whose flat keys
    copy its headline figures ("fk", "ik", "snapping")."""

    name: str
    label: str
    task: Task
    kind: Literal["model", "tcm", "tcm_continued"] = "model"
    folder: str | None = None
    predict: Callable[[Context, Dataset], np.ndarray] | None = None
    predict_at: Callable[[Context, Dataset, np.ndarray], np.ndarray] | None = None
    curve: Curve | None = None
    bars: bool = False
    heldout_sequences: int | None = None
    from_robot_start: bool = False
    flat: tuple[str, ...] = ()


def _learned_gate(ctx: Context, ds: Dataset) -> np.ndarray:
    return ctx.fk(FK_BRANCH, ds, gate="learned")


def _tcm_gated(ctx: Context, ds: Dataset) -> np.ndarray:
    return ctx.fk_tcm_gated(FK_BRANCH, ds)


def _calibrated_point(ctx: Context, ds: Dataset, at: np.ndarray) -> np.ndarray:
    return ctx.calibrated_point(ds, at)


def _calibrated_continued(ctx: Context, ds: Dataset) -> np.ndarray:
    return ctx.calibrated_continued(ds)


# --- the predictors -------------------------------------------------------------------------------
FK_PAPER_ROW = Row("lstm_mlp_paper", "LSTM-MLP (paper)", "fk", folder=FK_PAPER,
                   curve=Curve("tab:orange", "line", 1.0), bars=True, flat=("fk", "snapping"))
FK_BRANCH_ROW = Row("lstm_mlp_branch", "snap-aware LSTM-MLP", "fk", folder=FK_BRANCH,
                    curve=Curve(MODEL_COLOUR, "line", 1.3), bars=True, flat=("fk", "snapping"))
# ablations of the snap-aware model: its branch state from the nominal TCM continued along the same
# joint path (a physics gate; batch only), and from its learned gate instead of its fold gate (where
# its validation chose the learned gate, ctrkin.families.snap_aware.gate_choice, the two rows agree)
TCM_GATED_ROW = Row("lstm_mlp_branch_tcm_gate", "snap-aware, TCM-gated", "fk", predict=_tcm_gated)
LEARNED_GATE_ROW = Row("lstm_mlp_branch_learned_gate", "snap-aware, learned gate", "fk",
                       predict=_learned_gate)
BASELINE_ROWS = tuple(Row(m, label, "fk", folder=f"fk_{m}", bars=True, flat=("fk",)) for m, label in
                      zip(BASELINES, ("MLP", "LSTM", "CNN", "TCN", "ResNet"), strict=True))
ABLATION_ROW = Row(ABLATION, "LSTM-MLP without Δα0", "fk", folder=f"fk_{ABLATION}")
TCM_ROW = Row("tcm", "TCM (point-wise)", "fk", kind="tcm", curve=Curve(TCM_COLOUR, "points", 1.5), bars=True,
              flat=("fk", "snapping"))
TCM_CONTINUED_ROW = Row("tcm_continued", "TCM (continued)", "fk", kind="tcm_continued",
                        curve=Curve("tab:green", "line", 0.9), flat=("snapping",))
# the TCM calibrated on the training rows (every group and μ between the tubes, ctrkin.calibration):
# point-wise (no history), and followed along each sequence with the branch and the friction state
TCM_CALIBRATED_ROW = Row("tcm_calibrated", "calibrated TCM (point-wise)", "fk", kind="tcm",
                         predict_at=_calibrated_point, flat=("fk",))
TCM_CALIBRATED_CONTINUED_ROW = Row("tcm_calibrated_continued", "calibrated TCM with friction (continued)",
                                   "fk", kind="tcm_continued", predict=_calibrated_continued, flat=("fk",))
TCM_CALIBRATED_ROWS = (TCM_CALIBRATED_ROW, TCM_CALIBRATED_CONTINUED_ROW)
IK_PAPER_ROW = Row("lstm_mlp_paper", "LSTM-MLP (paper's network)", "ik", folder=IK_PAPER, flat=("ik",))
IK_REFINED_ROW = Row("lstm_mlp_refined", "LSTM-MLP IK refined on the FK", "ik", folder=IK_REFINED,
                     heldout_sequences=2, flat=("ik",))
IK_FOLLOW_ROW = Row("follow_mlp", "follow IK", "ik", folder=IK_FOLLOW, from_robot_start=True, flat=("ik",))

ROWS: tuple[Row, ...] = (FK_PAPER_ROW, FK_BRANCH_ROW, TCM_GATED_ROW, LEARNED_GATE_ROW, *BASELINE_ROWS,
                         ABLATION_ROW, TCM_ROW, TCM_CONTINUED_ROW, *TCM_CALIBRATED_ROWS,
                         IK_PAPER_ROW, IK_REFINED_ROW, IK_FOLLOW_ROW)
# the recommended models: the snap-aware FK and the follow IK (it reaches the targets the direct
# networks miss by millimetres, docs/reproduction.md); their figures also stand under HEADLINE
RECOMMENDED: dict[str, Row] = {"fk": FK_BRANCH_ROW, "ik": IK_FOLLOW_ROW}
# the learned FK rows every FK experiment compares, and the turn experiments' TCM rows
FK_LEARNED = (FK_PAPER_ROW, FK_BRANCH_ROW, TCM_GATED_ROW, LEARNED_GATE_ROW)
IK_ROWS = (IK_PAPER_ROW, IK_REFINED_ROW, IK_FOLLOW_ROW)


def labels() -> dict[str, str]:
    """Results key -> readable label of every row (figures, report.md); an FK row's where both tasks
    use a key."""
    out = {r.name: r.label for r in ROWS if r.task == "ik"}
    return out | {r.name: r.label for r in ROWS if r.task == "fk"}


def with_headline(results: dict[str, Any], task: Task) -> dict[str, Any]:
    """results plus the recommended model's entry again under HEADLINE, naming the model it is."""
    name = RECOMMENDED[task].name
    return {HEADLINE: {**results[name], "model": name}, **results}


def fk_predictions(ctx: Context, rows: Sequence[Row], ds: Dataset, at: np.ndarray, desc: str
                   ) -> tuple[dict[str, np.ndarray], np.ndarray | None]:
    """(len(at), 6) predictions of each FK row at rows `at` of ds, in the rows' order, and the
    point-wise TCM's time per point (s; None without a TCM row). The learned and continued rows
    predict whole sequences (with history); the point-wise TCMs solve only `at` (desc: the nominal
    one's progress)."""
    out: dict[str, np.ndarray] = {}
    times = None
    for r in rows:
        if r.predict_at is not None:
            out[r.name] = r.predict_at(ctx, ds, at)
        elif r.kind == "tcm":
            out[r.name], times = ctx.tcm_rows(ds, at, desc)
        elif r.predict is not None:
            out[r.name] = r.predict(ctx, ds)[at]
        elif r.kind == "tcm_continued":
            out[r.name] = ctx.tcm_continued(ds)[at]
        else:
            assert r.folder is not None
            out[r.name] = ctx.fk(r.folder, ds)[at]
    return out, times


def flat_rows(section: str) -> tuple[str, ...]:
    """The keys whose headline figures results.json copies under flat names in `section`, the
    recommended model's (HEADLINE) first where the section has one."""
    head = (HEADLINE,) if section in ("fk", "ik") else ()
    task = "ik" if section == "ik" else "fk"
    return head + tuple(r.name for r in ROWS if section in r.flat and r.task == task)


# --- experiments ----------------------------------------------------------------------------------
class Figure(NamedTuple):
    """A figure of the report: file stem in OUT/figures, title, and the caption under it (what is
    plotted, in which units, against what, how to read it)."""

    stem: str
    title: str
    caption: str


@dataclass(frozen=True)
class Experiment:
    """One experiment of the reproduction.

    name: its key in results.json (under "experiments", or at the top with `top_level`: fk, ik,
    grids, timing); stage: the line the run logs, and its key in results.json's seconds (stages
    may share one); run(ctx, rows): its results (the rows are its predictors, in order); rows: the
    predictors it compares; figures: what it draws, in the report's reading order; section: the
    table of report.md ("fk", "ik") that lists it with the paper's numbers."""

    name: str
    stage: str
    run: Callable[[Context, tuple[Row, ...]], dict[str, Any]]
    rows: tuple[Row, ...] = ()
    figures: tuple[Figure, ...] = ()
    top_level: bool = False
    section: Task | None = None
