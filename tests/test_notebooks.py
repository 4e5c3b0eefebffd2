"""The paper-example and steering notebooks run from top to bottom (outputs are not
committed)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.conftest import ROOT, execute_notebook

NOTEBOOK = ROOT / "notebooks" / "paper_example.ipynb"
STEERING = ROOT / "notebooks" / "steering.ipynb"


@pytest.mark.parametrize("path", [NOTEBOOK, STEERING], ids=lambda p: p.stem)
def test_notebook_is_committed_without_outputs(path):
    nb = json.loads(path.read_text())
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
    assert "r_T = 0.1501 m (error 0); closed form 0.1501 m" in text
    assert "Verdict.YES" in text or "verdict: YES" in text or "verdict: yes" in text
    # the last cell shows the pose report as it prints, in plain text and in html,
    # not the dump of its fields (about 4.9 kB of "PoseReport(model_name=...")
    last = nb.cells[-1].outputs[-1]["data"]
    plain, html = last["text/plain"], last["text/html"]
    assert plain.startswith("cdpm report: two_link_planar.yaml, pose 'nominal'")
    assert "Positive output controllability (Theorem 1): YES (nilpotent" in plain
    assert "PoseReport(" not in plain and "array(" not in plain
    assert html.startswith("<pre>cdpm report: two_link_planar.yaml")


@pytest.mark.slow
def test_steering_notebook_executes():
    pytest.importorskip("matplotlib")
    # the notebook asserts its own claims (Remark 11 tolerances, reached targets)
    nb = execute_notebook(STEERING, timeout=300)
    outputs = [out for cell in nb.cells if cell.cell_type == "code" for out in cell.outputs]
    text = "\n".join(out.get("text", "") for out in outputs)
    assert "POC: YES" in text
    assert "positive controllability: NO" in text
    assert "two_link_two_cables.yaml, pose 'nominal': POC NO" in text
    assert "two_link_vertical.yaml, pose 'nominal': POC YES" in text
    assert sum("image/png" in out.get("data", {}) for out in outputs) == 5


def test_every_notebook_cell_has_an_id():
    """nbformat 4.5 cells carry ids (a cell without one draws a
    MissingIDFieldWarning, and a future nbformat refuses it)."""
    for path in sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb")):
        cells = json.loads(path.read_text())["cells"]
        assert all("id" in cell for cell in cells), path.name
