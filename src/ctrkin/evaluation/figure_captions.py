"""The report's figure section: each figure of a reproduction in reading order, under its title with
the caption (what is plotted, in which units, against what, and how to read it) beneath. The figures
and captions are the experiments' own (ctrkin.evaluation.table.Figure, ctrkin.evaluation.experiments)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ctrkin.evaluation.table import Figure


def figure_section(folder: Path, figures: Sequence[Figure]) -> list[str]:
    """The report's figure section: each of `figures` present in `folder`, in that order, under its
    title with its caption beneath; a figure the list does not know is listed by its file name."""
    lines = ["## Figures"]
    known = {f.stem for f in figures}
    for f in figures:
        if (folder / f"{f.stem}.png").is_file():
            lines += ["", f"### {f.title}", "", f"![{f.title}](figures/{f.stem}.png)", "", f"*{f.caption}*"]
    for png in sorted(p for p in folder.glob("*.png") if p.stem not in known):
        lines += ["", f"### {png.stem}", "", f"![{png.stem}](figures/{png.name})"]
    return lines
