"""Names: joint, cable, output and pose names that clash with map names,
repeat, hold control characters or unicode, or are very long are refused
with cdpm's error naming the problem, or work end to end (``cdpm analyze``
prints them with no raw control character; a map labels with them)
(tests/fuzzing.py; ``python tools/fuzz_specs.py --class names`` runs more)."""

from __future__ import annotations

import contextlib
import io
from collections import Counter

import pytest

from tests.fuzzing import NameCase, make_name_case, raw_controls, run_name_case, write_name_case


@pytest.mark.parametrize(
    ("kind", "index", "name", "outcome", "says"),
    [
        ("cable", 3, "c2", "refused", "duplicate cable name 'c2'"),
        ("output", 1, "tip_x", "refused", "duplicate output name 'tip_x'"),
        ("pose", 2, "nominal", "refused", "key 'nominal' is given twice"),
        ("joint", 0, "q2", "refused", "'q2'"),
        ("cable", 0, "c\x1b[31m1", "refused", "non-printable character '\\x1b'"),
        ("pose", 1, "a\nb", "refused", "non-printable character '\\n'"),
        ("output", 0, "x\u202ey", "refused", "non-printable character '\\u202e'"),
        ("joint", 1, "q\x0c2", "refused", "not well-formed XML"),
        ("joint", 1, "poc", "refused", "has the name of a map variable"),
        ("cable", 2, 7, "refused", "expected a non-empty string, got 7"),
        ("cable", 0, "poc", "works", "poc"),
        ("output", 1, "ángulo_🦾", "works", "ángulo_🦾"),
        ("joint", 0, "關節", "works", "關節"),
        ("pose", 0, "x" * 5000, "works", "x" * 5000),
        ("pose", 1, "--pose", "works", "--pose"),
    ],
)
def test_name_is_refused_or_works_end_to_end(tmp_path, kind, index, name, outcome, says):
    result = run_name_case(NameCase(kind, index, name, "chosen"), tmp_path)
    assert result.kind == outcome, result
    assert says in result.detail or result.kind == "works", result.detail


def test_raw_controls_finds_what_a_terminal_would_obey():
    assert raw_controls("tip_x = 1 m\nq1 = 0.5 rad") == []
    assert raw_controls("a\x1b[31mb\tc\u202ed\u2028") == ["\t", "\x1b", "\u2028", "\u202e"]
    assert raw_controls("👩\u200d🔬 ángulo") == []


def test_seeded_names_are_refused_cleanly_or_work(tmp_path):
    outcomes = Counter()
    for seed in range(16):
        case = make_name_case(seed)
        folder = tmp_path / str(seed)
        folder.mkdir()
        outcomes[run_name_case(case, folder).kind] += 1
    assert outcomes["refused"] > 0 and outcomes["works"] > 0, outcomes


def test_pose_named_like_a_negative_number_is_found_by_the_command_line(tmp_path):
    from cdpm.cli import main

    spec = write_name_case(NameCase("pose", 0, "-1", "chosen"), tmp_path)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["analyze", str(spec), "--pose", "-1"])
    assert code == 0, err.getvalue()


@pytest.mark.slow
def test_many_seeded_names_are_refused_cleanly_or_work(tmp_path):
    outcomes = Counter()
    failures = []
    for seed in range(16, 316):
        case = make_name_case(seed)
        folder = tmp_path / str(seed)
        folder.mkdir()
        try:
            outcomes[(case.category, run_name_case(case, folder).kind)] += 1
        except AssertionError as exc:
            failures.append(str(exc)[:300])
    assert not failures, f"{len(failures)} of 300 fail:\n" + "\n".join(failures)
    assert {c for c, kind in outcomes if kind == "works"} >= {"map", "unicode", "long", "odd"}
