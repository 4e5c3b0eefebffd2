"""Hostile or broken spec text: refused at once with a short cdpm error."""

from __future__ import annotations

import re
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.errors import MAX_LISTED_PROBLEMS, MAX_PROBLEM_CHARS, SpecError
from cdpm.expressions import MAX_EXPRESSION_CHARS, parse_number
from cdpm.model.yaml_loading import MAX_YAML_DEPTH
from tests.conftest import paper_spec_copy, paper_spec_text

MODEL = Path(__file__).parent.parent / "models" / "two_link_planar"


def test_alias_bomb_is_refused_quickly(tmp_path):
    anchors = "x0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1]\n" + "".join(
        f"x{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]\n" for i in range(1, 9)
    )
    text = anchors + paper_spec_text().replace("gravity: [", "description: *a8\ngravity: [", 1)
    start = time.perf_counter()
    with pytest.raises(SpecError, match="expands to more than .* values through its aliases"):
        cdpm.load_robot(paper_spec_copy(tmp_path, text))
    assert time.perf_counter() - start < 5.0


def test_deep_nesting_is_refused(tmp_path):
    text = paper_spec_text() + "description: " + "[" * 3000 + "]" * 3000 + "\n"
    with pytest.raises(SpecError, match=f"nest more than {MAX_YAML_DEPTH} deep"):
        cdpm.load_robot(paper_spec_copy(tmp_path, text))


def test_modest_anchors_still_load(tmp_path):
    text = paper_spec_text().replace("gravity: [0, 0, 0]", "gravity: &g [0, 0, 0]", 1)
    text = text.replace(
        "outputs:\n", "outputs:\n  - {name: extra, frame: tip, component: y, point: *g}\n"
    )
    robot = cdpm.load_robot(paper_spec_copy(tmp_path, text))
    assert robot.output_names[0] == "extra"


@pytest.mark.parametrize("value", [".nan", ".inf", "inf-inf", "(-1)**0.5"])
def test_non_finite_or_complex_points_are_refused(tmp_path, value):
    text = paper_spec_text().replace("point: [0, 0.5, 0]", f"point: [{value}, 0.5, 0]", 1)
    assert text != paper_spec_text()
    with pytest.raises(SpecError, match=r"route\[0\]\.point"):
        cdpm.load_robot(paper_spec_copy(tmp_path, text))


def test_many_problems_give_a_short_message(tmp_path):
    bad = "".join(f"  - {{name: o{i}, frame: nope{i}, component: x}}\n" for i in range(500))
    text = paper_spec_text().replace("outputs:\n", "outputs:\n" + bad, 1)
    with pytest.raises(SpecError) as info:
        cdpm.load_robot(paper_spec_copy(tmp_path, text))
    message = str(info.value)
    assert "500 problems" in message and "and 492 more" in message
    assert len(message) < 4000
    assert len(info.value.problems) == 500
    assert message.count("\n  - ") == MAX_LISTED_PROBLEMS + 1
    assert all(len(line) <= MAX_PROBLEM_CHARS + 4 for line in message.splitlines())


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("(-1)**0.5", "not a real number"),
        ("+".join(["1"] * 3000), f"at most {MAX_EXPRESSION_CHARS}"),
        ("inf - inf", "NaN"),
        ("1/0", "divides by zero"),
        ("__import__('os')", "only numbers"),
    ],
)
def test_parser_refuses_with_value_error(text, match):
    with pytest.raises(ValueError, match=match):
        parse_number(text)


def test_parser_keeps_plain_arithmetic():
    assert parse_number("-2*pi/3") == pytest.approx(-2.0943951023931953, abs=0)
    assert parse_number("+".join(["1"] * 40)) == 40.0
    assert parse_number("-.inf") == float("-inf")
    with pytest.raises(ValueError, match="too large"):
        parse_number(10**400)


def _urdf_variant(tmp_path: Path, text: str) -> Path:
    shutil.copy(MODEL / "two_link_planar.yaml", tmp_path)
    (tmp_path / "two_link_planar.urdf").write_text(text)
    return tmp_path / "two_link_planar.yaml"


_URDF = (MODEL / "two_link_planar.urdf").read_text()


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (
            '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY a "aaaa">'
            '<!ENTITY b "&a;&a;&a;&a;">]>' + _URDF.split("?>", 1)[1],
            "declares entities or external references",
        ),
        (_URDF.replace('name="link1"', 'name="&undefined;"', 1), "undefined entity"),
        (re.sub(r'<mass value="[^"]*"', '<mass value="heavy"', _URDF, count=1), "not a number"),
        (re.sub(r'xyz="[^"]*"', 'xyz="0 0"', _URDF, count=1), "expected 3 numbers, got 2"),
        (re.sub(r'xyz="[^"]*"', 'xyz="nan 0 0"', _URDF, count=1), "must be finite"),
        (_URDF[:200], "not well-formed XML"),
        ("<robt/>", "expected <robot>"),
    ],
)
def test_broken_urdf_is_a_spec_error(tmp_path, text, match):
    with pytest.raises(SpecError, match=match):
        cdpm.load_robot(_urdf_variant(tmp_path, text))


@pytest.mark.parametrize(
    ("path", "match"),
    [("a\0b.yaml", "NUL character"), ("x" * 5000, "cannot use the path")],
)
def test_unusable_paths_are_spec_errors(path, match):
    with pytest.raises(SpecError, match=match) as info:
        cdpm.load_robot(path)
    assert len(str(info.value)) < 300


SPATIAL = Path(__file__).parent.parent / "models" / "spatial_8cable"


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ('<mass value="25.0"/>', '<mass value="1e-300"/>', "mass 1e-300 kg"),
        ('ixx="14.0"', 'ixx="1e300"', "moments of inertia"),
    ],
)
def test_extreme_magnitudes_are_model_errors(tmp_path, old, new, match):
    urdf = (SPATIAL / "spatial_8cable.urdf").read_text()
    assert old in urdf
    (tmp_path / "spatial_8cable.urdf").write_text(urdf.replace(old, new))
    shutil.copy(SPATIAL / "spatial_8cable.yaml", tmp_path)
    with pytest.raises(cdpm.ModelError, match=match):
        cdpm.load_robot(tmp_path / "spatial_8cable.yaml")


def test_numbers_that_overflow_to_infinity_are_refused(tmp_path):
    """YAML reads a finite literal beyond the float range as infinity: a
    cable bound of 1.0e+400 N would silently mean no bound. It is refused
    with its line; .inf, infinity as meant, still loads."""
    bounded = paper_spec_text().replace(
        "  - name: c1\n", "  - name: c1\n    tension: [0, 1.0e+400]\n"
    )
    with pytest.raises(SpecError, match=r"line 10: 1.0e\+400 is too large for a number .* \.inf"):
        cdpm.load_robot(paper_spec_copy(tmp_path, bounded))
    unbounded = bounded.replace("1.0e+400", ".inf")
    assert cdpm.load_robot(paper_spec_copy(tmp_path, unbounded)).tension_max[0] == np.inf
    from cdpm.model.yaml_loading import load_yaml

    # infinity as meant, under an explicit tag too
    assert load_yaml("a: !!float inf\nb: !!float -Infinity\n") == ({"a": np.inf, "b": -np.inf}, [])


def test_far_output_point_is_a_model_error(tmp_path):
    text = paper_spec_text().replace(
        "outputs:\n", "outputs:\n  - {name: far, frame: tip, component: x, point: [1e300, 0, 0]}\n"
    )
    with pytest.raises(cdpm.ModelError, match="lies 1e\\+300 m from its frame"):
        cdpm.load_robot(paper_spec_copy(tmp_path, text))


def test_caspr_xml_with_entities_is_refused(tmp_path):
    from cdpm.caspr import import_caspr

    bomb = (
        '<?xml version="1.0"?>\n<!DOCTYPE bodies_system [<!ENTITY a "aaaaaaaa">'
        '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;">]>\n<bodies_system>&b;</bodies_system>\n'
    )
    bodies, cables = tmp_path / "x_bodies.xml", tmp_path / "x_cables.xml"
    bodies.write_text(bomb)
    cables.write_text(bomb.replace("bodies_system", "cables"))
    with pytest.raises(cdpm.InputError, match="declares entities or external references"):
        import_caspr(bodies, cables, tmp_path / "out")


def test_every_cdpm_error_message_is_capped():
    from cdpm.errors import MAX_MESSAGE_CHARS

    exc = cdpm.InputError("x" * 10_000)
    assert len(str(exc)) <= MAX_MESSAGE_CHARS
    assert str(exc).endswith("more characters)")
    assert len(exc.args[0]) == 10_000  # the full text is kept


def test_libyaml_and_pyyaml_read_specs_alike():
    """Specs are read with libyaml when PyYAML has it: the same data and the
    same repeated-key lines as PyYAML's own parser on every shipped spec and
    on a text with a repeated key; a broken text's error is PyYAML's own,
    which shows the offending line."""
    import yaml

    from cdpm.model.yaml_loading import _load_yaml, load_yaml

    texts = [p.read_text() for p in sorted(MODEL.parent.glob("*/*.yaml"))]
    texts.append(paper_spec_text() + "gravity: [0, 0, -9.81]\n")
    assert len(texts) >= 7
    for text in texts:
        assert _load_yaml(text, fast=True) == _load_yaml(text, fast=False) == load_yaml(text)
    assert "key 'gravity' is given twice" in load_yaml(texts[-1])[1][0]
    with pytest.raises(yaml.YAMLError) as fast_error:
        load_yaml("cables: [\n  - {name: c1\n")
    with pytest.raises(yaml.YAMLError) as pure_error:
        _load_yaml("cables: [\n  - {name: c1\n", fast=False)
    assert str(fast_error.value) == str(pure_error.value)
    assert "line 2, column 3:\n      - {name: c1\n      ^" in str(fast_error.value)
