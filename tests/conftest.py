"""Shared fixtures: paths of the shipped models, a spec-writing helper and
the CASPR model library (``CDPM_CASPR_MODELS``)."""

from __future__ import annotations

import os
import shutil
import textwrap
from collections.abc import Mapping
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
PAPER_SPEC = MODELS / "two_link_planar" / "two_link_planar.yaml"


def paper_spec_copy(tmp_path: Path, text: str) -> Path:
    """A spec of the paper arm with the given YAML ``text``, written as
    ``spec.yaml`` in ``tmp_path`` beside a copy of the arm's URDF."""
    shutil.copy(PAPER_SPEC.with_suffix(".urdf"), tmp_path)
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    return path


def paper_spec_text() -> str:
    """The paper arm's spec, as YAML text to edit."""
    return PAPER_SPEC.read_text()


#: environment variable naming the ``models`` folder of a CASPR checkout
#: (https://github.com/darwinlau/CASPR, BSD-3-Clause), used by tests/test_caspr.py
CASPR_MODELS_ENV = "CDPM_CASPR_MODELS"
#: where the CASPR model library is looked for when the variable is not set
CASPR_MODELS_DEFAULT = ROOT.parent / "shared" / "caspr-models" / "models"


def caspr_models(environ: Mapping[str, str] | None = None) -> tuple[Path, str | None]:
    """The CASPR model library for the tests, and why it is missing.

    Args:
        environ: the environment to read (default ``os.environ``).

    Returns:
        (folder, skip reason): the folder named by ``CDPM_CASPR_MODELS`` (or
        the default), and None when it holds CASPR's ``models_list.csv``,
        else a sentence naming the variable.
    """
    environ = os.environ if environ is None else environ
    value = environ.get(CASPR_MODELS_ENV, "")
    folder = Path(value).expanduser() if value else CASPR_MODELS_DEFAULT
    if (folder / "models_list.csv").is_file():
        return folder, None
    where = f"{CASPR_MODELS_ENV}={value}" if value else f"{folder} ({CASPR_MODELS_ENV} not set)"
    return folder, (
        f"CASPR model library not found at {where}: set {CASPR_MODELS_ENV} to the "
        "models folder of a CASPR checkout (https://github.com/darwinlau/CASPR)"
    )


@pytest.fixture(scope="session", autouse=True)
def compiled_kernels():
    """Compile (or load from the disk cache) the maps' kernels once, before
    any test starts worker processes that would each compile them."""
    from cdpm.pipeline.compiled import load_kernels

    load_kernels()


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


def neither_case_spec(tmp_path: Path) -> Path:
    """The vertical arm (under gravity) with the zero-tension equilibrium
    method: outside both cases certified boxes cover (zero load, and a
    least-norm tension under load)."""
    src = MODELS / "two_link_vertical"
    for f in src.iterdir():
        if f.suffix in (".urdf", ".yaml"):
            shutil.copy(f, tmp_path)
    path = tmp_path / "two_link_vertical.yaml"
    text = path.read_text()
    lines = [
        "equilibrium: {method: zero}" if line.startswith("equilibrium:") else line
        for line in text.splitlines()
    ]
    path.write_text("\n".join(lines) + "\n")
    return path
