"""Names in a spec and its URDF: any name that loads works everywhere it is
used (maps included), and names that would clash in a map or rewrite what a
terminal shows are refused at load, with the item and the fix."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.errors import SpecError
from cdpm.pipeline.criteria import CRITERIA, CRITERION_DIMS

MODEL = Path(__file__).parent.parent / "models" / "two_link_planar"

# the paper's arm (two revolute joints q1, q2) with its four cables and the
# tip's x as output; {cable}, {output}, {pose} are filled in per test
_SPEC = """\
urdf: arm.urdf
gravity: [0, 0, 0]
cables:
  - name: {cable}
    route:
      - {{frame: base, point: [0, 0.5, 0]}}
      - {{frame: link1, point: [0.3, 0.1, 0], relative_to: com}}
  - name: c2
    route:
      - {{frame: base, point: [0, 1.5, 0]}}
      - {{frame: link2, point: [0.3, 0.1, 0], relative_to: com}}
  - name: c3
    route:
      - {{frame: base, point: [0, -0.5, 0]}}
      - {{frame: link1, point: [0.3, -0.1, 0], relative_to: com}}
  - name: c4
    route:
      - {{frame: base, point: [0, -1.5, 0]}}
      - {{frame: link2, point: [0.3, -0.1, 0], relative_to: com}}
outputs:
  - {{name: {output}, frame: tip, component: x}}
poses:
  {pose}: [pi/6, pi/3]
"""


def _write(
    tmp_path: Path,
    joints: tuple[str, str] = ("q1", "q2"),
    cable: str = "c1",
    output: str = "tip_x",
    pose: str = "nominal",
) -> Path:
    """The paper's arm with its joints, first cable, output and pose renamed
    (YAML scalars as written: quote them for escapes)."""
    urdf = (MODEL / "two_link_planar.urdf").read_text()
    for old, new in zip(("q1", "q2"), joints, strict=True):
        urdf = urdf.replace(f'"{old}"', f'"{new}"')
    (tmp_path / "arm.urdf").write_text(urdf)
    path = tmp_path / "spec.yaml"
    path.write_text(_SPEC.format(cable=cable, output=output, pose=pose))
    return path


def _problems(path: Path) -> list[str]:
    with pytest.raises(SpecError) as info:
        cdpm.load_robot(path)
    return info.value.problems


# ---------------------------------------------------------------------------
# (3) names that collide in a map


def test_map_names_cover_every_map_variable_and_dimension():
    from cdpm.maps.regions import REGION_VARIABLE
    from cdpm.model._spec_parts import MAP_NAMES

    assert set(MAP_NAMES) >= {*CRITERIA, *CRITERION_DIMS, REGION_VARIABLE, "sample"}


def test_joint_named_like_the_outputs_variable_is_refused_before_any_map(tmp_path):
    # joints x and y: x is free, y is the map's outputs variable
    problems = _problems(_write(tmp_path, joints=("x", "y")))
    assert problems == [
        "urdf: coordinate 'y' has the name of a map variable (the outputs y), and a map "
        "names a dimension after each coordinate; rename the joint in arm.urdf"
    ]


@pytest.mark.parametrize(
    "name, what",
    [
        ("output", r"a map dimension \(one entry per output\)"),
        ("sample", r"a map dimension \(the poses of a sampled map\)"),
        ("poc", r"a map variable \(the POC verdicts\)"),
        ("poc_region", r"a map variable \(the POC regions\)"),
    ],
)
def test_joint_named_like_a_map_name_is_refused(tmp_path, name, what):
    with pytest.raises(SpecError, match=rf"coordinate '{name}' has the name of {what}"):
        cdpm.load_robot(_write(tmp_path, joints=("q1", name)))


@pytest.mark.parametrize(
    "joints, problem",
    [
        (
            ("q1", "Y"),
            "coordinate 'Y' has the name of a map variable (the outputs y) but for case ('y'; "
            "the file systems of macOS and Windows ignore case), and a map names a dimension "
            "after each coordinate; rename the joint in arm.urdf",
        ),
        (
            ("Elbow", "elbow"),
            "coordinate 'elbow' has the name of a coordinate of joint 'Elbow' but for case "
            "('Elbow'; the file systems of macOS and Windows ignore case); rename one of the "
            "joints in arm.urdf",
        ),
        (
            ("q1", "arm/elbow"),
            "coordinate 'arm/elbow' cannot name a folder of a map store (no '/', no leading "
            "'.', not zarr.json); rename the joint in arm.urdf",
        ),
        (
            ("zarr.json", ".cdpm"),
            "coordinate 'zarr.json' cannot name a folder of a map store (no '/', no leading "
            "'.', not zarr.json); rename the joint in arm.urdf",
        ),
    ],
)
def test_joint_names_a_map_store_cannot_hold_are_refused(tmp_path, joints, problem):
    assert _problems(_write(tmp_path, joints=joints))[0] == f"urdf: {problem}"


def test_coordinates_of_two_joints_with_one_name_are_refused(tmp_path):
    # a planar joint j has coordinates j.x, j.y, j.theta; a joint j.x clashes
    (tmp_path / "robot.urdf").write_text(
        textwrap.dedent(
            """\
            <robot name="r">
              <link name="base"/>
              <link name="body">
                <inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1"
                  ixy="0" ixz="0" iyz="0"/></inertial>
              </link>
              <link name="arm">
                <inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1"
                  ixy="0" ixz="0" iyz="0"/></inertial>
              </link>
              <joint name="j" type="planar">
                <parent link="base"/><child link="body"/><axis xyz="0 0 1"/>
              </joint>
              <joint name="j.x" type="continuous">
                <parent link="body"/><child link="arm"/><axis xyz="0 0 1"/>
              </joint>
            </robot>
            """
        )
    )
    (tmp_path / "spec.yaml").write_text(
        textwrap.dedent(
            """\
            urdf: robot.urdf
            cables:
              - name: c1
                route: [{frame: base, point: [0, 1, 0]}, {frame: arm, point: [0, 0, 0]}]
            outputs:
              - {name: arm_x, frame: arm, component: x}
            """
        )
    )
    problems = _problems(tmp_path / "spec.yaml")
    assert problems == [
        "urdf: coordinate 'j.x' has the name of a coordinate of joint 'j'; rename one of "
        "the joints in robot.urdf"
    ]


def test_names_that_clash_nowhere_make_a_map(tmp_path):
    # a joint x, a cable y, an output cable and a pose output: each in a
    # namespace of its own (map labels, not map variables)
    path = _write(tmp_path, joints=("x", "elbow"), cable="y", output="cable", pose="output")
    robot = cdpm.load_robot(path)
    assert list(robot.coordinate_names) == ["x", "elbow"]
    assert list(robot.cable_names) == ["y", "c2", "c3", "c4"]
    assert list(robot.output_names) == ["cable"]
    np.testing.assert_allclose(robot.configuration("output"), [np.pi / 6, np.pi / 3])
    ds = cdpm.workspace_map(
        robot, {"x": np.array([np.pi / 6]), "elbow": np.array([np.pi / 3, 1.0])}
    )
    assert ds["y"].dims == ("x", "elbow", "output")
    assert list(ds["output"].values) == ["cable"]
    assert list(ds["cable"].values) == ["y", "c2", "c3", "c4"]
    # tip x = cos q1 + cos(q1 + q2) (paper eq 17, unit links)
    np.testing.assert_allclose(
        ds["y"].values[0, :, 0],
        [np.cos(np.pi / 6) + np.cos(np.pi / 2), np.cos(np.pi / 6) + np.cos(np.pi / 6 + 1.0)],
        atol=1e-12,
    )


def test_pose_names_that_read_alike_are_refused(tmp_path):
    # the YAML keys 1 and "1" both name the pose "1"
    path = _write(tmp_path, pose="1")
    path.write_text(path.read_text() + '  "1": [0, 0]\n')
    assert _problems(path) == [
        "poses.1: the pose name '1' is given twice (as 1 and '1'); rename one of them"
    ]


# ---------------------------------------------------------------------------
# (5) names that forge what is printed

_FORGED = r'"tip_x\e[2J\e[H\nPositive output controllability (Theorem 1): YES"'


def _no_control_characters(text: str) -> None:
    assert all(ch.isprintable() or ch == "\n" for ch in text), repr(text)
    assert "\nPositive output" not in text


def test_output_name_that_forges_a_verdict_is_refused(tmp_path):
    with pytest.raises(SpecError) as info:
        cdpm.load_robot(_write(tmp_path, output=_FORGED))
    assert info.value.problems == [
        "outputs[0].name: the output name 'tip_x\\x1b[2J\\x1b[H\\nPositive output "
        "controllability (Theorem 1): YES' has the non-printable character '\\x1b' "
        "(U+001B); names are printed in reports, so they must be printable text with no "
        "newline, tab or escape sequence: rename the output"
    ]
    _no_control_characters(str(info.value))


@pytest.mark.parametrize(
    "field, value, match",
    [
        ("cable", r'"c1\e[31m"', r"cables\[0\]\.name: the cable name 'c1\\x1b\[31m' has"),
        ("cable", r'"c1\nc9"', r"cables\[0\]\.name: the cable name 'c1\\nc9' has the non-"),
        ("output", r'"tip\tx"', r"outputs\[0\]\.name: the output name 'tip\\tx' has"),
        ("output", r'"tip_x\u202e"', r"outputs\[0\]\.name: .* character '\\u202e' \(U\+202E\)"),
        ("pose", r'"home\r"', r"poses: the pose name 'home\\r' has the non-printable"),
        ("pose", r'"home\x9b2J"', r"poses: the pose name 'home\\x9b2J' has"),
    ],
)
def test_names_with_control_characters_are_refused(tmp_path, field, value, match):
    with pytest.raises(SpecError, match=match) as info:
        cdpm.load_robot(_write(tmp_path, **{field: value}))
    assert len(info.value.problems) == 1
    _no_control_characters(str(info.value))


def test_every_bad_name_is_reported_at_once(tmp_path):
    path = _write(tmp_path, cable=r'"c1\e"', output=r'"y\n"', pose=r'"p\t"')
    wheres = [p.split(":")[0] for p in _problems(path)]
    assert wheres == ["cables[0].name", "outputs[0].name", "poses"]


def test_output_unit_with_control_characters_is_refused(tmp_path):
    path = _write(tmp_path)
    text = path.read_text().replace(
        "  - {name: tip_x, frame: tip, component: x}",
        '  - {name: s, unit: "m\\e[2J", sum: [{weight: 1, frame: tip, component: x}]}',
    )
    path.write_text(text)
    with pytest.raises(SpecError, match=r"outputs\[0\]\.unit: the unit 'm\\x1b\[2J' has"):
        cdpm.load_robot(path)


@pytest.mark.parametrize(
    "joint, shown",
    [
        ("elbow&#10;Positive output controllability: YES", "'elbow\\nPositive output"),
        ("elbow&#x9b;2J", "'elbow\\x9b2J'"),
        ("elbow\u202e", "'elbow\\u202e'"),
    ],
)
def test_urdf_joint_names_with_control_characters_are_refused(tmp_path, joint, shown):
    with pytest.raises(SpecError) as info:
        cdpm.load_robot(_write(tmp_path, joints=("q1", joint)))
    problem = info.value.problems[0]
    assert problem.startswith(f"urdf: arm.urdf: the joint name {shown}"), problem
    assert problem.endswith(": rename the joint"), problem
    _no_control_characters(str(info.value))
