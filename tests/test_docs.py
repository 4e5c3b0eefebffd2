"""The README and docs point only at things in the repository."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_no_references_to_files_outside_the_repository(doc):
    text = doc.read_text(encoding="utf-8")
    for outside in ("shared/papers", "THEORY.md", "../shared", "STYLE.md"):
        assert outside not in text, f"{doc.name} mentions {outside!r}"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_relative_links_and_images_exist(doc):
    text = doc.read_text(encoding="utf-8")
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
        if "://" in target or target.startswith("mailto:"):
            continue
        assert (doc.parent / target).exists(), f"{doc.name} links to missing {target}"


def test_the_theory_is_in_docs():
    theory = (ROOT / "docs" / "theory.md").read_text(encoding="utf-8")
    for topic in ("Theorem 1", "Brammer", "Reach margin", "Lemma 1"):
        assert topic in theory
