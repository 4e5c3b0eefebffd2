"""Headless picture: the PNG shows the cables by state and the verdict."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from cdpm.errors import InputError
from cdpm.viewer import COLORS
from tests.conftest import PAPER_SPEC, ROOT

pytest.importorskip("matplotlib")


def _pixels(path):
    import matplotlib.image

    return (np.asarray(matplotlib.image.imread(path))[..., :3] * 255).round().astype(int)


def _count_near(pixels, rgb, tol=10):
    target = np.round(np.array(rgb) * 255)
    return int(np.sum(np.all(np.abs(pixels - target) <= tol, axis=-1)))


@pytest.mark.slow
def test_paper_figure(paper_robot, tmp_path):
    from cdpm.plotting.picture import render_pose

    path = tmp_path / "nominal.png"
    fig = render_pose(paper_robot, "nominal", path)
    ax = fig.axes[0]
    assert "POC YES (r_T 0.15 m)" in ax.get_title()
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [m]", "y [m]")  # the arm's plane
    px = _pixels(path)
    assert _count_near(px, COLORS["slack"]) > 300  # four dashed pink cables
    assert _count_near(px, COLORS["yes"]) > 60  # green star
    assert _count_near(px, COLORS["no"]) == 0
    # the verdict follows the pose: stretched along x, the output cannot move
    fig = render_pose(paper_robot, [0.0, 0.0], tmp_path / "straight.png")
    assert "POC NO" in fig.axes[0].get_title()
    px = _pixels(tmp_path / "straight.png")
    assert _count_near(px, COLORS["no"]) > 60 and _count_near(px, COLORS["yes"]) == 0


def test_projection_planes(paper_robot):
    from cdpm.plotting.picture import render_pose

    fig = render_pose(paper_robot, [math.pi / 2, 0.0], plane="xz", title="side")
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel(), ax.get_title()) == ("x [m]", "z [m]", "side")
    # at q = (pi/2, 0) the links lie along y: attachments 0.1 either side, x = -+0.1
    lines = [line for line in ax.get_lines() if line.get_linestyle() == "--"]
    assert len(lines) == 4
    xs = sorted(float(line.get_xdata()[1]) for line in lines)
    np.testing.assert_allclose(xs, [-0.1, -0.1, 0.1, 0.1], atol=1e-12)


def test_bad_plane_and_suffix(paper_robot, tmp_path):
    from cdpm.plotting.picture import render_pose

    with pytest.raises(InputError, match="plane='top'"):
        render_pose(paper_robot, "nominal", plane="top")
    with pytest.raises(InputError, match=r"unknown image format '\.jpgg'; use one of .*jpg"):
        render_pose(paper_robot, "nominal", tmp_path / "pose.jpgg")


def test_picture_command(tmp_path, capsys):
    from cdpm.cli import main

    out = tmp_path / "pose.png"
    assert main(["picture", str(PAPER_SPEC), "--q", "pi/6", "pi/3", "-o", str(out)]) == 0
    assert "POC YES" in capsys.readouterr().out
    assert out.stat().st_size > 10_000
    assert main(["picture", str(PAPER_SPEC), "--pose", "nope", "-o", str(out)]) == 1
    assert "pose 'nope' not in spec; poses: nominal" in capsys.readouterr().err
    # the file name is checked before the spec is even read
    with pytest.raises(SystemExit) as info:
        main(["picture", "missing.yaml", "-o", str(tmp_path / "pose.jpgg")])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "argument -o/--output: cannot write pose.jpgg: unknown image format '.jpgg'" in err


def test_picture_writes_every_format_plot_writes(tmp_path, capsys):
    """cdpm picture and cdpm plot take the same image formats (one list,
    matplotlib's): a .jpg picture is a JPEG of the pose, not an error."""
    from PIL import Image

    from cdpm.cli import main
    from cdpm.plotting import image_formats

    assert {"png", "pdf", "svg", "jpg", "jpeg"} <= set(image_formats())
    out = tmp_path / "pose.jpg"
    assert main(["picture", str(PAPER_SPEC), "--pose", "nominal", "-o", str(out)]) == 0
    assert f"wrote {out}: POC YES" in capsys.readouterr().out
    with Image.open(out) as image:
        assert image.format == "JPEG" and image.size[0] > 300
        pixels = np.asarray(image.convert("RGB")).astype(int)
    # JPEG blurs colours a little: the green YES star and the pink slack cables show
    assert _count_near(pixels, COLORS["yes"], tol=30) > 60
    assert _count_near(pixels, COLORS["slack"], tol=30) > 300
    # a name without an extension gets .png, as with cdpm plot
    assert main(["picture", str(PAPER_SPEC), "--pose", "nominal", "-o", str(tmp_path / "p")]) == 0
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_missing_matplotlib_gives_install_hint():
    code = textwrap.dedent(
        f"""
        import sys
        sys.modules["matplotlib"] = None  # as if not installed
        import cdpm
        from cdpm.plotting.picture import render_pose
        try:
            render_pose(cdpm.load_robot({str(PAPER_SPEC)!r}))
        except cdpm.MissingExtraError as exc:
            print("HINT:", exc)
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
        env={**os.environ, "MPLBACKEND": "agg"},
    )
    assert out.returncode == 0, out.stderr
    assert 'pip install "cdpm[viz]"' in out.stdout


SPATIAL_SPEC = ROOT / "models" / "spatial_8cable" / "spatial_8cable.yaml"
MULTILINK_SPEC = ROOT / "models" / "multilink_arm" / "multilink_arm.yaml"


def _extents(fig):
    """Rendered boxes (display pixels) of the title, the legend and the labels."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    ax = fig.axes[0]
    labels = [t for t in ax.texts if t.get_text()]
    boxes = [t.get_window_extent(renderer) for t in labels]
    return ax.title.get_window_extent(renderer), ax.get_legend(), labels, boxes, renderer


def _inside(box, outer, slack=0.5):
    return (
        box.x0 >= outer.x0 - slack
        and box.x1 <= outer.x1 + slack
        and box.y0 >= outer.y0 - slack
        and box.y1 <= outer.y1 + slack
    )


@pytest.mark.slow
@pytest.mark.parametrize("spec, pose", [(SPATIAL_SPEC, "centre"), (MULTILINK_SPEC, "hanging")])
def test_long_titles_fit_the_figure(spec, pose, tmp_path):
    import cdpm
    from cdpm.plotting.picture import render_pose

    fig = render_pose(cdpm.load_robot(spec), pose, tmp_path / "pose.png")
    title, *_ = _extents(fig)
    assert _inside(title, fig.bbox), (title, fig.bbox)
    text = fig.axes[0].get_title()
    assert f"pose {pose!r}" in text and "POC " in text
    assert "-0 " not in text + " " and "=-0," not in text  # no negative zeros
    if spec == SPATIAL_SPEC:
        # a free flyer's coordinates are grouped under its joint's name
        assert "platform_joint: x=0, y=0, z=1, roll=0, pitch=0, yaw=0" in " ".join(text.split())


def test_a_long_custom_title_is_wrapped_to_fit(paper_robot):
    from cdpm.plotting.picture import render_pose

    words = "a caption far too long for one line of the default figure width " * 3
    fig = render_pose(paper_robot, "nominal", title=words.strip())
    title, *_ = _extents(fig)
    assert _inside(title, fig.bbox)
    assert " ".join(fig.axes[0].get_title().split()) == words.strip()


@pytest.mark.parametrize(
    "spec, pose, plane",
    [(SPATIAL_SPEC, "centre", "xy"), (SPATIAL_SPEC, "offset", "xz"), (MULTILINK_SPEC, None, "yz")],
)
def test_cable_labels_neither_collide_nor_leave_the_axes(spec, pose, plane, tmp_path):
    import cdpm
    from cdpm.plotting.picture import render_pose

    robot = cdpm.load_robot(spec)
    fig = render_pose(robot, pose, tmp_path / "pose.png", plane=plane)
    _, legend, labels, boxes, renderer = _extents(fig)
    ax = fig.axes[0]
    frame = ax.get_window_extent(renderer)
    legend_box = legend.get_window_extent(renderer)
    # the legend sits under the axes (and their x label), inside the figure
    assert legend_box.y1 < ax.xaxis.get_tightbbox(renderer).y0 and _inside(legend_box, fig.bbox)
    cable_names = {c.name for c in robot.spec.cables}
    named = set()
    for text, box in zip(labels, boxes, strict=True):
        assert _inside(box, frame), f"{text.get_text()!r} leaves the axes"
        assert not box.overlaps(legend_box), f"{text.get_text()!r} is under the legend"
        named |= {w.strip(",") for w in text.get_text().split()} & cable_names
    for i in range(len(boxes)):
        for j in range(i):
            assert not boxes[i].overlaps(boxes[j]), (labels[i].get_text(), labels[j].get_text())
    assert named == cable_names  # every cable is still named
    if plane == "xy":
        # seen from above, the upper and lower cable of a corner share an anchor and a label
        assert any(t.get_text().startswith("c1 (") and "c5" in t.get_text() for t in labels)


PENDULUM_SPEC = ROOT / "models" / "double_pendulum_cables" / "double_pendulum_cables.yaml"


@pytest.fixture(scope="module")
def pendulum():
    pytest.importorskip("cmeel", reason="example-robot-data (pip install 'cdpm[robots]')")
    import cdpm

    return cdpm.load_robot(PENDULUM_SPEC)


def _link_segments(ax):
    """Link segments drawn in ``ax`` as ((x0, y0), (x1, y1)) in plot coordinates."""
    from matplotlib.colors import to_rgb

    return [
        tuple(zip(line.get_xdata(), line.get_ydata(), strict=True))
        for line in ax.get_lines()
        if np.allclose(to_rgb(line.get_color()), COLORS["link"])
    ]


def test_output_marker_sits_on_the_output_point(pendulum, tmp_path):
    from cdpm.plotting.picture import render_pose

    # the outputs are y and z of a point 0.2 m along link2, not link2's origin
    fig = render_pose(pendulum, "leaning", tmp_path / "leaning.png", plane="yz")
    ax = fig.axes[0]
    y = pendulum.output("leaning")  # (tip_y, tip_z) [m]
    stars = [c for c in ax.collections if np.allclose(c.get_sizes(), 260)]
    assert len(stars) == 1
    np.testing.assert_allclose(stars[0].get_offsets(), [y], atol=1e-12)
    label = next(t for t in ax.texts if t.get_text() == "tip_y, tip_z")
    np.testing.assert_allclose(label.xy, y, atol=1e-12)


def test_last_link_is_drawn_to_its_points(pendulum):
    import pinocchio as pin

    from cdpm.plotting.picture import render_pose

    # link2 has no child joint: it used to be missing from the picture
    q = pendulum.as_q("leaning")
    data = pendulum.model.createData()
    pin.forwardKinematics(pendulum.model, data, q)
    joint2 = np.asarray(data.oMi[2].translation)[[1, 2]]  # link2's joint, (y, z)
    c4_on_link2 = pendulum.attachment_points(q)[3][1][[1, 2]]
    tip = pendulum.output(q)
    segments = _link_segments(render_pose(pendulum, q, plane="yz").axes[0])
    for end in (tip, c4_on_link2):
        assert any(
            np.allclose(seg[0], joint2, atol=1e-12) and np.allclose(seg[-1], end, atol=1e-12)
            for seg in segments
        ), end
    # link2 reaches up to the output point, 0.2 m from its joint
    assert np.linalg.norm(tip - joint2) == pytest.approx(0.2, abs=1e-9)


# ---------------------------------------------------------------- output kinds


def _spec_with_outputs(tmp_path, source, outputs: str):
    """A copy of the spec ``source`` (beside a copy of its URDF) with other outputs."""
    import shutil

    import cdpm

    text = source.read_text()
    head, tail = text.split("\noutputs:\n", 1)
    poses = tail[tail.index("\nposes:") :]
    spec = cdpm.load_robot(source).spec
    shutil.copy(spec.urdf_path, tmp_path / spec.urdf_path.name)
    path = tmp_path / f"{source.stem}_outputs.yaml"
    path.write_text(f"{head}\noutputs:\n{textwrap.dedent(outputs).strip()}{poses}")
    return cdpm.load_robot(path)


def _arrows(ax):
    """The arrows drawn in ``ax``: (colour, start, end) in plot coordinates."""
    from matplotlib.colors import to_rgb

    return [
        (to_rgb(t.arrow_patch.get_edgecolor()), np.array(t.xyann), np.array(t.xy))
        for t in ax.texts
        if getattr(t, "arrow_patch", None) is not None
    ]


def test_heavier_cables_are_drawn_over_lighter_ones_and_every_marker_is_explained():
    """Seen from the side, the IPAnema's upper and lower cables project onto
    each other: the heavier is drawn on top (the 389 N c1 was hidden under
    the 61 N c4), and the legend names the joints, anchors, attachments
    and centres of mass."""
    import cdpm
    from cdpm.plotting.picture import render_pose
    from cdpm.viewer.state import CableState, pose_state

    robot = cdpm.load_robot(SPATIAL_SPEC)
    fig = render_pose(robot, "offset", plane="xz")
    ax = fig.axes[0]
    state = pose_state(robot, "offset")
    cables = [ln for ln in ax.get_lines() if 3.0 <= ln.get_zorder() <= 3.1]  # in cable order
    assert len(cables) == robot.n_cables
    taut = [k for k, s in enumerate(state.cable_states) if s is CableState.TAUT]
    order = sorted(taut, key=lambda k: state.tension[k])
    z = [cables[k].get_zorder() for k in order]
    assert z == sorted(z) and len(set(z)) == len(z)  # strictly heavier on top
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    for marker in ("joint", "cable anchor on the base", "cable attachment on a link"):
        assert marker in labels


@pytest.mark.slow
def test_orientation_outputs_draw_their_frame_axes(tmp_path):
    from cdpm.plotting.picture import render_pose
    from cdpm.viewer.state import AXIS_RGB

    robot = _spec_with_outputs(
        tmp_path,
        SPATIAL_SPEC,
        """
        - {name: x, frame: platform, component: x}
        - {name: y, frame: platform, component: y}
        - {name: z, frame: platform, component: z}
        - {name: rx, frame: platform, component: rx}
        - {name: ry, frame: platform, component: ry}
        - {name: rz, frame: platform, component: rz}
        """,
    )
    fig = render_pose(robot, "offset", tmp_path / "pose.png", plane="xy")
    ax = fig.axes[0]
    # the platform at (0.5, -0.3, 1.2), turned by roll 0.05, pitch -0.05, yaw 0.1
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("xyz", [0.05, -0.05, 0.1]).as_matrix()
    arrows = _arrows(ax)
    assert [a[0] for a in arrows] == [pytest.approx(AXIS_RGB[0]), pytest.approx(AXIS_RGB[1])]
    extent = 4.0  # the scene's width, the anchors' x from -2 to 2 m
    for (_, start, end), k in zip(arrows, (0, 1), strict=True):
        np.testing.assert_allclose(start, [0.5, -0.3], atol=1e-12)
        np.testing.assert_allclose(end - start, 0.15 * extent * R[:2, k], atol=1e-9)
    # the z axis points out of the picture: named beside the origin, not drawn
    texts = [t.get_text() for t in ax.texts]
    assert "z (out)" in texts and "x" in texts and "y" in texts
    star = next(c for c in ax.collections if np.allclose(c.get_sizes(), 260))
    np.testing.assert_allclose(star.get_offsets(), [[0.5, -0.3]], atol=1e-12)
    assert "x, y, z, rx, ry, rz" in texts  # the six outputs share the platform's marker
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "orientation output: its frame's axes x, y, z" in labels
    assert any(label.startswith("output point: POC ") for label in labels)
    px = _pixels(tmp_path / "pose.png")
    assert _count_near(px, AXIS_RGB[0], tol=25) > 40 and _count_near(px, AXIS_RGB[1], tol=25) > 40


def test_joint_and_cable_outputs_get_no_marker(tmp_path):
    from cdpm.plotting.picture import render_pose

    vertical = ROOT / "models" / "two_link_vertical" / "two_link_vertical.yaml"
    robot = _spec_with_outputs(
        tmp_path,
        vertical,
        """
        - {name: elbow, joint: q2}
        - {name: c1_length, cable: c1}
        """,
    )
    fig = render_pose(robot, "nominal", tmp_path / "pose.png")
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [m]", "z [m]")
    assert not [c for c in ax.collections if np.allclose(c.get_sizes(), 260)]  # no star
    assert _arrows(ax) == []  # no triad
    # c1, from (0, 0.5) to its attachment on link1, under a halo in the verdict colour
    q1, q2 = math.pi / 6, math.pi / 3
    # (its attachment: 0.3 m past link1's centre, 0.5 m out, and 0.1 m across it)
    c1 = np.array(
        [0.8 * math.cos(q1) - 0.1 * math.sin(q1), 0.8 * math.sin(q1) + 0.1 * math.cos(q1)]
    )
    length = float(np.hypot(c1[0], c1[1] - 0.5))
    assert robot.output("nominal") == pytest.approx([q2, length], abs=1e-12)
    (halo,) = [line for line in ax.get_lines() if line.get_alpha() == 0.35]
    np.testing.assert_allclose(halo.get_xydata(), [[0.0, 0.5], c1], atol=1e-12)
    from cdpm.viewer import pose_state

    verdict = pose_state(robot, "nominal").verdict_rgb
    assert halo.get_color() == verdict
    # the joint output is named at its joint, (cos q1, sin q1)
    (elbow,) = [t for t in ax.texts if t.get_text() == "elbow"]
    np.testing.assert_allclose(elbow.xy, [math.cos(q1), math.sin(q1)], atol=1e-12)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert f"elbow = {q2:.3g} rad: joint q2" in labels
    assert f"c1_length = {length:.3g} m: cable c1" in labels
    assert not any(label.startswith("output point") for label in labels)
    # the halo on white: the verdict's green at alpha 0.35
    light_green = 0.65 + 0.35 * np.array(COLORS["yes"])
    assert _count_near(_pixels(tmp_path / "pose.png"), light_green, tol=6) > 200
