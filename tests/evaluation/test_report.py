"""report.md structure, from the results of a tiny reproduction (tiny_results.json: rounded, without
the flat keys): headline columns, the tiny warning, Table II/III texts, a caption under each figure."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from ctrkin.evaluation.experiments import FIGURES
from ctrkin.evaluation.report import TINY_WARNING, describe_structure, write_report
from ctrkin.evaluation.results import ReproResults

RESULTS = Path(__file__).with_name("tiny_results.json")
NUMBER = re.compile(r"^(–|-?\d+(\.\d+)?)$")


@pytest.fixture
def results() -> dict[str, Any]:
    return json.loads(RESULTS.read_text())


def _report(results: dict[str, Any], folder: Path, pngs: tuple[str, ...] = ()) -> str:
    (folder / "figures").mkdir()
    for stem in pngs:
        (folder / "figures" / f"{stem}.png").write_bytes(b"png")
    write_report(ReproResults.from_dict(results), folder / "report.md")
    return (folder / "report.md").read_text()


def _tables(text: str, section: str) -> list[list[list[str]]]:
    """The markdown tables of a section: each a list of rows (header first) of cells."""
    body = text.split(section, 1)[1].split("\n## ", 1)[0]
    tables, cur = [], []
    for line in [*body.splitlines(), ""]:
        if line.startswith("|"):
            if not line.startswith("|---"):
                cur.append([c.strip() for c in line.strip("|").split("|")])
        elif cur:
            tables.append(cur)
            cur = []
    return tables


def test_headline_columns_hold_what_they_say(results, tmp_path) -> None:
    fk, ik, speed = _tables(_report(results, tmp_path), "## Headline")
    assert fk[0] == ["quantity", "paper", "ours vs measured", "ours vs truth"]
    for row in fk[1:]:                       # both "ours" columns: numbers, or a precision / recall pair
        for cell in row[2:]:
            assert all(NUMBER.match(part.strip()) for part in cell.split("/")), row
    assert ik[0] == ["quantity", "paper", "ours"]
    assert all(NUMBER.match(row[2]) for row in ik[1:])
    assert any("through the learned FK model" in row[0] for row in ik)
    assert any("driving the robot" in row[0] for row in ik)
    assert speed[0] == ["quantity", "paper", "ours", "how ours was timed"]
    for row in speed[1:]:
        assert re.match(r"^\d+\.\d+ ± \d+\.\d+$", row[2]), row
        assert "streaming" in row[3] or "point-wise" in row[3]


def test_tiny_scale_warns_at_the_top_and_other_scales_do_not(results, tmp_path) -> None:
    text = _report(results, tmp_path)
    assert text.index(TINY_WARNING) < text.index("## Headline")
    results["scale"]["name"] = "quick"
    (tmp_path / "quick").mkdir()
    assert TINY_WARNING not in _report(results, tmp_path / "quick")


def test_tables_two_and_three_say_what_they_compare(results, tmp_path) -> None:
    text = _report(results, tmp_path)
    assert "Table II is not like with like" in text
    ib = _tables(text, "## Input buffer (Table II)")[0]
    assert "paper FK test MAE, normalised" in ib[0] and "IK test MAE, normalised" in ib[0]
    assert [row[0] for row in ib[1:]] == ["1", "2", "3", "4", "5"]
    structures = dict(row for row in _tables(text, "## Input buffer (Table II)")[1][1:])
    assert set(structures) == {"S1", "S2", "S3", "S4", "S5"}
    assert structures["S1"] == describe_structure("S1")


def test_describe_structure_spells_out_the_layers() -> None:
    assert describe_structure("S4") == "LSTM 128 → Dense 128 (ReLU) → LSTM 64 → flatten → Dense 6"
    assert describe_structure("paper") == "LSTM 128 → flatten → Dense 64 (ReLU) → Dense 6"


def test_each_figure_has_a_title_and_a_caption_under_it(results, tmp_path) -> None:
    stems = tuple(f.stem for f in FIGURES)
    text = _report(results, tmp_path, (*stems, "extra_plot"))
    figures = text.split("## Figures", 1)[1].split("\n## ", 1)[0]
    at = -1
    for f in FIGURES:
        image = f"![{f.title}](figures/{f.stem}.png)"
        assert figures.index(f"### {f.title}") < figures.index(image), f.stem
        assert figures.index(image) > at, f.stem                             # reading order
        at = figures.index(image)
        after = figures[at + len(image):].lstrip("\n").split("\n", 1)[0]
        assert after == f"*{f.caption}*" and len(f.caption) > 60, f.stem
    assert "figures/extra_plot.png" in figures                               # an unknown figure still shows


def test_figures_missing_on_disk_are_not_linked(results, tmp_path) -> None:
    text = _report(results, tmp_path, ("fig7_input_buffer",))
    assert "figures/fig7_input_buffer.png" in text
    assert "figures/fig8_structures.png" not in text


def test_the_report_names_the_robot_and_paper_table_i_only_for_the_paper_robot(results, tmp_path) -> None:
    from ctrkin.robots import load_robot

    results["robot"] = load_robot("paper").to_dict()
    (tmp_path / "a").mkdir()
    assert "Robot: paper (paper Table I), virtual robot seed" in _report(results, tmp_path / "a")
    results["robot"] = load_robot("timclab").to_dict()
    results["virtual_settings"] = {"noise_mm": 0.1}
    (tmp_path / "b").mkdir()
    text = _report(results, tmp_path / "b")
    assert "Robot: timclab, virtual robot seed 0 with noise_mm = 0.1." in text
    assert "Table I)" not in text
