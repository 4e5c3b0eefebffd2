"""Fault injection for specs and URDFs: mutate shipped models at random and
check that cdpm either refuses them with its own short error or gives a
correct, finite result.

Besides mutated specs, URDFs and CASPR files, seeded case generators for
four more classes, each a ``make_*_case(seed)`` and a ``run_*_case`` that
asserts its invariant:

- scale: a model with every mass times 10**k and every length times 10**j
  has the unit model's POC verdicts (or cdpm's refusal of magnitudes
  outside its range);
- names: renamed joints, cables, outputs and poses are refused with cdpm's
  error naming the problem, or work end to end with no raw control
  character in what cdpm prints;
- viewer requests: hostile requests to the inspection page's /api/pose
  get a 4xx with a short JSON error and no traceback;
- the last tracebacks: huge YAML integers, alias chains, sexagesimal
  numbers, crossed CASPR joint limits, picture dpi and titles, inertias.

Used by tests/test_fuzz.py and tests/test_fuzz_*.py (a fixed number of
seeded cases in CI) and by tools/fuzz_specs.py (as many as asked for).
"""

from __future__ import annotations

import copy
import functools
import json
import math
import random
import re
import shutil
import signal
import sys
import unicodedata
import xml.etree.ElementTree as ET
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

import cdpm
from cdpm.errors import CdpmError, short_repr
from cdpm.model.coordinates import coordinate_units
from cdpm.verdicts import STATUS_CODES, STATUS_LABELS, VERDICT_LABELS
from tests.scaled_models import scaled_copy

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


class _CaseClock:
    """``with _CaseClock(label):`` turns a case that runs longer than
    CASE_SECONDS into an AssertionError naming ``label``."""

    def __init__(self, label: str, seconds: float = CASE_SECONDS) -> None:
        self.label, self.seconds = label, seconds

    def __enter__(self) -> None:
        self._previous = signal.signal(signal.SIGALRM, _alarm)
        signal.setitimer(signal.ITIMER_REAL, self.seconds)

    def __exit__(self, kind, value, traceback) -> bool:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, self._previous)
        if kind is CaseTimeout:
            raise AssertionError(f"{self.label}: took more than {self.seconds} s") from None
        return False


# --------------------------------------------------------------------------
# scale: every mass times 10**k, every length times 10**j


#: shipped models with a URDF of their own and no joint damping (damping
#: would have to follow the time scale sqrt(length / gravity) as well)
SCALE_MODELS = [
    ROOT / "models" / name / f"{name}.yaml"
    for name in ("two_link_vertical", "two_link_planar", "spatial_8cable", "multilink_arm")
]

#: exponents the scale cases draw from: masses 10**k, lengths 10**j
SCALE_MASS_EXPONENTS = range(-9, 10)
SCALE_LENGTH_EXPONENTS = range(-3, 4)

#: poses of a scale case besides the spec's named poses
SCALE_RANDOM_POSES = 6


@dataclass
class ScaleCase:
    """A shipped model, the exponents of its scaled copy (masses times
    10**mass_exp, lengths times 10**length_exp) and the poses compared, as
    natural coordinates of the unit model (N, nv) [rad or m]."""

    model: Path
    mass_exp: int
    length_exp: int
    natural: np.ndarray

    def __str__(self) -> str:
        return f"{self.model.stem} with masses x 1e{self.mass_exp}, lengths x 1e{self.length_exp}"


def write_scaled_model(model: Path, folder: Path, mass_exp: int, length_exp: int) -> Path:
    """A copy of ``model`` in ``folder`` with masses times 10**mass_exp and
    lengths times 10**length_exp (:func:`tests.scaled_models.scaled_copy`),
    tension bounds [0, inf) and the least-norm equilibrium without
    pretension; returns its spec path."""
    data = yaml.safe_load(model.read_text())
    return scaled_copy(
        model,
        model.parent / data["urdf"],
        folder,
        10.0**mass_exp,
        10.0**length_exp,
        equilibrium={"method": "min_norm"},
        unbounded=True,
    )


def make_scale_case(
    model: Path, seed: int, mass_exp: int | None = None, length_exp: int | None = None
) -> ScaleCase:
    """A seeded scale case of ``model``: the exponents (drawn from
    SCALE_MASS_EXPONENTS and SCALE_LENGTH_EXPONENTS where not given; one in
    five cases leaves each at 0) and the spec's named poses plus
    SCALE_RANDOM_POSES random poses near them (0.3 rad, 0.05 robot sizes)."""
    rng = random.Random(seed)
    if mass_exp is None:
        mass_exp = rng.choice(SCALE_MASS_EXPONENTS) if rng.random() < 0.8 else 0
    if length_exp is None:
        length_exp = rng.choice(SCALE_LENGTH_EXPONENTS) if rng.random() < 0.8 else 0
    robot = cdpm.load_robot(model)
    named = np.array([robot.to_natural(q) for q in robot.poses.values()])
    metres = np.array(coordinate_units(robot.model)) == "m"
    step = np.where(metres, 0.05 * robot.size, 0.3)
    draw = np.random.default_rng(seed)
    around = named[draw.integers(len(named), size=SCALE_RANDOM_POSES)]
    natural = np.vstack([named, around + draw.normal(size=around.shape) * step])
    return ScaleCase(model, mass_exp, length_exp, natural)


def scale_range_problems(model: Path, mass_exp: int, length_exp: int) -> list[str]:
    """What puts ``model`` scaled by 10**mass_exp kg and 10**length_exp m
    outside the magnitudes cdpm analyses (MODEL_MASS_RANGE,
    MODEL_INERTIA_MAX, MAX_MODEL_LENGTH): the scaled copy must be refused
    for exactly these."""
    from cdpm.model.robot import MAX_MODEL_LENGTH, MODEL_INERTIA_MAX, MODEL_MASS_RANGE

    robot = cdpm.load_robot(model)
    mass, length = 10.0**mass_exp, 10.0**length_exp
    problems = []
    for j in range(1, robot.model.njoints):
        inertia = robot.model.inertias[j]
        m = float(inertia.mass) * mass
        if m != 0 and not MODEL_MASS_RANGE[0] <= m <= MODEL_MASS_RANGE[1]:
            problems.append(f"mass {m:g} kg")
        moment = float(np.abs(np.linalg.eigvalsh(np.array(inertia.inertia))).max())
        if moment * mass * length**2 > MODEL_INERTIA_MAX:
            problems.append(f"moment of inertia {moment * mass * length**2:g} kg m^2")
        offset = float(np.abs(robot.model.jointPlacements[j].translation).max()) * length
        if offset > MAX_MODEL_LENGTH:
            problems.append(f"joint offset {offset:g} m")
    data = yaml.safe_load(model.read_text())
    points = [p["point"] for c in data["cables"] for p in c["route"]]
    points += [o["point"] for o in data.get("outputs", []) if "point" in o]
    far = max((abs(float(v)) for point in points for v in point), default=0.0) * length
    if far > MAX_MODEL_LENGTH:
        problems.append(f"attachment point {far:g} m from its frame")
    return problems


def _scaled_results(case: ScaleCase, folder: Path, mass_exp: int, length_exp: int):
    """Status, POC verdicts and outputs (lengths divided by the scale) of
    the scaled model at the case's poses (lengths among the natural
    coordinates scaled too), or the cdpm error that refused it."""
    spec = write_scaled_model(case.model, folder, mass_exp, length_exp)
    try:
        robot = cdpm.load_robot(spec)
        metres = np.array(coordinate_units(robot.model)) == "m"
        natural = case.natural * np.where(metres, 10.0**length_exp, 1.0)
        values = cdpm.evaluate_poses(robot, natural, margin=False)
    except CdpmError as exc:
        message = str(exc)
        assert len(message) <= MAX_MESSAGE, f"{case}: message of {len(message)} characters"
        return exc
    except Exception as exc:
        raise AssertionError(f"{case}: {type(exc).__name__} is not a cdpm error: {exc}") from exc
    metres_out = np.array(robot.output_units) == "m"
    return {
        "status": values["status"],
        "poc": values["poc"],
        "y": values["y"] / np.where(metres_out, 10.0**length_exp, 1.0),
        "size": robot.size / 10.0**length_exp,
    }


def _verdict_text(results: dict, i: int) -> str:
    status, poc = int(results["status"][i]), int(results["poc"][i])
    return f"{STATUS_LABELS[status]}, POC {VERDICT_LABELS[poc]}"


def run_scale_case(case: ScaleCase, folder: Path) -> Outcome:
    """Compare the scaled model with the unit one (the same model with its
    tension bounds and pretension dropped, at scale 1); raise
    AssertionError unless (a) both give the same status and POC verdict at
    every pose and outputs that scale with the lengths, or (b) the scaled
    model lies outside the magnitudes cdpm analyses
    (:func:`scale_range_problems`) and is refused with cdpm's error saying so."""
    with _CaseClock(str(case), 4 * CASE_SECONDS):
        unit = _scaled_results(case, folder / "unit", 0, 0)
        scaled = _scaled_results(case, folder / "scaled", case.mass_exp, case.length_exp)
        out_of_range = scale_range_problems(case.model, case.mass_exp, case.length_exp)
    assert isinstance(unit, dict), f"{case.model.stem} refused at scale 1: {unit}"
    if out_of_range:
        assert isinstance(scaled, CdpmError), (
            f"{case}: analysed although outside cdpm's range ({'; '.join(out_of_range)})"
        )
        assert "cdpm analyses masses of" in str(scaled), (
            f"{case}: refused for another reason: {scaled}"
        )
        return Outcome("refused (out of range)", "; ".join(out_of_range))
    assert isinstance(scaled, dict), (
        f"{case}: refused although within cdpm's range: "
        f"{type(scaled).__name__}: {str(scaled)[:300]}"
    )
    differ = []
    for i, natural in enumerate(case.natural):
        before, after = _verdict_text(unit, i), _verdict_text(scaled, i)
        if before != after:
            differ.append(
                f"pose {np.round(natural, 4).tolist()}: {before} at scale 1, {after} scaled"
            )
    assert not differ, f"{case}: verdicts differ at {len(differ)} poses: " + "; ".join(differ[:4])
    ok = unit["status"] == STATUS_CODES["ok"]
    assert np.all(np.isfinite(scaled["y"][ok])), f"{case}: non-finite outputs"
    np.testing.assert_allclose(
        scaled["y"][ok], unit["y"][ok], rtol=0, atol=1e-9 * unit["size"], err_msg=str(case)
    )
    counts = Counter(VERDICT_LABELS[int(v)] for v in scaled["poc"])
    return Outcome(
        "same verdicts", ", ".join(f"{n} {label}" for label, n in sorted(counts.items()))
    )


# --------------------------------------------------------------------------
# names: joints, cables, outputs and poses renamed


#: the model whose names the name cases change (joints q1, q2; cables c1-c4;
#: outputs tip_x, tip_z; poses nominal, horizontal, elbow_up)
NAMES_MODEL = ROOT / "models" / "two_link_vertical" / "two_link_vertical.yaml"

#: characters that rewrite what a terminal shows or end a line
CONTROL_CHARACTERS = [
    "\x00",
    "\x07",
    "\x08",
    "\t",
    "\n",
    "\r",
    "\x0b",
    "\x0c",
    "\x1b",
    "\x1b[31m",
    "\x1b]0;x\x07",
    "\x7f",
    "\x85",
    "\x9b",
    "\u200b",
    "\u200e",
    "\u2028",
    "\u2029",
    "\u202e",
    "\u2066",
    "\ufeff",
    "\ud800",
    "\U000e0001",
]

#: printable names beyond ASCII
UNICODE_NAMES = [
    "ángulo",
    "關節",
    "ジョイント",
    "Ω",
    "Ω",
    "e\u0301",
    "🦾",
    "👩‍🔬",
    "Ⅻ",
    "𝑞₁",
    "ß",
    "İ",
    "ǅ",
    "\u00a0x",
]

#: names that look like something else to YAML, a shell, a store or a parser
ODD_NAMES = [
    "",
    " ",
    " c1",
    "c1 ",
    "a b",
    "a/b",
    "..",
    ".hidden",
    "zarr.json",
    "a.b",
    "pi/2",
    "1",
    "0x1f",
    "true",
    "null",
    "~",
    "-",
    "*",
    "&a",
    "#x",
    "a: b",
    "[1]",
    "{x}",
    "'",
    '"',
    "\\",
    "%s",
    "<tip>",
    "&amp;",
    "--pose",
    "-h",
    "$(rm)",
    "C:\\x",
    "NaN",
    "inf",
    "q1 ",
]

#: values that are not names at all (YAML numbers, booleans, null, lists)
NOT_NAMES = [1, 1.5, -0.0, True, None, [], {}, ["c1"], {"name": "c1"}, 10**30]


@dataclass
class NameCase:
    """One renamed item: which kind (joint, cable, output, pose), its index
    among its kind, the new name and the category it was drawn from."""

    kind: str
    index: int
    name: object
    category: str

    def __str__(self) -> str:
        return f"{self.kind} {self.index} named {short_repr(self.name, 60)} ({self.category})"


def _existing_names(data: dict) -> dict[str, list[str]]:
    return {
        "joint": ["q1", "q2"],
        "cable": [c["name"] for c in data["cables"]],
        "output": [o["name"] for o in data["outputs"]],
        "pose": list(data["poses"]),
    }


def make_name_case(seed: int) -> NameCase:
    """A seeded name case: a kind, an item of it and a new name from one
    category (map names, duplicates, control characters, unicode, very long
    names, odd text, non-names)."""
    from cdpm.model._spec_parts import MAP_NAMES

    rng = random.Random(seed)
    data = yaml.safe_load(NAMES_MODEL.read_text())
    names = _existing_names(data)
    kind = rng.choice(sorted(names))
    index = rng.randrange(len(names[kind]))
    category = rng.choice(["map", "duplicate", "control", "unicode", "long", "odd", "not a name"])
    base = rng.choice([names[kind][index], "arm", "x"])
    if category == "map":
        name = rng.choice(sorted(MAP_NAMES) + ["x", "y", "q1", "cable", "output", "pose"])
        name = rng.choice([name, name.upper(), name.capitalize()])
    elif category == "duplicate":
        same_kind = [n for n in names[kind] if n != names[kind][index]]
        any_kind = [n for ns in names.values() for n in ns if n != names[kind][index]]
        name = rng.choice(same_kind if rng.random() < 0.7 else any_kind)
    elif category == "control":
        k = rng.randrange(len(base) + 1)
        name = base[:k] + rng.choice(CONTROL_CHARACTERS) + base[k:]
    elif category == "unicode":
        name = rng.choice(UNICODE_NAMES) + rng.choice(["", base, "_" + base])
    elif category == "long":
        name = (base * 100_000)[: rng.choice([64, 200, 255, 256, 1000, 4097, 100_000])]
    elif category == "odd":
        name = rng.choice(ODD_NAMES)
    else:
        name = copy.deepcopy(rng.choice(NOT_NAMES))
    if kind == "joint" and not isinstance(name, str):
        name = str(name)  # a URDF attribute is text
    return NameCase(kind, index, name, category)


def _flow(value, allow_unicode: bool) -> str:
    """``value`` as one line of YAML (a string with a non-printable
    character double-quoted, with escapes)."""
    style = '"' if isinstance(value, str) and not value.isprintable() else None
    text = yaml.safe_dump(
        value,
        default_flow_style=True,
        default_style=style,
        allow_unicode=allow_unicode,
        width=10**9,
    )
    return text.rstrip("\n").removesuffix("\n...")  # not strip(): names may end in U+00A0


def write_name_case(case: NameCase, folder: Path) -> Path:
    """The names model with the case's item renamed, in ``folder``; returns
    the spec path. Poses are written as YAML text, so a duplicate pose name
    is a repeated key and a list is a key YAML cannot hash."""
    data = yaml.safe_load(NAMES_MODEL.read_text())
    urdf = (NAMES_MODEL.parent / data["urdf"]).read_text()
    old = _existing_names(data)[case.kind][case.index]
    if case.kind == "joint":
        root = ET.fromstring(urdf)
        for joint in root.iter("joint"):
            if joint.get("name") == old:
                joint.set("name", case.name)
        urdf = ET.tostring(root, encoding="unicode")
    elif case.kind == "cable":
        data["cables"][case.index]["name"] = case.name
    elif case.kind == "output":
        data["outputs"][case.index]["name"] = case.name
    unicode = len(str(case.name)) % 2 == 0  # raw unicode in half the files, escapes in the rest
    poses = data.pop("poses")
    lines = ["poses:"]
    for i, (name, value) in enumerate(poses.items()):
        key = case.name if case.kind == "pose" and i == case.index else name
        key = _flow(key, unicode)
        # YAML's implicit keys end at 1024 characters: longer ones explicit
        lines.append(f"  ? {key}\n  :" if len(key) > 1000 else f"  {key}:")
        lines[-1] += f" {_flow(value, unicode)}"
    (folder / data["urdf"]).write_text(urdf)
    text = yaml.safe_dump(data, sort_keys=False, allow_unicode=unicode, width=10**9)
    spec = folder / NAMES_MODEL.name
    spec.write_text(text + "\n".join(lines) + "\n", encoding="utf-8", errors="surrogatepass")
    return spec


def raw_controls(text: str) -> list[str]:
    """The characters of ``text`` that must not reach a terminal raw
    (controls but newline, format characters such as bidirectional
    overrides, line and paragraph separators, lone surrogates)."""
    return sorted(
        {
            ch
            for ch in text
            if ch != "\n"
            and unicodedata.category(ch) in ("Cc", "Cf", "Cs", "Zl", "Zp")
            and ch != "\u200d"  # the zero-width joiner of emoji sequences
        }
    )


def run_name_case(case: NameCase, folder: Path) -> Outcome:
    """Load the renamed model; raise AssertionError unless it is refused
    with a short cdpm error that names a problem and prints no raw control
    character, or it works end to end: ``cdpm analyze`` of the renamed pose
    (or the first) exits 0 with a report that shows the name and no raw
    control character, and a two-pose map labels its coordinates, cables
    and outputs with the names."""
    spec = write_name_case(case, folder)
    _warm_up_maps()
    with _CaseClock(str(case)):
        try:
            robot = cdpm.load_robot(spec)
        except CdpmError as exc:
            message = str(exc)
            assert len(message) <= MAX_MESSAGE, f"{case}: message of {len(message)} characters"
            bad = raw_controls(message)
            assert not bad, f"{case}: the error prints raw {bad}: {message[:300]!r}"
            assert re.search(r"name|YAML|XML|joint|cable|output|pose|coordinate", message), (
                f"{case}: the error does not say which name: {message[:300]!r}"
            )
            return Outcome("refused", f"{type(exc).__name__}: {message[:200]}")
        except Exception as exc:
            raise AssertionError(
                f"{case}: {type(exc).__name__} is not a cdpm error: {exc}"
            ) from exc
        return _name_end_to_end(case, robot, spec)


@functools.cache
def _warm_up_maps() -> None:
    """One small map of the names model, outside any case's clock: the
    first map of a process imports xarray and loads the compiled kernels."""
    robot = cdpm.load_robot(NAMES_MODEL)
    cdpm.workspace_map(robot, {c: np.array([0.1, 0.2]) for c in robot.coordinate_names})


def _name_end_to_end(case: NameCase, robot, spec: Path) -> Outcome:
    import contextlib
    import io

    from cdpm.cli import main

    names = {
        "joint": list(robot.coordinate_names),
        "cable": list(robot.cable_names),
        "output": list(robot.output_names),
        "pose": list(robot.poses),
    }[case.kind]
    assert str(case.name) in names or case.kind == "pose", f"{case}: loaded as {names}"
    pose = str(case.name) if case.kind == "pose" else next(iter(robot.poses))
    assert pose in robot.poses, f"{case}: pose {pose!r} missing from {list(robot.poses)}"
    out, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            # --pose=NAME: a name such as "--pose" or "-h" is not taken for an option
            code = main(["analyze", str(spec), f"--pose={pose}"])
    except SystemExit as exc:
        code = exc.code
    except Exception as exc:
        raise AssertionError(f"{case}: cdpm analyze raised {type(exc).__name__}: {exc}") from exc
    text = out.getvalue() + err.getvalue()
    assert code == 0, f"{case}: cdpm analyze exited {code}: {text[-300:]!r}"
    assert "Traceback" not in text, f"{case}: traceback: {text[-300:]!r}"
    bad = raw_controls(text)
    assert not bad, f"{case}: cdpm analyze prints raw {bad}"
    if case.kind in ("cable", "output"):
        assert str(case.name) in text, f"{case}: the report does not show the name"
    ds = cdpm.workspace_map(robot, {c: np.array([0.1, 0.2]) for c in robot.coordinate_names})
    assert [str(d) for d in ds["poc"].dims] == list(robot.coordinate_names), f"{case}: map dims"
    assert [str(c) for c in ds["cable"].values] == list(robot.cable_names), f"{case}: map cables"
    assert [str(o) for o in ds["output"].values] == list(robot.output_names), f"{case}: outputs"
    return Outcome("works", f"{case.kind} {short_repr(case.name, 40)}")


# --------------------------------------------------------------------------
# viewer: requests to the inspection page's /api/pose


@dataclass
class RequestCase:
    """One raw HTTP request to the page: what it tries, its method, path,
    headers and body, and whether only a 4xx answer is right (``strict``)
    or a 200 is too (a body that may be a valid pose)."""

    what: str
    headers: dict
    body: bytes
    strict: bool = True
    path: str = "/api/pose"

    def __str__(self) -> str:
        return f"{self.what}: {short_repr(self.body.decode('latin-1'), 60)}"


def _nested(depth: int, leaf: str = "0") -> str:
    return "[" * depth + leaf + "]" * depth


def _bad_bodies(rng: random.Random) -> list[tuple[str, bytes]]:
    """(what, body) of request bodies that are not a pose: a 4xx is the
    only right answer."""
    depth = rng.choice([50, 999, 1000, 5000, 100_000, 500_000])
    digits = rng.choice([4301, 5000, 100_000])
    return [
        ("deep nesting", _nested(depth).encode()),
        ("deep natural", ('{"natural": ' + _nested(depth) + "}").encode()),
        ("deep object", ('{"a": ' * depth + "0" + "}" * depth).encode()),
        ("deep pose", ('{"pose": ' + _nested(depth, '"nominal"') + "}").encode()),
        ("huge integer", ('{"natural": [' + "9" * digits + ", 0]}").encode()),
        ("huge float", b'{"natural": [1e999, 0]}'),
        ("NaN", b'{"natural": [NaN, 0]}'),
        ("Infinity", b'{"natural": [Infinity, -Infinity]}'),
        (
            "wrong type",
            rng.choice(
                [
                    b'{"natural": "abc"}',
                    b'{"natural": {}}',
                    b'{"natural": true}',
                    b'{"natural": [true, false]}',
                    b'{"natural": [[0, 0]]}',
                    b'{"natural": [0, 0, 0]}',
                    b'{"natural": [{}, []]}',
                ]
            ),
        ),
        (
            "wrong pose",
            rng.choice(
                [
                    b'{"pose": 1}',
                    b'{"pose": []}',
                    b'{"pose": {}}',
                    b'{"pose": true}',
                    b'{"pose": "nominal\\u0000"}',
                    b'{"pose": "\\ud800"}',
                    b'{"pose": "' + b"x" * 500_000 + b'"}',
                ]
            ),
        ),
        ("both", b'{"natural": [0, 0], "pose": "nominal"}'),
        ("neither", rng.choice([b"{}", b'{"x": 1}', b"", b"null"])),
        ("not an object", rng.choice([b"[]", b"1", b'"nominal"', b"true", b"NaN", b"-Infinity"])),
        (
            "not JSON",
            rng.choice(
                [
                    b"\xff\xfe\x00",
                    b"natural=1",
                    b"{'pose': 'nominal'}",
                    b"{",
                    b'{"pose": "nominal"',
                    b"\x00" * 100,
                    "☃".encode(),
                    b'{"pose": "nominal"}}',
                    bytes(rng.randrange(256) for _ in range(200)),
                ]
            ),
        ),
    ]


#: bodies that may be a pose: a 200 (with the panel) or a 4xx is right
_MAYBE_BODIES = [
    b'{"natural": [0.1, 0.2]}',
    b'{"natural": ["pi/6", "pi/3"]}',
    b'{"natural": [1e308, -1e308]}',
    b'{"natural": [5e-324, 0]}',
    b'{"pose": "nominal"}',
    b'{"pose": "nominal", "extra": [1, 2]}',
    b'{"natural": [0.1, 0.2], "natural": [0.3, 0.4]}',
]

_GOOD_BODY = b'{"pose": "nominal"}'


def page_credentials(page) -> dict:
    """The header that lets a request in as the page's own (its token,
    where the page has one), so that the cases reach what they test."""
    token = getattr(page, "token", None)
    if token is None:
        return {}
    from cdpm.viewer.page import TOKEN_HEADER

    return {TOKEN_HEADER: token}


def make_request_case(seed: int, port: int, credentials: dict | None = None) -> RequestCase:
    """A seeded request: a bad body, a body that may be a pose, a wrong
    Content-Type, a bad Host, a bad Origin, a bad Content-Length or (with
    ``credentials``, :func:`page_credentials`) a missing or wrong token;
    every other request carries ``credentials``."""
    rng = random.Random(seed)
    own = f"127.0.0.1:{port}"
    headers = {"Host": own, "Content-Type": "application/json", **(credentials or {})}
    kinds = ["body", "body", "maybe", "type", "host", "origin", "length"]
    kind = rng.choice(kinds + (["token"] if credentials else []))
    if kind == "token":
        ((name, value),) = credentials.items()
        wrong = rng.choice([None, "", value[:-1], value + "x", value.upper(), "\x00" + value])
        if wrong is None:
            del headers[name]
        else:
            headers[name] = wrong
        return RequestCase(f"token {short_repr(wrong, 20)}", headers, _GOOD_BODY)
    if kind == "body":
        what, body = rng.choice(_bad_bodies(rng))
        return RequestCase(what, headers, body)
    if kind == "maybe":
        return RequestCase("maybe a pose", headers, rng.choice(_MAYBE_BODIES), strict=False)
    if kind == "type":
        kind_of = rng.choice(
            [
                "text/plain",
                "application/x-www-form-urlencoded",
                "multipart/form-data; boundary=x",
                "text/html",
                "application/xml",
                "",
                None,
                "application/jsonx",
                "json",
            ]
        )
        if kind_of is None:
            del headers["Content-Type"]
        else:
            headers["Content-Type"] = kind_of
        return RequestCase(f"Content-Type {kind_of!r}", headers, _GOOD_BODY)
    if kind == "host":
        host = rng.choice(
            [
                "evil.example",
                "127.0.0.1.evil.example",
                "[::1",
                "[::1]x",
                "",
                None,
                "127.0.0.1:99999",
                "localhost:abc",
                "x" * 10_000,
                "127.0.0.1 evil",
                "0.0.0.0",
                "2130706433",
                "127.1",
                "@evil.example",
                "local\x7fhost",
            ]
        )
        if host is None:
            del headers["Host"]
        else:
            headers["Host"] = host
        return RequestCase(f"Host {short_repr(host, 40)}", headers, _GOOD_BODY)
    if kind == "origin":
        origin = rng.choice(
            [
                "http://evil.example",
                "null",
                "http://127.0.0.1.evil.example",
                f"http://evil.example:{port}",
                "http://localhost:1",
                "file://",
                "https://127.0.0.1:1",
                "x" * 10_000,
                "http://[::1",
            ]
        )
        headers["Origin"] = origin
        return RequestCase(f"Origin {short_repr(origin, 40)}", headers, _GOOD_BODY)
    length = rng.choice(["-1", "abc", "99999999999999999999", "1e3", " 5", "0x10", str(1 << 21)])
    headers["Content-Length"] = length
    return RequestCase(f"Content-Length {length!r}", headers, _GOOD_BODY)


def send_request(port: int, case: RequestCase, timeout: float = 30.0) -> tuple[int | None, bytes]:
    """Send ``case`` as raw bytes (``Connection: close``) and read the whole
    answer; returns (status or None without an answer, body)."""
    import socket

    headers = dict(case.headers)
    headers.setdefault("Content-Length", str(len(case.body)))
    headers["Connection"] = "close"
    head = f"POST {case.path} HTTP/1.1\r\n" + "".join(f"{k}: {v}\r\n" for k, v in headers.items())
    data = head.encode("latin-1", errors="replace") + b"\r\n" + case.body
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as sock:
        try:
            sock.sendall(data)
            sock.shutdown(socket.SHUT_WR)  # a short body ends here, not at a timeout
        except OSError:
            pass  # the server may answer and close before reading everything
        chunks = []
        try:
            while chunk := sock.recv(1 << 16):
                chunks.append(chunk)
        except (ConnectionResetError, TimeoutError):
            pass
    answer = b"".join(chunks)
    if not answer.startswith(b"HTTP/"):
        return None, answer
    status = int(answer.split(b" ", 2)[1])
    return status, answer.partition(b"\r\n\r\n")[2]


def run_request_case(port: int, case: RequestCase, stderr_text) -> Outcome:
    """Send ``case`` to the page on ``port``; raise AssertionError unless
    the answer is a 4xx with a short JSON error (or, for a body that may be
    a pose, a 200 with the panel) and nothing was written to stderr with a
    traceback (``stderr_text()``: what the server wrote so far)."""
    before = len(stderr_text())
    with _CaseClock(str(case)):
        status, body = send_request(port, case)
    written = stderr_text()[before:]
    assert "Traceback" not in written, f"{case}: traceback on stderr: {written[-600:]}"
    assert status is not None, f"{case}: no answer ({body[:100]!r})"
    if status == 200 and not case.strict:
        panel = json.loads(body)
        assert panel["verdicts"], f"{case}: a panel without verdicts"
        return Outcome("200", case.what)
    assert 400 <= status < 500, f"{case}: status {status}: {body[:300]!r}"
    try:
        error = json.loads(body)["error"]
    except (ValueError, KeyError, TypeError):
        raise AssertionError(
            f"{case}: status {status} without a JSON error: {body[:200]!r}"
        ) from None
    assert isinstance(error, str) and 0 < len(error) <= MAX_MESSAGE, (
        f"{case}: error {error[:200]!r}"
    )
    return Outcome(str(status), case.what)


class StderrCapture:
    """``with StderrCapture() as text:``: what any thread writes to
    ``sys.stderr`` (the HTTP server's tracebacks included) is kept, and
    ``text()`` returns it so far."""

    def __enter__(self):
        import io

        self._previous, self._buffer = sys.stderr, io.StringIO()
        sys.stderr = self._buffer
        return self._buffer.getvalue

    def __exit__(self, *exc_info) -> None:
        sys.stderr = self._previous


# --------------------------------------------------------------------------
# the last tracebacks: huge YAML integers, alias chains, sexagesimal
# numbers, crossed CASPR joint limits, picture dpi and titles, inertias


#: the model the YAML and inertia cases change
TRACEBACK_MODEL = ROOT / "models" / "two_link_vertical" / "two_link_vertical.yaml"


def _huge_integers(rng: random.Random) -> list[str]:
    """YAML number tokens past Python's 4,300-digit limit or float range."""
    n = rng.choice([4300, 4301, 5000, 20_000, 200_000])
    return [
        "1" * n,
        "-" + "9" * n,
        "+" + "1" * n,
        "0x" + "f" * (n // 4),
        "0o" + "7" * (n // 2),
        "0b" + "1" * n,
        "1_0" * (n // 2),
        "1" * n + ".5",
        "." + "1" * n,
        "1e" + "9" * 6,
        "1" * 400,
        "-" + "1" * 310 + ".0",
        "0" * n + "1",
        "1" * n + "e-" + "1" * 5,
    ]


#: YAML 1.1 sexagesimal numbers and look-alikes
SEXAGESIMAL = [
    "190:20:30",
    "1:2",
    "-1:30.5",
    "+1:2:3",
    "0:0",
    "1:60",
    "1:2:3:4:5:6:7:8",
    "99:99",
    "1:2.5e3",
    "-0:0:1",
    "1_0:20",
    "1:" * 500 + "1",
    "12:30:00.000001",
]


@dataclass
class TracebackCase:
    """One case of the last tracebacks' classes: its class (``kind``) and
    what was drawn for it."""

    kind: str
    seed: int
    detail: str = ""

    def __str__(self) -> str:
        return f"{self.kind} (seed {self.seed}): {self.detail[:120]}"


TRACEBACK_KINDS = (
    "huge integer",
    "alias chain",
    "sexagesimal",
    "caspr limits",
    "picture",
    "inertia",
)


def make_traceback_case(seed: int, kind: str | None = None) -> TracebackCase:
    rng = random.Random(seed)
    return TracebackCase(kind or rng.choice(TRACEBACK_KINDS), seed)


def _numeric_paths(data) -> list[tuple]:
    return [
        p
        for p in _paths(data)
        if p and isinstance(_get(data, p), (int, float, str)) and p[0] != "urdf"
    ]


def _spec_with_token(rng: random.Random, folder: Path, token: str) -> Path:
    """The traceback model with one value (or a pose's key) written as the
    raw YAML ``token``."""
    data = yaml.safe_load(TRACEBACK_MODEL.read_text())
    shutil.copy(TRACEBACK_MODEL.parent / data["urdf"], folder)
    marker = "@@TOKEN@@"
    if rng.random() < 0.15:
        data["poses"] = {marker: data["poses"]["nominal"], **data["poses"]}
    else:
        path = rng.choice(_numeric_paths(data))
        _get(data, path[:-1])[path[-1]] = marker
    text = yaml.safe_dump(data, sort_keys=False, width=10**9).replace(f"'{marker}'", token)
    text = text.replace(marker, token)
    spec = folder / TRACEBACK_MODEL.name
    spec.write_text(text)
    return spec


def _spec_with_reused_anchor(rng: random.Random, folder: Path) -> Path:
    """The traceback model with its gravity vector anchored (``&g``) and
    some base attachment points written as the alias ``*g``."""
    data = yaml.safe_load(TRACEBACK_MODEL.read_text())
    shutil.copy(TRACEBACK_MODEL.parent / data["urdf"], folder)
    text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=10**9)
    text = text.replace("gravity: [", "gravity: &g [", 1)
    lines = text.splitlines()
    points = [i for i, line in enumerate(lines) if "point: [" in line]
    for i in rng.sample(points, rng.randint(1, len(points))):
        lines[i] = re.sub(r"point: \[[^]]*\]", "point: *g", lines[i])
    spec = folder / TRACEBACK_MODEL.name
    spec.write_text("\n".join(lines) + "\n")
    return spec


def _alias_text(rng: random.Random) -> tuple[str, str, str]:
    """YAML text defining anchors, the alias to use, and what it is."""
    shape = rng.choice(["chain", "laughs", "key", "plain", "valid"])
    if shape == "valid":
        return "", "", "the gravity vector anchored and reused as attachment points"
    if shape == "chain":
        n = rng.choice([10, 100, 500, 1000, 5000])
        text = "a0: &a0 [1]\n" + "".join(f"a{i}: &a{i} [*a{i - 1}]\n" for i in range(1, n))
        return text, f"*a{n - 1}", f"a chain of {n} aliases"
    if shape == "laughs":
        n = rng.choice([4, 9, 12, 20])
        text = "l0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + "".join(
            f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]\n" for i in range(1, n)
        )
        return text, f"*l{n - 1}", f"{n} levels of nine aliases each"
    if shape == "key":
        n = rng.choice([10, 300, 3000])
        text = "k0: &k0 [1]\n" + "".join(f"k{i}: &k{i} [*k{i - 1}]\n" for i in range(1, n))
        return text + f"? *k{n - 1}\n: 1\n", "*k0", f"an alias chain of {n} as a key"
    return "s: &s [1, 2]\n", "*s", "a plain alias"  # shape == "plain"


def _picture_arguments(rng: random.Random) -> list[str]:
    dpi = rng.choice(
        [
            "0",
            "-1",
            "1e-300",
            "0.01",
            "5",
            "19.99",
            "20",
            "72",
            "150",
            "2000",
            "1e5",
            "1e308",
            "nan",
            "inf",
            "-inf",
            "abc",
            "1e400",
            "",
            "pi",
            "1" * 5000,
        ]
    )
    title = rng.choice(
        [
            "",
            "x" * 1000,
            "x" * 1001,
            "$",
            "$x",
            "$\\frac{",
            "$\\undefinedcommand$",
            "$" + "{" * 500 + "$",
            "a\nb" * 300,
            "\x1b[31mred",
            "🦾" * 300,
            "%s%n{}",
            "\u202ex",
            "word " * 199,
            "\\",
            "$$$$",
            "$x^{" * 50 + "$",
            "_" * 999,
            "\x00",
            "a" + "\u0301" * 900,
            "$\\sqrt[" * 20 + "$",
        ]
    )
    args = []
    if rng.random() < 0.8:
        args += ["--dpi", dpi]
    if rng.random() < 0.8 or not args:
        args += ["--title", title]
    return args


def _inertia_urdf(rng: random.Random) -> tuple[str, str]:
    """The traceback model's URDF with one link's inertia replaced."""
    moments = rng.choice(
        [
            ("0", "0", "0", "0", "0", "0"),  # zero (the model's own: point masses)
            ("1", "2", "0", "1", "0", "1"),  # indefinite: moments -1, 1, 3
            ("-1", "0", "0", "1", "0", "1"),  # a negative diagonal entry
            ("1", "1", "0", "1", "0", "1"),  # semi-definite: moments 0, 1, 2
            ("1", "0", "0", "1", "0", "5"),  # positive but no body's (izz > ixx + iyy)
            ("1e-300", "0", "0", "1e-300", "0", "1e-300"),
            ("1e300", "0", "0", "1e300", "0", "1e300"),
            ("nan", "0", "0", "1", "0", "1"),
            ("inf", "0", "0", "1", "0", "1"),
            ("1", "1e300", "0", "1", "0", "1"),
            ("-1e-12", "0", "0", "1", "0", "1"),
            ("1", "0", "0", "1", "0", "-1e-20"),
        ]
    )
    mass = rng.choice(["1.0", "0", "1e-12", "-1", "1e-9"])
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    data = yaml.safe_load(TRACEBACK_MODEL.read_text())
    root = ET.fromstring((TRACEBACK_MODEL.parent / data["urdf"]).read_text())
    links = [link for link in root.iter("link") if link.find("inertial") is not None]
    link = rng.choice(links)
    inertial = link.find("inertial")
    inertial.find("mass").set("value", mass)
    for key, value in zip(keys, moments, strict=True):
        inertial.find("inertia").set(key, value)
    detail = f"{link.get('name')}: mass {mass}, " + " ".join(
        f"{k}={v}" for k, v in zip(keys, moments, strict=True)
    )
    return ET.tostring(root, encoding="unicode"), detail


def run_traceback_case(case: TracebackCase, folder: Path) -> Outcome:
    """Write and run one case; raise AssertionError unless cdpm refuses it
    with its own short error or gives a clean result (finite verdicts and
    margins as :func:`run_case` checks them, or a written picture)."""
    rng = random.Random(case.seed * 7 + 1)
    if case.kind in ("huge integer", "sexagesimal", "alias chain"):
        if case.kind == "alias chain":
            prefix, alias, case.detail = _alias_text(rng)
            if alias:
                spec = _spec_with_token(rng, folder, alias)
                spec.write_text(prefix + spec.read_text())
            else:  # aliases that make a valid spec
                spec = _spec_with_reused_anchor(rng, folder)
        else:
            pool = _huge_integers(rng) if case.kind == "huge integer" else SEXAGESIMAL
            token = rng.choice(pool)
            case.detail = short_repr(token, 60)
            spec = _spec_with_token(rng, folder, token)
        with _CaseClock(str(case)):
            return _run(spec)
    if case.kind == "inertia":
        data = yaml.safe_load(TRACEBACK_MODEL.read_text())
        urdf, case.detail = _inertia_urdf(rng)
        (folder / data["urdf"]).write_text(urdf)
        shutil.copy(TRACEBACK_MODEL, folder)
        with _CaseClock(str(case)):
            return _run(folder / TRACEBACK_MODEL.name)
    if case.kind == "caspr limits":
        return _caspr_limits_case(case, rng, folder)
    return _picture_case(case, rng, folder)


def _caspr_limits_case(case: TracebackCase, rng: random.Random, folder: Path) -> Outcome:
    import warnings

    from tests.test_caspr import _DOFS, _write_model

    joints = [rng.choice(sorted(_DOFS)) for _ in range(rng.randint(1, 3))]
    overrides = {}
    for k, joint in enumerate(joints, start=1):
        n = _DOFS[joint]
        low = [rng.choice([-1.0, 0.5, 2.0, -1e300, 1e-12, 0.0]) for _ in range(n)]
        high = [
            rng.choice([1.0, -0.5, 0.0, -2.0, 1e300, -1e-12]) if rng.random() < 0.6 else v + 1
            for v in low
        ]
        overrides[k] = {
            "qmin": " ".join(map(repr, low)),
            "qmax": " ".join(map(repr, high)),
            "q0": " ".join(repr((a + b) / 2) for a, b in zip(low, high, strict=True)),
        }
    case.detail = f"{joints}: {overrides}"
    bodies, cables = _write_model(folder, joints, overrides=overrides)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # CasprWarnings about the unusual models
        return run_caspr_case(bodies, cables, None, folder / "out")


def _picture_case(case: TracebackCase, rng: random.Random, folder: Path) -> Outcome:
    arguments = _picture_arguments(rng)
    case.detail = short_repr(arguments, 100)
    return run_picture_case(arguments, folder, str(case))


def run_picture_case(arguments: list[str], folder: Path, label: str = "") -> Outcome:
    """``cdpm picture`` of the traceback model's nominal pose with
    ``arguments``; raise AssertionError unless it writes a PNG and exits 0,
    or exits 1 or 2 with a short message, no traceback and no picture."""
    import contextlib
    import io

    from cdpm.cli import main

    label = label or short_repr(arguments, 100)
    picture = folder / "pose.png"
    argv = ["picture", str(TRACEBACK_MODEL), "--pose", "nominal", "-o", str(picture), *arguments]
    out, err = io.StringIO(), io.StringIO()
    with _CaseClock(label, 3 * CASE_SECONDS):
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = main(argv)
        except SystemExit as exc:
            code = exc.code
        except Exception as exc:
            raise AssertionError(
                f"{label}: {type(exc).__name__} is not a cdpm error: {exc}"
            ) from exc
    text = out.getvalue() + err.getvalue()
    assert "Traceback" not in text, f"{label}: traceback: {text[-500:]}"
    if code == 0:
        assert picture.is_file() and picture.read_bytes().startswith(b"\x89PNG"), (
            f"{label}: no picture"
        )
        return Outcome("picture", label)
    assert code in (1, 2), f"{label}: exit code {code}"
    message = err.getvalue().strip()
    assert message and len(message) <= MAX_MESSAGE, (
        f"{label}: message of {len(message)} characters: {message[:300]!r}"
    )
    assert not picture.exists(), f"{label}: a picture was left after the error"
    return Outcome("refused", message.splitlines()[-1][:200])
