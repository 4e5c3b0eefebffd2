"""The paper-example notebook runs from top to bottom (outputs are not committed)."""

from __future__ import annotations

import json

import pytest

from tests.conftest import ROOT, execute_notebook

NOTEBOOK = ROOT / "notebooks" / "paper_example.ipynb"


def test_notebook_is_committed_without_outputs():
    nb = json.loads(NOTEBOOK.read_text())
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert code, "notebook has no code cells"
    assert all(not c.get("outputs") and c.get("execution_count") is None for c in code)


@pytest.mark.slow
def test_paper_example_notebook_executes():
    nb = execute_notebook(NOTEBOOK, timeout=300)
    text = "\n".join(
        out.get("text", "") + json.dumps(out.get("data", {}))
        for cell in nb.cells
        if cell.cell_type == "code"
        for out in cell.get("outputs", [])
    )
    assert "eq 14 check: True" in text
    assert "certificate re-checks: True" in text
    assert "Verdict.YES" in text or "verdict: YES" in text or "verdict: yes" in text
