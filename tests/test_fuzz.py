"""Seeded fault injection: mutated specs and URDFs of the shipped models give
cdpm's own short errors or correct finite results (tests/fuzzing.py; run
more cases with tools/fuzz_specs.py)."""

from __future__ import annotations

import os
import tempfile
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.fuzzing import (
    MODELS,
    caspr_models,
    make_case,
    make_caspr_case,
    run_case,
    run_caspr_case,
)

#: cases per CI run (CDPM_FUZZ_CASES overrides)
CASES = int(os.environ.get("CDPM_FUZZ_CASES", "500"))

OUTCOMES: Counter = Counter()


@settings(
    max_examples=CASES,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@pytest.mark.slow
@given(model=st.sampled_from(MODELS), seed=st.integers(0, 2**32 - 1))
def test_mutated_models_fail_cleanly_or_give_finite_results(model, seed):
    with tempfile.TemporaryDirectory() as folder:
        spec = make_case(model, seed, Path(folder))
        OUTCOMES[run_case(spec).kind] += 1


def test_fuzzing_reaches_both_refusals_and_analyses():
    """The cases above are not all refused at the first line: some analyse."""
    if not OUTCOMES:  # run alone
        test_mutated_models_fail_cleanly_or_give_finite_results()
    assert OUTCOMES["refused"] > 0
    assert OUTCOMES["analysed"] > 0


#: CASPR cases per CI run (CDPM_FUZZ_CASPR_CASES overrides)
CASPR_CASES = int(os.environ.get("CDPM_FUZZ_CASPR_CASES", "200"))


def _caspr_library():
    from tests.conftest import caspr_models as library

    folder, reason = library()
    return folder, reason


_CASPR_FOLDER, _CASPR_SKIP = _caspr_library()
_CASPR_MODELS = caspr_models(_CASPR_FOLDER) if _CASPR_SKIP is None else []


@pytest.mark.skipif(_CASPR_SKIP is not None, reason=str(_CASPR_SKIP))
@settings(
    max_examples=CASPR_CASES,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@pytest.mark.slow
@given(index=st.integers(0, max(len(_CASPR_MODELS) - 1, 0)), seed=st.integers(0, 2**32 - 1))
def test_mutated_caspr_models_fail_cleanly_or_give_finite_results(index, seed):
    import warnings

    with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # CasprWarnings about the mutated files
        bodies, cables, ops = make_caspr_case(_CASPR_MODELS[index], seed, Path(folder))
        run_caspr_case(bodies, cables, ops, Path(folder) / "out")
