"""Failures found in the last round of hostile inputs (second batch): the
reach margin of robots with many cables, maps run from ``python -c`` or a
script on stdin, URDFs with very many joints."""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
import yaml

import cdpm
from cdpm.analysis.reach import reach_margins, zonotope_inradii
from cdpm.cli import main
from cdpm.errors import ModelError
from cdpm.numerics import MAX_MODEL_DOF
from tests.conftest import MODELS

SPATIAL = MODELS / "spatial_8cable"
ROOT = Path(__file__).resolve().parents[1]

# --------------------------------------------------------------------------
# 1. the reach margin of 128 cables and 3 outputs


def test_reach_margin_of_128_cables_is_computed_on_fewer_intervals():
    # x' = -a x + B u, y = x, |u_j| <= 1: e^{A t} B = e^{-a t} B, one sign
    # for every direction and t, so R_T = (1 - e^{-a T}) / a {B u} and
    # piecewise-constant inputs reach all of it (no Jensen gap)
    rng = np.random.default_rng(7)
    n, m, a, T = 3, 128, 2.0, 0.5
    B = rng.normal(size=(n, m))
    A = -a * np.eye(n)
    r = reach_margins(A[None], B[None], np.eye(n)[None], -np.ones((1, m)), np.ones((1, m)), T)
    box = zonotope_inradii(B[None], np.zeros((1, n)))[0]
    expected = (1 - math.exp(-a * T)) / a * box
    assert r.intervals[0] == 4  # 12 would exceed REACH_MAX_FACET_WORK
    # the bracket [value, value + error] holds the exact r_T and is narrow
    assert abs(r.value[0] - expected) < 1e-9 * expected
    assert 0 <= r.error[0] < 1e-3 * expected


def _many_cables(tmp_path, count: int):
    shutil.copy(SPATIAL / "spatial_8cable.urdf", tmp_path)
    spec = yaml.safe_load((SPATIAL / "spatial_8cable.yaml").read_text())
    cables = []
    for i in range(count):
        route = [dict(point) for point in spec["cables"][i % 8]["route"]]
        x, y, z = route[0]["point"]
        shift = 0.001 * (i // 8)
        route[0] = {"frame": "world", "point": [x + shift, y - shift, z]}
        cables.append({"name": f"c{i}", "tension": [0, 720], "route": route})
    spec["cables"] = cables
    path = tmp_path / "many.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_analyze_prints_a_reach_margin_for_128_cables(tmp_path, capsys):
    spec = _many_cables(tmp_path, 128)
    assert main(["analyze", str(spec), "--q", "0", "0", "1", "0", "0", "0", "1"]) == 0
    out = capsys.readouterr().out
    assert "nan" not in out
    line = next(s for s in out.splitlines() if "Reach margin r_T" in s)
    assert "not computed" not in line and float(line.split("= ")[1].split()[0]) > 0


# --------------------------------------------------------------------------
# 2. maps with workers from `python -c` and from a script on stdin

_MAP_SCRIPT = f"""
import numpy as np
import cdpm

if __name__ == "__main__":
    robot = cdpm.load_robot({str(MODELS / "two_link_planar" / "two_link_planar.yaml")!r})
    axes = {{name: np.linspace(-1, 1, 4) for name in robot.coordinate_names}}
    ds = cdpm.workspace_map(robot, axes, workers=2, chunk_size=4)
    print("poses", ds.sizes["q1"] * ds.sizes["q2"])
"""


def _marked_processes(marker: str) -> list[int]:
    """Processes whose environment holds ``marker`` (ours and their children)."""
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                environ = Path("/proc", entry, "environ").read_bytes()
            except OSError:
                continue
            if marker.encode() in environ:
                found.append(int(entry))
    return found


def _run_python(arguments, tmp_path, stdin=None):
    marker = f"CDPM_TEST_MARKER=map-{uuid.uuid4().hex}"
    env = dict(os.environ, PYTHONPATH=str(ROOT), CDPM_TEST_MARKER=marker.split("=")[1])
    done = subprocess.run(
        [sys.executable, *arguments],
        cwd=tmp_path,
        env=env,
        input=stdin,
        capture_output=True,
        text=True,
        timeout=300,
    )
    deadline = time.monotonic() + 10
    while _marked_processes(marker) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _marked_processes(marker) == [], "a worker or fork server was left behind"
    return done


@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="needs Linux /proc")
def test_map_with_workers_from_a_script_on_stdin_falls_back_to_one(tmp_path):
    done = _run_python(["-"], tmp_path, stdin=_MAP_SCRIPT)
    assert done.returncode == 0, done.stderr
    assert "poses 16" in done.stdout
    assert "workspace_map runs with workers=1, not 2" in done.stderr
    assert "<stdin>" in done.stderr and "main" in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="needs Linux /proc")
def test_map_with_workers_from_python_c_runs(tmp_path):
    done = _run_python(["-c", _MAP_SCRIPT], tmp_path)
    assert done.returncode == 0, done.stderr
    assert "poses 16" in done.stdout
    assert "Traceback" not in done.stderr


# --------------------------------------------------------------------------
# 3. a URDF with about 1,000 joints


def _chain(tmp_path, joints: int) -> Path:
    """A planar chain of ``joints`` revolute joints, two cables on its tip."""
    inertial = (
        '<inertial><origin xyz="0.05 0 0"/><mass value="0.1"/><inertia ixx="1e-4" ixy="0" '
        'ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial>'
    )
    links = ['<link name="base"/>'] + [
        f'<link name="l{i}">{inertial}</link>' for i in range(joints)
    ]
    chain = [
        f'<joint name="j{i}" type="revolute"><parent link="{"base" if i == 0 else f"l{i - 1}"}"/>'
        f'<child link="l{i}"/><origin xyz="{0 if i == 0 else 0.1} 0 0"/><axis xyz="0 0 1"/>'
        '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
        for i in range(joints)
    ]
    (tmp_path / "chain.urdf").write_text(f'<robot name="chain">{"".join(links + chain)}</robot>')
    tip = f"l{joints - 1}"
    spec = {
        "urdf": "chain.urdf",
        "gravity": [0, -9.81, 0],
        "cables": [
            {
                "name": name,
                "tension": [0, 100],
                "route": [
                    {"frame": "world", "point": [0, y, 0]},
                    {"frame": tip, "point": [0.1, 0, 0]},
                ],
            }
            for name, y in (("a", 1), ("b", -1))
        ],
        "outputs": [{"name": "x", "frame": tip, "point": [0.1, 0, 0], "component": "x"}],
    }
    path = tmp_path / "chain.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_a_thousand_joints_are_refused_at_load_with_a_model_error(tmp_path, capsys):
    spec = _chain(tmp_path, 999)  # 1,000 links: within MAX_URDF_LINKS
    with pytest.raises(ModelError, match=r"999 moving joints .* more than the 200 cdpm analyses"):
        cdpm.load_robot(spec)
    assert main(["analyze", str(spec), "--q", "0"]) != 0
    err = capsys.readouterr().err
    assert "999 moving joints" in err and "fewer poses" not in err


def test_the_degree_of_freedom_limit_is_exact(tmp_path):
    with pytest.raises(ModelError, match=f"{MAX_MODEL_DOF + 1} degrees of freedom"):
        cdpm.load_robot(_chain(tmp_path, MAX_MODEL_DOF + 1))
    assert cdpm.load_robot(_chain(tmp_path, 20)).nv == 20


def test_a_criterion_not_computed_prints_so_not_nan_with_a_unit():
    """A map criterion left at its NaN fill (a margin too large to search,
    a pose not analysed) reads "not computed", never "nan m"."""
    from cdpm.text.format import criteria_lines

    lines = criteria_lines({"reach_margin": np.nan, "reach_margin_error": 0.5})
    assert lines[0].split(":", 1)[1].strip() == "not computed (NaN)"
    assert lines[1].split(":", 1)[1].strip() == "0.5 m"
