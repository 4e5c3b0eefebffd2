"""The one home of the coordinates (:mod:`cdpm.model.coordinates`): each
joint's kind, each coordinate's unit, URDF limits and default range, on the
shipped models and on a planar cart with a slider and a wheel; and the
viewer's sliders and ``cdpm find``'s box built on them."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

import cdpm
from cdpm.model.coordinates import (
    RANGE_REASONS,
    ConfigurationError,
    coordinate_limits,
    coordinate_units,
    default_ranges,
    joint_kind,
)
from cdpm.regions.search import search_box
from cdpm.viewer import coordinate_sliders
from tests.conftest import MODELS

VERTICAL = MODELS / "two_link_vertical"
SPATIAL = MODELS / "spatial_8cable"

_LINK = """<link name="{}"><inertial><mass value="1"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>"""


def _cart(tmp_path, origin: str = 'xyz="0 0 0.5"'):
    """A planar cart (x, y, theta) hanging from the world at ``origin``, a
    slider on it (prismatic, limits 0 0: none usable) and a wheel
    (continuous); world anchors span x in [-2, 3], y in [-1, 2]."""
    links = "\n".join(_LINK.format(n) for n in ("cart", "slider", "wheel"))
    (tmp_path / "cart.urdf").write_text(
        f"""<robot name="cart"><link name="world"/>{links}
  <joint name="base" type="planar"><parent link="world"/><child link="cart"/>
    <origin {origin}/><axis xyz="0 0 1"/></joint>
  <joint name="slide" type="prismatic"><parent link="cart"/><child link="slider"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0" effort="1" velocity="1"/></joint>
  <joint name="spin" type="continuous"><parent link="slider"/><child link="wheel"/>
    <axis xyz="0 0 1"/></joint>
</robot>"""
    )
    (tmp_path / "cart.yaml").write_text(
        textwrap.dedent(
            """\
            urdf: cart.urdf
            cables:
              - name: a
                route: [{frame: world, point: [-2, -1, 0.5]}, {frame: cart, point: [0, 0, 0]}]
              - name: b
                route: [{frame: world, point: [3, 1, 0.5]}, {frame: cart, point: [0, 0, 0]}]
              - name: c
                route: [{frame: world, point: [0, 2, 0.5]}, {frame: wheel, point: [0.1, 0, 0]}]
            outputs: [{name: x, frame: cart, component: x}]
            poses:
              start: {base: [0.5, 0.25, 0.1], slide: 0.3, spin: 0}
            """
        )
    )
    return cdpm.load_robot(tmp_path / "cart.yaml")


def test_joint_kinds_and_units():
    vertical, spatial = cdpm.load_robot(VERTICAL), cdpm.load_robot(SPATIAL)
    assert [joint_kind(j) for j in list(vertical.model.joints)[1:]] == ["euclidean"] * 2
    assert [joint_kind(j) for j in list(spatial.model.joints)[1:]] == ["freeflyer"]
    assert coordinate_units(vertical.model) == ["rad", "rad"]
    assert coordinate_units(spatial.model) == ["m", "m", "m", "rad", "rad", "rad"]


def test_an_unsupported_joint_kind_says_so():
    class Mimic:
        nq, nv = 2, 1

        def shortname(self):
            return "JointModelMimic"

    with pytest.raises(ConfigurationError, match="JointModelMimic is not supported"):
        joint_kind(Mimic())


def test_limits_in_natural_coordinates():
    lower, upper = coordinate_limits(cdpm.load_robot(VERTICAL).model)
    np.testing.assert_allclose([lower, upper], [[-np.pi, -np.pi], [np.pi, np.pi]])
    # a free flyer: no limits for x, y, z in the URDF; none for its angles
    lower, upper = coordinate_limits(cdpm.load_robot(SPATIAL).model)
    assert np.all(lower == -np.inf) and np.all(upper == np.inf)


def test_default_ranges_of_the_shipped_models():
    ranges = default_ranges(cdpm.load_robot(VERTICAL))
    np.testing.assert_allclose([ranges.low, ranges.high], [[-np.pi] * 2, [np.pi] * 2])
    assert ranges.limited.all() and ranges.reasons == (RANGE_REASONS["limits"],) * 2
    spatial = cdpm.load_robot(SPATIAL)
    ranges = default_ranges(spatial)
    # x, y, z: the box of the 8 anchors on the frame; roll and yaw a turn, pitch half
    np.testing.assert_allclose(ranges.low, [-2.0, -1.5, 0.0, -np.pi, -np.pi / 2, -np.pi])
    np.testing.assert_allclose(ranges.high, [2.0, 1.5, 2.0, np.pi, np.pi / 2, np.pi])
    assert ranges.reasons[:3] == (RANGE_REASONS["anchors"],) * 3
    assert ranges.reasons[3:] == tuple(RANGE_REASONS[k] for k in ("turn", "pitch", "turn"))
    assert not ranges.limited.any() and ranges.units == ("m", "m", "m", "rad", "rad", "rad")
    assert "platform_joint.pitch [-1.571, 1.571] rad (half a turn" in str(ranges)
    with pytest.raises(ValueError, match="read-only"):
        ranges.low[0] = 0.0


def test_default_ranges_of_a_cart_with_a_slider_and_a_wheel(tmp_path):
    robot = _cart(tmp_path)
    assert joint_kind(robot.model.joints[1]) == "planar"
    assert joint_kind(robot.model.joints[3]) == "continuous"
    assert coordinate_units(robot.model) == ["m", "m", "rad", "m", "rad"]
    ranges = default_ranges(robot)  # reference: the spec's first pose (slide 0.3)
    expected = {
        "base.x": (-2.0, 3.0, "anchors"),
        "base.y": (-1.0, 2.0, "anchors"),
        "base.theta": (-math.pi, math.pi, "turn"),
        "slide": (-0.7, 1.3, "reference"),  # limits 0 0 are not usable
        "spin": (-math.pi, math.pi, "turn"),
    }
    rows = zip(ranges.names, ranges.low, ranges.high, ranges.reasons, strict=True)
    for name, lo, hi, why in rows:
        low, high, reason = expected[name]
        assert (lo, hi) == pytest.approx((low, high)) and why == RANGE_REASONS[reason], name
    # another reference moves the +-1 m span only
    assert default_ranges(robot, [0, 0, 0, 1.0, 0]).as_dict()["slide"] == pytest.approx((0, 2))
    assert default_ranges(robot, "start").as_dict() == ranges.as_dict()


def test_anchor_boxes_follow_the_joint_placement(tmp_path):
    shifted = default_ranges(_cart(tmp_path, 'xyz="1 0 0.5"')).as_dict()
    assert shifted["base.x"] == pytest.approx((-3.0, 2.0))  # x is measured from the joint
    turned = default_ranges(_cart(tmp_path, 'xyz="0 0 0.5" rpy="0 0 0.5"'))
    # axes not along the world's: +-1 m around the first pose
    assert turned.as_dict()["base.x"] == pytest.approx((-0.5, 1.5))
    assert turned.reasons[0] == RANGE_REASONS["reference"]


def test_the_viewer_and_find_share_the_rule(tmp_path):
    spatial = cdpm.load_robot(SPATIAL)
    centre = spatial.to_natural(spatial.configuration("centre"))
    sliders = {s.name: (s.low, s.high) for s in coordinate_sliders(spatial, centre)}
    box = search_box(spatial)
    assert sliders == dict(zip(box.names, zip(box.low, box.high, strict=True), strict=True))
    # the viewer centres the +-1 m spans on the viewed pose and holds its value
    robot = _cart(tmp_path)
    sliders = {s.name: (s.low, s.high) for s in coordinate_sliders(robot, [3.5, 0, 0, 0.25, 0])}
    assert sliders["slide"] == pytest.approx((-0.75, 1.25))
    assert sliders["base.x"] == pytest.approx((-2.0, 3.5))
