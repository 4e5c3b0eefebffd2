"""Cable spec loading and validation: every problem reported, clearly."""

from __future__ import annotations

import math

import numpy as np
import pytest

import cdpm
from cdpm.errors import InputError, SpecError
from cdpm.model.spec import load_spec, parse_number
from tests.conftest import PAPER_SPEC

GOOD = """
urdf: arm.urdf
gravity: [0, 0, 0]
cables:
  - name: c1
    route:
      - {frame: base, point: [0, 0.5, 0]}
      - {frame: link1, point: [0.3, 0.1, 0], relative_to: com}
outputs:
  - {name: tip_x, frame: tip, component: x}
"""


def test_paper_spec_fields():
    spec = load_spec(PAPER_SPEC)
    assert [c.name for c in spec.cables] == ["c1", "c2", "c3", "c4"]
    # Table I offsets are relative to the link centre (0.5 m along the link)
    assert spec.cables[0].route[1].point_in_frame == pytest.approx((0.8, 0.1, 0.0))
    assert spec.cables[3].route[1].point_in_frame == pytest.approx((0.8, -0.1, 0.0))
    assert spec.cables[1].route[0].point_in_frame == pytest.approx((0.0, 1.5, 0.0))
    assert all(c.tension_min == 0 and math.isinf(c.tension_max) for c in spec.cables)
    np.testing.assert_allclose(
        spec.poses["nominal"], [math.pi / 6, math.pi / 3], rtol=0, atol=1e-15
    )
    np.testing.assert_array_equal(spec.gravity, [0, 0, 0])
    np.testing.assert_array_equal(spec.model.gravity.linear, [0, 0, 0])
    assert len(spec.sha256) == 64


def test_gravity_and_loads_beyond_physics_are_refused(write_spec):
    """Gravity of 1e308 m/s^2 made the dynamics overflow into numpy's
    LinAlgError; the spec and the overrides now name the limit."""
    from cdpm.maps.plan import override_robot

    with pytest.raises(SpecError, match="gravity: values must be finite, at most 1e\\+06 m/s\\^2"):
        load_spec(write_spec(GOOD.replace("gravity: [0, 0, 0]", "gravity: [1.0e+308, 0, 0]")))
    robot = cdpm.load_robot(write_spec(GOOD))
    with pytest.raises(InputError, match="gravity \\[m/s\\^2\\] must be 3 numbers of at most"):
        override_robot(robot, gravity=[1e308, 0, 0])
    with pytest.raises(InputError, match="external wrench .* of at most 1e\\+12"):
        override_robot(robot, external_wrench=[1e300, 0])


def test_default_gravity_is_standard(write_spec):
    spec = load_spec(write_spec(GOOD.replace("gravity: [0, 0, 0]\n", "")))
    np.testing.assert_array_equal(spec.gravity, [0, 0, -9.81])


def test_misspelled_frame_lists_valid_frames(write_spec):
    path = write_spec(GOOD.replace("frame: link1", "frame: lnk1"))
    with pytest.raises(
        cdpm.SpecError,
        match=r"cables\[0\] \(c1\)\.route\[1\]\.frame: frame 'lnk1' not in URDF; "
        r"frames: world, base, link1, link2, q1, q2, tip, tip_joint",
    ):
        load_spec(path)


def test_missing_urdf(write_spec):
    path = write_spec(GOOD.replace("urdf: arm.urdf", "urdf: nope.urdf"))
    with pytest.raises(
        cdpm.SpecError,
        match=r"urdf: file 'nope.urdf' not found .*URDF files beside the spec: arm.urdf",
    ):
        load_spec(path)


def test_cable_with_one_point(write_spec):
    text = GOOD.replace("      - {frame: link1, point: [0.3, 0.1, 0], relative_to: com}\n", "")
    with pytest.raises(
        cdpm.SpecError, match=r"route: has 1 point\(s\); a cable needs at least 2 attachment points"
    ):
        load_spec(write_spec(text))


def test_non_numeric_point(write_spec):
    path = write_spec(GOOD.replace("point: [0, 0.5, 0]", "point: [0, half, 0]"))
    with pytest.raises(
        cdpm.SpecError,
        match=r"route\[0\]\.point\[1\]: 'half' is not a number \(only numbers, pi, e, inf and "
        r"\+ - \* / \*\* are allowed \(found 'half'\)\)$",
    ):
        load_spec(path)


def test_coincident_attachment_pair(write_spec):
    text = GOOD.replace(
        "{frame: link1, point: [0.3, 0.1, 0], relative_to: com}",
        "{frame: base, point: [0, 0.5, 0]}",
    )
    with pytest.raises(
        cdpm.SpecError, match=r"points 0 and 1 coincide .*needs two distinct attachment points"
    ):
        load_spec(write_spec(text))


def test_all_problems_in_one_error(write_spec):
    text = GOOD.replace("frame: link1", "frame: lnk1").replace("component: x", "component: q")
    text += "poses:\n  bad: [1, 2, 3]\nfoo: 1\n"
    with pytest.raises(cdpm.SpecError) as info:
        load_spec(write_spec(text))
    err = info.value
    assert len(err.problems) == 4, err.problems
    message = str(err)
    assert "4 problems in cable spec" in message
    assert "unknown key 'foo'" in message
    assert "'q' is not valid; use one of x, y, z" in message
    assert "poses.bad: [2] ... " not in message
    assert "poses.bad" in message and "expected nq=2" in message
    assert str(err.path).endswith("spec.yaml")


@pytest.mark.parametrize(
    ("bounds", "message"),
    [
        ("[10, 5]", r"tension: maximum 5.0 must be >= minimum 10.0"),
        ("[-1, 5]", r"minimum -1.0 must be finite and >= 0"),
        # beyond MAX_TENSION (1e12 N) the statics overflow; inf stays "no upper bound"
        ("[0, 1e300]", r"maximum 1e\+300 is above 1e\+12 N; give inf"),
        ("[2e12, inf]", r"minimum 2000000000000.0 is above 1e\+12 N"),
        ("[0, 1e400]", r"'1e400' is too large for a number"),
        ("[true, 10]", r"True is a boolean, not a number$"),
    ],
)
def test_bad_tension_bounds(write_spec, bounds, message):
    text = GOOD.replace("  - name: c1\n", f"  - name: c1\n    tension: {bounds}\n")
    with pytest.raises(cdpm.SpecError, match=message):
        load_spec(write_spec(text))


def test_infinite_tension_bound_is_no_upper_bound(write_spec):
    text = GOOD.replace("  - name: c1\n", "  - name: c1\n    tension: [0, inf]\n")
    assert math.isinf(load_spec(write_spec(text)).cables[0].tension_max)


def test_com_on_massless_link_is_refused(write_spec):
    text = GOOD.replace(
        "{frame: link1, point: [0.3, 0.1, 0], relative_to: com}",
        "{frame: tip, point: [0, 0, 0], relative_to: com}",
    )
    with pytest.raises(
        cdpm.SpecError, match=r"'com' needs a URDF link with an inertia; 'tip' is not one"
    ):
        load_spec(write_spec(text))


def test_missing_file_and_bad_yaml(tmp_path):
    with pytest.raises(cdpm.SpecError, match="cable spec file not found"):
        load_spec(tmp_path / "absent.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("cables: [\n")
    with pytest.raises(cdpm.SpecError, match="not valid YAML"):
        load_spec(bad)
    bad.write_text("- just a list\n")
    with pytest.raises(cdpm.SpecError, match="a cable spec is a YAML mapping"):
        load_spec(bad)


def test_yaml_tags_are_not_executed(write_spec):
    text = GOOD + "description: !!python/object/apply:os.system ['echo hacked']\n"
    with pytest.raises(cdpm.SpecError, match="not valid YAML"):
        load_spec(write_spec(text))


def test_named_poses_by_joint(write_spec):
    spec = load_spec(write_spec(GOOD + "poses:\n  bent: {q2: -pi/2}\n  straight: [0, 0]\n"))
    np.testing.assert_allclose(spec.poses["bent"], [0.0, -math.pi / 2], atol=1e-15)
    np.testing.assert_array_equal(spec.poses["straight"], [0.0, 0.0])


def test_parse_number():
    assert parse_number("pi/6") == pytest.approx(math.pi / 6, abs=1e-16)
    assert parse_number("-2*pi/3") == pytest.approx(-2 * math.pi / 3, abs=1e-15)
    assert parse_number(".inf") == math.inf
    assert parse_number(3) == 3.0
    with pytest.raises(ValueError, match="only numbers, pi, e, inf"):
        parse_number("__import__('os').getcwd()")
    with pytest.raises(ValueError, match="is a boolean, not a number"):
        parse_number(True)
    # finite literals past the largest float are no silent inf (a spec bound
    # [0, 1e400] read as "no upper bound"); inf itself stays
    for text in ("1e400", "1e308*10", "-1e400"):
        with pytest.raises(ValueError, match=r"too large for a number \(beyond 1.8e308\)"):
            parse_number(text)
    assert parse_number("2*inf") == parse_number("inf") == math.inf


def test_parse_number_is_one_function_under_its_public_names():
    import cdpm.expressions

    assert cdpm.parse_number is cdpm.expressions.parse_number
    assert parse_number is cdpm.expressions.parse_number  # cdpm.model.spec re-exports it


def test_outputs_are_required_and_may_be_offset_points(write_spec):
    text = GOOD.replace("outputs:\n  - {name: tip_x, frame: tip, component: x}\n", "")
    with pytest.raises(cdpm.SpecError, match=r"outputs: missing; give at least one output"):
        load_spec(write_spec(text))
    text = GOOD.replace(
        "{name: tip_x, frame: tip, component: x}",
        "{name: mid_y, frame: link2, component: y, point: [0.5, 0, 0]}",
    )
    robot = cdpm.load_robot(write_spec(text))
    q = np.array([0.3, 0.4])
    expected = math.sin(0.3) + 0.5 * math.sin(0.7)  # middle of link 2
    np.testing.assert_allclose(robot.output(q), [expected], atol=1e-12)


def test_number_parser_refuses_huge_powers_quickly():
    with pytest.raises(ValueError, match="is too large for a number"):
        parse_number("9**9**9")


def test_duplicate_keys_are_refused_with_their_lines(write_spec):
    text = GOOD.replace("  - name: c1\n", "  - name: c1\n    name: c2\n") + (
        "poses:\n  a: [0, 0]\nposes:\n  b: [1, 1]\n"
    )
    path = write_spec(text)
    with pytest.raises(cdpm.SpecError) as info:
        load_spec(path)
    message = str(info.value)
    assert message.startswith(f"{path}: 2 problems in cable spec:")
    assert (
        "line 6: key 'name' is given twice in the same mapping (first on line 5); "
        "YAML would keep only the last one" in message
    )
    assert "line 14: key 'poses' is given twice in the same mapping (first on line 12)" in message
    assert message.index("line 6:") < message.index("line 14:")
    # equal keys in different mappings, and merged keys overridden, are fine
    spec = load_spec(
        write_spec(GOOD + "poses:\n  a: &a {q1: 0.1, q2: 0.2}\n  b: {<<: *a, q2: 0.5}\n")
    )
    np.testing.assert_array_equal(spec.poses["a"], [0.1, 0.2])
    np.testing.assert_array_equal(spec.poses["b"], [0.1, 0.5])


def test_pretension_method_needs_a_pretension(write_spec):
    for equilibrium in ("{method: pretension}", "{method: pretension, pretension: 0}"):
        with pytest.raises(
            cdpm.SpecError,
            match=r"equilibrium: method 'pretension' needs pretension: N > 0 .*method: min_norm",
        ):
            load_spec(write_spec(GOOD + f"equilibrium: {equilibrium}\n"))
    spec = load_spec(write_spec(GOOD + "equilibrium: {method: pretension, pretension: 5}\n"))
    assert (spec.equilibrium_method, spec.pretension) == ("pretension", 5.0)
    # a pretension that is no number is one problem, not also a missing pretension
    with pytest.raises(cdpm.SpecError) as info:
        load_spec(write_spec(GOOD + "equilibrium: {method: pretension, pretension: true}\n"))
    assert "equilibrium.pretension" in str(info.value)
    assert "needs pretension" not in str(info.value)
