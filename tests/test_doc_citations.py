"""Citations of the documentation point at files and sections that exist.

Code and docs cite a document as `docs/<file>.md` and a section of it as `docs/<file>.md: Section`
(the section name is the start of a heading of that file, up to the next bracket, comma, semicolon or
full stop). The design document is docs/design.md; a bare DESIGN.md (not in the repository) is refused.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
CITATION = re.compile(r"docs/([\w.-]+?\.md)(?::[ \t]*([^()\[\],;:\n`*]+))?")
BARE_DESIGN = re.compile(r"(?<![\w/])DESIGN\.md")
HEADING = re.compile(r"^#+\s+(.*?)\s*$", re.MULTILINE)


def _cited_in() -> list[Path]:
    """Every file that may cite the docs: code, tests, benchmarks, docs, README, packaged data."""
    files = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
    for folder in ("src", "tests", "benchmarks"):
        files += sorted(p for p in (ROOT / folder).rglob("*") if p.suffix in (".py", ".toml", ".md")
                        and "egg-info" not in str(p))
    return [p for p in files if p.resolve() != Path(__file__).resolve()]


def _headings(doc: str) -> list[str]:
    return HEADING.findall((DOCS / doc).read_text(encoding="utf-8"))


def _section_exists(doc: str, section: str) -> bool:
    """A heading of `doc` starts with `section`, at a word boundary."""
    return any(h == section or (h.startswith(section) and not h[len(section)].isalnum())
               for h in _headings(doc))


def citations(text: str) -> list[tuple[str, str | None]]:
    """(file, section or None) of every docs/ citation in text."""
    out = []
    for m in CITATION.finditer(text):
        section = m.group(2).strip().rstrip(".").strip() if m.group(2) else None
        out.append((m.group(1), section or None))
    return out


def test_the_parser_reads_files_and_sections() -> None:
    text = ("(docs/design.md: Conventions, fixed) and docs/mechanics.md: Model. "
            "(docs/reproduction.md says why); `docs/data.md`: ...")
    assert citations(text) == [("design.md", "Conventions"), ("mechanics.md", "Model"),
                               ("reproduction.md", None), ("data.md", None)]
    assert _section_exists("mechanics.md", "Model")       # "Model (src/ctrkin/mechanics/kernels.py, …)"
    assert not _section_exists("mechanics.md", "Mode")
    assert BARE_DESIGN.search("see DESIGN.md: Mechanics") and not BARE_DESIGN.search("docs/design.md")


def test_cited_docs_and_sections_exist() -> None:
    problems = []
    for path in _cited_in():
        text, where = path.read_text(encoding="utf-8"), path.relative_to(ROOT)
        if BARE_DESIGN.search(text):
            problems.append(f"{where}: cite docs/design.md, not DESIGN.md (not in the repository)")
        for doc, section in citations(text):
            if not (DOCS / doc).is_file():
                problems.append(f"{where} cites docs/{doc}, which does not exist")
            elif section is not None and not _section_exists(doc, section):
                problems.append(f"{where} cites 'docs/{doc}: {section}'; docs/{doc} has no heading starting "
                                f"so (its headings: {_headings(doc)})")
    assert not problems, "\n".join(problems)


def test_design_doc_is_linked_from_the_readme() -> None:
    assert "docs/design.md" in (ROOT / "README.md").read_text(encoding="utf-8")
