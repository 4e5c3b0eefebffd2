"""Shared fixtures: paths of the shipped models and a spec-writing helper."""

from __future__ import annotations

import shutil
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
PAPER_SPEC = MODELS / "two_link_planar" / "two_link_planar.yaml"
SHARED = ROOT.parent / "shared"


@pytest.fixture(scope="session")
def paper_robot():
    import cdpm

    return cdpm.load_robot(PAPER_SPEC)


@pytest.fixture
def write_spec(tmp_path):
    """Write a spec beside a copy of the paper's URDF; returns its path."""
    shutil.copy(MODELS / "two_link_planar" / "two_link_planar.urdf", tmp_path / "arm.urdf")

    def _write(text: str, name: str = "spec.yaml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return path

    return _write


def execute_notebook(path: Path, timeout: int = 300):
    """Run a notebook top to bottom in its own folder; returns it with outputs.

    Skips when the test extra's notebook runner is missing.
    """
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    nb = nbformat.read(path, as_version=4)
    nbclient.NotebookClient(
        nb,
        timeout=timeout,
        kernel_name="python3",
        resources={"metadata": {"path": str(Path(path).parent)}},
    ).execute()
    return nb
