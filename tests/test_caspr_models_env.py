"""The CASPR model library is found where ``CDPM_CASPR_MODELS`` says; the
tests that need it skip with a reason naming the variable when it is absent."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import CASPR_MODELS_ENV, ROOT, caspr_models

CASPR, _CASPR_MISSING = caspr_models()


def test_caspr_models_variable_names_the_folder(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    folder, reason = caspr_models({CASPR_MODELS_ENV: str(empty)})
    assert folder == empty
    assert reason is not None and f"{CASPR_MODELS_ENV}={empty}" in reason
    (empty / "models_list.csv").write_text("")
    assert caspr_models({CASPR_MODELS_ENV: str(empty)}) == (empty, None)
    # unset or empty: the default folder, and a reason that names the variable
    for environ in ({}, {CASPR_MODELS_ENV: ""}):
        folder, reason = caspr_models(environ)
        assert folder == caspr_models({})[0] != empty
        assert reason is None or f"({CASPR_MODELS_ENV} not set)" in reason


SPHERICAL_TEST = "tests/test_caspr.py::test_spherical_library_model_warns_about_its_outputs"


def _pytest_with_library(folder: Path, test: str) -> str:
    """Run one test in a fresh pytest with CDPM_CASPR_MODELS=folder."""
    out = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", test],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
        env={**os.environ, CASPR_MODELS_ENV: str(folder)},
    )
    return out.stdout + out.stderr


@pytest.mark.slow
def test_library_tests_skip_naming_the_variable(tmp_path):
    text = _pytest_with_library(tmp_path, SPHERICAL_TEST)
    assert "1 skipped" in text, text
    assert f"set {CASPR_MODELS_ENV} to the models folder" in text, text
    assert f"{CASPR_MODELS_ENV}={tmp_path}" in text, text


@pytest.mark.slow
@pytest.mark.skipif(_CASPR_MISSING is not None, reason=_CASPR_MISSING or "")
def test_library_tests_read_the_folder_the_variable_names(tmp_path):
    # a library of one model, copied: the test finds it there
    copy = tmp_path / "models"
    shutil.copytree(
        CASPR / "examples" / "Example_spherical", copy / "examples" / "Example_spherical"
    )
    (copy / "models_list.csv").write_text("")
    text = _pytest_with_library(copy, SPHERICAL_TEST)
    assert "1 passed" in text, text
    # and only there: the same folder without the model fails to import it
    shutil.rmtree(copy / "examples")
    text = _pytest_with_library(copy, SPHERICAL_TEST)
    assert "1 failed" in text and str(copy) in text, text
