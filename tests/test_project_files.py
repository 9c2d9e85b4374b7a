"""The project files a user and a citation manager read: LICENSE, CITATION.cff, CHANGELOG.md,
CONTRIBUTING.md, and one version everywhere (`ctrkin --version`)."""

from __future__ import annotations

import importlib.metadata
import re
import tomllib
from pathlib import Path

from click.testing import CliRunner

import ctrkin
import ctrkin.version
from ctrkin.cli.main import cli

ROOT = Path(__file__).resolve().parents[1]


def test_version_is_semantic_and_the_same_everywhere() -> None:
    assert re.fullmatch(r"\d+\.\d+\.\d+", ctrkin.__version__)
    res = CliRunner().invoke(cli, ["--version"])
    assert res.exit_code == 0 and res.output.strip() == f"ctrkin, version {ctrkin.__version__}"
    assert importlib.metadata.version("ctrkin") == ctrkin.__version__      # the installed metadata
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert pyproject["project"]["dynamic"] == ["version"]
    # the version's one place is the leaf module ctrkin.version (the package root re-exports it)
    assert pyproject["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "ctrkin.version.__version__"}
    assert ctrkin.version.__version__ == ctrkin.__version__


def test_license_is_mit_as_pyproject_says() -> None:
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License") and "Copyright (c)" in text and "the ctrkin developers" in text
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert pyproject["project"]["license"] == {"text": "MIT"}


def test_citation_file() -> None:
    """CFF 1.2.0 (validated once with cffconvert --validate; the keys it needs are checked here)."""
    text = (ROOT / "CITATION.cff").read_text()
    top = dict(re.findall(r"^([a-z-]+):[ \t]*(.*)$", text, re.MULTILINE))
    assert top["cff-version"] == "1.2.0" and top["type"] == "software" and top["license"] == "MIT"
    assert top["version"] == ctrkin.__version__
    assert {"message", "title", "authors", "references"} <= set(top)
    paper = (ROOT.parent / "shared" / "reference" / "paper.txt")
    title = ("Learning-Based Kinematic Modeling for Concentric Tube Robot: Addressing its Nonlinearity and "
             "Snapping Behavior")
    assert title in " ".join(text.split())
    if paper.exists():                                  # the reference copy, where this checkout has it
        assert title in paper.read_text()


def test_changelog_has_this_version_and_the_moved_history() -> None:
    text = (ROOT / "CHANGELOG.md").read_text()
    versions = re.findall(r"^## \[(\d+\.\d+\.\d+)\]", text, re.MULTILINE)
    assert versions[0] == ctrkin.__version__ and "0.1.0" in versions
    assert "## [Unreleased]" in text and "semantic versioning" in text
    assert "```bash" not in text          # history records commands as text: the docs' blocks run
    for doc in ("reproduction", "mechanics", "learned_kinematics", "robustness"):
        assert f"From docs/{doc}.md" in text
    # the docs describe the current code: no dated measurement section is left in them
    for doc in sorted((ROOT / "docs").rglob("*.md")):
        for heading in re.findall(r"^#+ .*$", doc.read_text(), re.MULTILINE):
            assert not re.search(r"20\d\d-\d\d-\d\d", heading), f"{doc.name}: {heading}"
