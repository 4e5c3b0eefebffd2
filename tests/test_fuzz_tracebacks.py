"""The inputs that last ended in tracebacks, fuzzed: huge YAML integers,
alias chains, sexagesimal numbers, CASPR joint limits with q_min > q_max,
``cdpm picture`` dpi and titles, zero and indefinite inertias in URDFs. Each
gives cdpm's own short error or a clean result (finite verdicts and margins,
a written picture), never a raw exception (tests/fuzzing.py; ``python
tools/fuzz_specs.py --class tracebacks`` runs more)."""

from __future__ import annotations

from collections import Counter

import pytest

from tests.fuzzing import (
    TRACEBACK_KINDS,
    make_traceback_case,
    run_picture_case,
    run_traceback_case,
)


@pytest.mark.parametrize("kind", TRACEBACK_KINDS)
def test_each_class_fails_cleanly_or_gives_a_clean_result(tmp_path, kind):
    outcomes = Counter()
    for seed in range(3):
        folder = tmp_path / str(seed)
        folder.mkdir()
        case = make_traceback_case(seed, kind)
        outcomes[run_traceback_case(case, folder).kind] += 1
    assert sum(outcomes.values()) == 3


@pytest.mark.parametrize(
    ("arguments", "outcome"),
    [
        (["--title", "$\\undefinedcommand$"], "refused or picture"),
        (["--title", "$$$$"], "refused or picture"),
        (["--dpi", "1" * 5000], "refused"),
        (["--dpi", "nan"], "refused"),
        (["--dpi", "72", "--title", "x" * 1000], "picture"),
    ],
    ids=["unknown TeX command", "empty maths", "5000-digit dpi", "nan dpi", "longest title"],
)
def test_picture_arguments_fail_cleanly(tmp_path, arguments, outcome):
    pytest.importorskip("matplotlib")
    result = run_picture_case(arguments, tmp_path)
    assert result.kind in outcome.split(" or "), result


@pytest.mark.slow
def test_many_seeded_cases_fail_cleanly_or_give_clean_results(tmp_path):
    failures, outcomes = [], Counter()
    for seed in range(300):
        folder = tmp_path / str(seed)
        folder.mkdir()
        case = make_traceback_case(seed)
        try:
            outcomes[(case.kind, run_traceback_case(case, folder).kind)] += 1
        except AssertionError as exc:
            failures.append(str(exc)[:300])
    assert not failures, f"{len(failures)} of 300 fail:\n" + "\n".join(failures)
    assert {kind for kind, outcome in outcomes if outcome != "refused"} >= {"inertia", "picture"}
