"""The pose-inspection notebook runs top to bottom, slider change included."""

from __future__ import annotations

import json

import pytest

from tests.conftest import ROOT, execute_notebook

NOTEBOOK = ROOT / "notebooks" / "inspect_pose.ipynb"


def test_notebook_is_committed_without_outputs():
    nb = json.loads(NOTEBOOK.read_text())
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert code and all(not c["outputs"] and c["execution_count"] is None for c in code)


@pytest.mark.slow
def test_inspect_notebook_executes_and_a_slider_change_updates_the_verdict():
    pytest.importorskip("meshcat")
    pytest.importorskip("ipywidgets")
    nb = execute_notebook(NOTEBOOK, timeout=120)
    outputs = {
        i: "\n".join(
            out.get("text", "") + json.dumps(out.get("data", {})) for out in cell.get("outputs", [])
        )
        for i, cell in enumerate(nb.cells)
        if cell.cell_type == "code"
    }
    assert any("open http://127.0.0.1:" in text for text in outputs.values())
    widget = [
        text for text in outputs.values() if "application/vnd.jupyter.widget-view+json" in text
    ]
    assert widget, "the slider widget was not displayed"
    slider_cell = next(i for i, c in enumerate(nb.cells) if 'sliders["q2"].value' in c.source)
    assert outputs[slider_cell].startswith("POC: NO")
    assert "slack cables: c1, c2, c3, c4" in outputs[slider_cell]
    assert "updates, median" in "\n".join(outputs.values())
