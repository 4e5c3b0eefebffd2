"""The inspection page's /api/pose under hostile requests: deep nesting, huge
numbers, wrong types, bodies that are not JSON, a wrong Content-Type, bad
Host, Origin and Content-Length headers each get a 4xx with a short JSON
error, and the server writes no traceback (tests/fuzzing.py; ``python
tools/fuzz_specs.py --class viewer`` runs more)."""

from __future__ import annotations

import os
import socket
from collections import Counter

import pytest

from tests.fuzzing import (
    RequestCase,
    StderrCapture,
    make_request_case,
    page_credentials,
    run_request_case,
)
from tests.processes import alive

_JSON = {"Content-Type": "application/json"}
_POSE = b'{"pose": "nominal"}'


def _refused(port: int) -> bool:
    with socket.socket() as sock:
        return sock.connect_ex(("127.0.0.1", port)) != 0


@pytest.fixture(scope="module")
def page(paper_robot):
    """The paper's arm on the inspection page, closed (and checked gone:
    its port and the meshcat server) after the module."""
    pytest.importorskip("meshcat")
    from cdpm.viewer import InspectionPage

    page = InspectionPage(paper_robot, "nominal")
    port, server = page.port, page.viewer.server_pid
    try:
        yield page
    finally:
        page.close()
    assert _refused(port), f"the page still listens on {port}"
    if os.path.isdir("/proc"):
        assert not alive(server), "the meshcat server still runs"


def _case(what, body=_POSE, strict=True, **headers):
    return what, body, strict, headers


CASES = [
    _case("deep nesting", b"[" * 100_000 + b"]" * 100_000),
    _case("deep natural", b'{"natural": ' + b"[" * 5000 + b"0" + b"]" * 5000 + b"}"),
    _case("deep object", b'{"a": ' * 5000 + b"0" + b"}" * 5000),
    _case("huge integer", b'{"natural": [' + b"9" * 5000 + b", 0]}"),
    _case("huge float", b'{"natural": [1e999, 0]}'),
    _case("NaN", b'{"natural": [NaN, 0]}'),
    _case("wrong type", b'{"natural": {"q1": 0}}'),
    _case("wrong pose type", b'{"pose": ["nominal"]}'),
    _case("not an object", b'"nominal"'),
    _case("not JSON", b"\xff\xfe\x00{"),
    _case("Content-Type text/plain", **{"Content-Type": "text/plain"}),
    _case("Content-Type form", **{"Content-Type": "application/x-www-form-urlencoded"}),
    _case("no Content-Type", **{"Content-Type": None}),
    _case("Host evil.example", Host="evil.example"),
    _case("Host [::1", Host="[::1"),
    _case("Host of 10,000 characters", Host="x" * 10_000),
    _case("Origin evil.example", Origin="http://evil.example"),
    _case("Origin null", Origin="null"),
    _case("Content-Length -1", **{"Content-Length": "-1"}),
    _case("Content-Length abc", **{"Content-Length": "abc"}),
]


@pytest.mark.parametrize(("what", "body", "strict", "headers"), CASES, ids=[c[0] for c in CASES])
def test_hostile_request_gets_a_4xx_without_traceback(page, what, body, strict, headers):
    port = page.port
    merged = {"Host": f"127.0.0.1:{port}", **_JSON, **page_credentials(page), **headers}
    merged = {k: v for k, v in merged.items() if v is not None}
    with StderrCapture() as text:
        outcome = run_request_case(port, RequestCase(what, merged, body, strict), text)
    assert outcome.kind.startswith("4"), outcome


def test_the_page_answers_its_own_requests(page):
    """The checks can pass: the page's own request (its Host, Origin and
    JSON) gets the panel, so the 4xx above are refusals, not a dead server."""
    port = page.port
    own = f"127.0.0.1:{port}"
    headers = {"Host": own, "Origin": f"http://{own}", **_JSON, **page_credentials(page)}
    with StderrCapture() as text:
        outcome = run_request_case(port, RequestCase("own", headers, _POSE, strict=False), text)
    assert outcome.kind == "200"


def test_seeded_requests_get_4xx_or_the_panel(page):
    outcomes = Counter()
    with StderrCapture() as text:
        for seed in range(12):
            case = make_request_case(seed, page.port, page_credentials(page))
            outcomes[run_request_case(page.port, case, text).kind] += 1
    assert sum(n for kind, n in outcomes.items() if kind.startswith("4")) > 0, outcomes


@pytest.mark.slow
def test_many_seeded_requests_get_4xx_or_the_panel(page):
    failures, outcomes = [], Counter()
    with StderrCapture() as text:
        for seed in range(12, 312):
            case = make_request_case(seed, page.port, page_credentials(page))
            try:
                outcomes[run_request_case(page.port, case, text).kind] += 1
            except AssertionError as exc:
                failures.append(str(exc)[:300])
    assert not failures, f"{len(failures)} of 300 fail:\n" + "\n".join(failures)
