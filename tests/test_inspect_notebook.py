"""The pose-inspection notebook runs top to bottom, slider change included."""

from __future__ import annotations

import json

import pytest

from tests.conftest import ROOT

NOTEBOOK = ROOT / "notebooks" / "inspect_pose.ipynb"


def test_notebook_is_committed_without_outputs():
    nb = json.loads(NOTEBOOK.read_text())
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert code and all(not c["outputs"] and c["execution_count"] is None for c in code)


@pytest.mark.slow
def test_inspect_notebook_executes_and_a_slider_change_updates_the_verdict():
    pytest.importorskip("meshcat")
    pytest.importorskip("ipywidgets")
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        nb,
        timeout=120,
        kernel_name="python3",
        resources={"metadata": {"path": str(NOTEBOOK.parent)}},
    )
    client.execute()
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
