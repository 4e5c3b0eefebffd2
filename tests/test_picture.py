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


def test_paper_figure(paper_robot, tmp_path):
    from cdpm.picture import render_pose

    path = tmp_path / "nominal.png"
    fig = render_pose(paper_robot, "nominal", path)
    ax = fig.axes[0]
    assert "POC YES (margin" in ax.get_title()
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
    from cdpm.picture import render_pose

    fig = render_pose(paper_robot, [math.pi / 2, 0.0], plane="xz", title="side")
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel(), ax.get_title()) == ("x [m]", "z [m]", "side")
    # at q = (pi/2, 0) the links lie along y: attachments 0.1 either side, x = -+0.1
    lines = [line for line in ax.get_lines() if line.get_linestyle() == "--"]
    assert len(lines) == 4
    xs = sorted(float(line.get_xdata()[1]) for line in lines)
    np.testing.assert_allclose(xs, [-0.1, -0.1, 0.1, 0.1], atol=1e-12)


def test_bad_plane_and_suffix(paper_robot, tmp_path):
    from cdpm.picture import render_pose

    with pytest.raises(InputError, match="plane='top'"):
        render_pose(paper_robot, "nominal", plane="top")
    with pytest.raises(InputError, match="use a .png, .pdf or .svg name"):
        render_pose(paper_robot, "nominal", tmp_path / "pose.jpeg")


def test_picture_command(tmp_path, capsys):
    from cdpm.cli import main

    out = tmp_path / "pose.png"
    assert main(["picture", str(PAPER_SPEC), "--q", "pi/6", "pi/3", "-o", str(out)]) == 0
    assert "POC YES" in capsys.readouterr().out
    assert out.stat().st_size > 10_000
    assert main(["picture", str(PAPER_SPEC), "--pose", "nope", "-o", str(out)]) == 1
    assert "pose 'nope' not in spec; poses: nominal" in capsys.readouterr().err


def test_missing_matplotlib_gives_install_hint():
    code = textwrap.dedent(
        f"""
        import sys
        sys.modules["matplotlib"] = None  # as if not installed
        import cdpm
        from cdpm.picture import render_pose
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
