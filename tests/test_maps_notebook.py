"""The workspace-map notebook runs from top to bottom (outputs are not committed)."""

from __future__ import annotations

import json

import pytest

from tests.conftest import ROOT, execute_notebook

NOTEBOOK = ROOT / "notebooks" / "workspace_map.ipynb"


def test_notebook_is_committed_without_outputs():
    nb = json.loads(NOTEBOOK.read_text())
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert code
    assert all(not c.get("outputs") and c.get("execution_count") is None for c in code)


@pytest.mark.slow
def test_workspace_map_notebook_executes():
    pytest.importorskip("matplotlib")
    nb = execute_notebook(NOTEBOOK, timeout=600)
    text = "\n".join(
        out.get("text", "") + json.dumps(out.get("data", {}).get("text/plain", ""))
        for cell in nb.cells
        if cell.cell_type == "code"
        for out in cell.get("outputs", [])
    )
    assert "POC at the nominal pose: True" in text
    assert "positive controllability == wrench closure everywhere: True" in text
    assert "image/png" in json.dumps([c.get("outputs") for c in nb.cells if "outputs" in c])
