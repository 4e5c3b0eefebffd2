"""Fault injection for specs and URDFs: mutate shipped models at random and
check that cdpm either refuses them with its own short error or gives a
correct, finite result.

Used by tests/test_fuzz.py (a fixed number of seeded cases in CI) and by
tools/fuzz_specs.py (as many as asked for).
"""

from __future__ import annotations

import copy
import math
import random
import signal
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

import cdpm
from cdpm.errors import CdpmError

ROOT = Path(__file__).resolve().parents[1]
MODELS = sorted(p for p in (ROOT / "models").glob("*/*.yaml") if not p.name.startswith("_"))

#: longest message a cdpm error may have
MAX_MESSAGE = 4000

#: seconds a case may take before it counts as a hang
CASE_SECONDS = 10.0

#: values put in place of spec or URDF values
JUNK = [
    None,
    True,
    False,
    "",
    "abc",
    "pi/0",
    "(-1)**0.5",
    ".nan",
    ".inf",
    "-.inf",
    "nan",
    1e308,
    -1e308,
    1e300,
    1e-300,
    -1e-300,
    0,
    -1,
    10**30,
    3.5,
    -2,
    [],
    {},
    [1, 2],
    [[[]]],
    "x" * 5000,
    {"a": 1},
    "1+" * 150 + "1",
    [0, 0, 0],
    [1e300, 0, 0],
    [".nan", 0, 0],
    "world",
    "tip",
    "c1",
    "min_norm",
    {"frame": "world"},
    ["a", "b", "c"],
]
URDF_JUNK = [
    "",
    "abc",
    "nan",
    "inf",
    "-inf",
    "1e300",
    "1e-300",
    "-1",
    "0",
    "0 0",
    "1 2 3 4",
    "nan 0 0",
    "1e300 0 0",
    "&bogus;",
    "0 0 0",
    "continuous",
    "floating",
    "x" * 3000,
]


class CaseTimeout(BaseException):
    """A case ran longer than CASE_SECONDS."""


@dataclass
class Outcome:
    """What one case did: ``"refused"`` (a cdpm error), ``"analysed"`` or
    ``"no equilibrium"``, with the message or verdict."""

    kind: str
    detail: str


def _paths(node, prefix=()):
    """Every path into a nested dict/list structure."""
    yield prefix
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _paths(value, prefix + (key,))
    elif isinstance(node, list):
        for k, value in enumerate(node):
            yield from _paths(value, prefix + (k,))


def _get(node, path):
    for key in path:
        node = node[key]
    return node


def mutate_spec(data: dict, rng: random.Random) -> dict:
    """A copy of a spec mapping with 1-3 random mutations: a value
    replaced by junk, a key deleted, an unknown key added, a list item
    repeated."""
    data = copy.deepcopy(data)
    for _ in range(rng.randint(1, 3)):
        paths = [p for p in _paths(data) if p]
        if not paths:
            break
        path = rng.choice(paths)
        parent = _get(data, path[:-1])
        op = rng.random()
        if op < 0.65:
            parent[path[-1]] = copy.deepcopy(rng.choice(JUNK))
        elif op < 0.8 and isinstance(parent, dict):
            del parent[path[-1]]
        elif op < 0.9 and isinstance(parent, dict):
            parent[rng.choice(["extra", "weight", "sum", "unit", "joint", "cable"])] = (
                copy.deepcopy(rng.choice(JUNK))
            )
        elif isinstance(parent, list):
            parent.append(copy.deepcopy(parent[path[-1]]))
    return data


def mutate_urdf(text: str, rng: random.Random) -> str:
    """A URDF text with one random attribute replaced or element dropped."""
    root = ET.fromstring(text)
    elements = [e for e in root.iter() if e.attrib]
    element = rng.choice(elements)
    if rng.random() < 0.85:
        attribute = rng.choice(sorted(element.attrib))
        element.set(attribute, rng.choice(URDF_JUNK))
    else:
        for parent in root.iter():
            if element in list(parent):
                parent.remove(element)
                break
    out = ET.tostring(root, encoding="unicode")
    if rng.random() < 0.03:
        out = '<!DOCTYPE robot [<!ENTITY a "aaaa">]>\n' + out
    return out


def make_case(model: Path, seed: int, folder: Path) -> Path:
    """Write a mutated copy of ``model`` (its spec, and sometimes its URDF)
    into ``folder``; returns the spec path."""
    rng = random.Random(seed)
    data = yaml.safe_load(model.read_text())
    urdf_name = data.get("urdf") if isinstance(data.get("urdf"), str) else None
    if urdf_name:
        urdf = (model.parent / urdf_name).read_text()
        if rng.random() < 0.35:
            urdf = mutate_urdf(urdf, rng)
        (folder / Path(urdf_name).name).write_text(urdf)
        data["urdf"] = Path(urdf_name).name
    if rng.random() < 0.85:
        data = mutate_spec(data, rng)
    spec = folder / model.name
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    return spec


def _alarm(signum, frame):
    raise CaseTimeout


def run_case(spec: Path) -> Outcome:
    """Load and analyse a (mutated) spec; raise AssertionError when cdpm
    misbehaves: an exception that is not a cdpm error, a message over
    MAX_MESSAGE characters, a non-finite verdict or margin, more than
    CASE_SECONDS."""
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, CASE_SECONDS)
    try:
        return _run(spec)
    except CaseTimeout:
        raise AssertionError(f"{spec}: took more than {CASE_SECONDS} s") from None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _run(spec: Path) -> Outcome:
    try:
        robot = cdpm.load_robot(spec)
        pose = next(iter(robot.poses), None)
        q = robot.poses[pose] if pose is not None else robot.neutral()
        report = cdpm.analyze_pose(robot, q, infeasible="report")
        text = str(report)
    except CdpmError as exc:
        message = str(exc)
        assert len(message) <= MAX_MESSAGE, (
            f"{spec}: message of {len(message)} characters: {message[:300]}"
        )
        return Outcome("refused", f"{type(exc).__name__}: {message[:200]}")
    except Exception as exc:
        raise AssertionError(f"{spec}: {type(exc).__name__} is not a cdpm error: {exc}") from exc
    if not report.feasible:
        return Outcome("no equilibrium", text[:200])
    lin = report.linearisation
    for name in ("A", "B", "C", "tension"):
        value = getattr(lin, name)
        assert np.all(np.isfinite(value)), f"{spec}: non-finite {name}"
    verdict = report.poc.verdict.name
    assert verdict in ("YES", "NO", "MARGINAL"), f"{spec}: verdict {verdict!r}"
    margin = report.poc.margin
    if verdict == "YES":
        assert margin is not None and math.isfinite(margin), f"{spec}: YES with margin {margin}"
    r, err = report.reach_margin
    # r_T is finite, or NaN with an infinite error: "not resolvable" (a mode
    # grows too fast within T), which the report says in words
    # or NaN with a NaN error: "not computed" (too many facet candidates)
    resolvable = math.isfinite(r) and math.isfinite(err)
    assert resolvable or (math.isnan(r) and not math.isfinite(err)), f"{spec}: r_T {r} +- {err}"
    if not resolvable:
        reason = "not resolvable" if math.isinf(err) else "not computed"
        assert reason in text, f"{spec}: r_T NaN without a reason"
    return Outcome("analysed", f"POC {verdict}")


# --------------------------------------------------------------------------
# CASPR XML

CASPR_JUNK = URDF_JUNK + ["-3", "1 2", "0;0;0", "abc def", "1e308", "3000", "-1e308", "  "]


#: CASPR models left out of the fuzzing: their unmutated import and
#: analysis alone takes longer than CASE_SECONDS (8S_neck: 24 joints, 76
#: cables, about 12 s, nearly all in the reach margin's zonotope with 912
#: generators)
SLOW_CASPR = frozenset({"8S_neck"})


def caspr_models(library: Path) -> list[Path]:
    """Bodies files of the CASPR library (each beside its cables file),
    without SLOW_CASPR."""
    return sorted(
        p
        for p in library.glob("**/*_bodies.xml")
        if p.with_name(p.name.replace("_bodies.xml", "_cables.xml")).is_file()
        and p.name.removesuffix("_bodies.xml") not in SLOW_CASPR
    )


def mutate_xml(text: str, rng: random.Random) -> str:
    """An XML text with 1-3 random attributes or texts replaced, elements
    dropped or repeated, or an encoding or entity declaration added."""
    head = ""
    if text.startswith("<?xml"):
        head, _, text = text.partition("?>")
        head += "?>"
    root = ET.fromstring(text.split(">", 1)[1] if text.lstrip().startswith("<!DOCTYPE") else text)
    for _ in range(rng.randint(1, 3)):
        elements = list(root.iter())
        element = rng.choice(elements)
        op = rng.random()
        if op < 0.4 and element.attrib:
            element.set(rng.choice(sorted(element.attrib)), rng.choice(CASPR_JUNK))
        elif op < 0.75:
            element.text = rng.choice(CASPR_JUNK)
        elif op < 0.9:
            for parent in root.iter():
                if element in list(parent):
                    parent.remove(element)
                    break
        else:
            for parent in root.iter():
                if element in list(parent):
                    for _ in range(rng.choice([1, 5, 200])):
                        parent.append(copy.deepcopy(element))
                    break
    out = ET.tostring(root, encoding="unicode")
    r = rng.random()
    if r < 0.03:
        return '<?xml version="1.0" encoding="klingon"?>\n' + out
    if r < 0.06:
        return '<!DOCTYPE x [<!ENTITY a "aaaa">]>\n' + out
    return (head or '<?xml version="1.0"?>') + "\n" + out


def make_caspr_case(bodies: Path, seed: int, folder: Path) -> tuple[Path, Path, Path | None]:
    """Mutated copies of a CASPR model's bodies, cables and operational
    spaces files in ``folder``."""
    rng = random.Random(seed)
    stem = bodies.name.replace("_bodies.xml", "")
    files = [bodies, bodies.with_name(f"{stem}_cables.xml")]
    ops = bodies.with_name(f"{stem}_operational_spaces.xml")
    if ops.is_file():
        files.append(ops)
    which = rng.randrange(len(files))
    written = []
    for k, path in enumerate(files):
        text = path.read_text(encoding="utf-8", errors="replace")
        if k == which:
            text = mutate_xml(text, rng)
        target = folder / path.name
        target.write_text(text, encoding="utf-8")
        written.append(target)
    return written[0], written[1], written[2] if len(written) > 2 else None


def run_caspr_case(bodies: Path, cables: Path, ops: Path | None, out: Path) -> Outcome:
    """Import (and when it imports, analyse) a mutated CASPR model; as
    :func:`run_case`, cdpm's own errors or finite results only."""
    from cdpm.caspr import import_caspr

    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, CASE_SECONDS)
    try:
        try:
            result = import_caspr(bodies, cables, out, operational_spaces_xml=ops)
        except CdpmError as exc:
            message = str(exc)
            assert len(message) <= MAX_MESSAGE, f"{bodies}: message of {len(message)} characters"
            return Outcome("refused", f"{type(exc).__name__}: {message[:200]}")
        except Exception as exc:
            raise AssertionError(
                f"{bodies}: {type(exc).__name__} is not a cdpm error: {exc}"
            ) from exc
        return _run(result.spec_path)
    except CaseTimeout:
        raise AssertionError(f"{bodies}: took more than {CASE_SECONDS} s") from None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
