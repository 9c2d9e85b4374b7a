"""The documentation site's sources: every page in the navigation, the whole top-level API in the
reference. (`mkdocs build --strict` itself runs in .ci/run.)"""

from __future__ import annotations

import re
from pathlib import Path

import ctrkin

ROOT = Path(__file__).resolve().parents[1]


def test_the_api_reference_documents_everything_ctrkin_exports() -> None:
    page = (ROOT / "docs" / "api" / "index.md").read_text()
    documented = set(re.findall(r"^::: ctrkin\.(\w+)\s*$", page, re.MULTILINE))
    assert documented == set(ctrkin.__all__)


def test_every_page_is_in_the_navigation() -> None:
    config = (ROOT / "mkdocs.yml").read_text()
    nav = config[config.index("\nnav:"):]
    listed = set(re.findall(r"([\w/]+\.md)\s*$", nav, re.MULTILINE))
    pages = {str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs").rglob("*.md")}
    assert pages == listed
    assert "strict: true" in config and "docstring_style: numpy" in config
