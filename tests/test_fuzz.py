"""Seeded fault injection: mutated specs and URDFs of the shipped models give
cdpm's own short errors or correct finite results (tests/fuzzing.py; run
more cases with tools/fuzz_specs.py)."""

from __future__ import annotations

import os
import tempfile
from collections import Counter
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.fuzzing import MODELS, make_case, run_case

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
