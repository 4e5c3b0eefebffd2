"""What the pose report says, in words a new user reads right: a taut cable
never shows a tension of 0, a singular pose says so, a singular mass
matrix is named as the cause, and a notebook shows the report, not a
dump of its fields."""

from __future__ import annotations

import json
import shlex
import shutil

import numpy as np
import pytest

import cdpm
from cdpm.cli import main
from tests.conftest import PAPER_SPEC, ROOT, caspr_models

VERTICAL = ROOT / "models" / "two_link_vertical"
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def _cable_rows(text: str) -> dict[str, list[str]]:
    """The cable table of a report: name -> [length, tension, state, ...]."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.split()[:2] == ["name", "length"])
    rows = {}
    for line in lines[start + 1 :]:
        if not line.startswith("  ") or not line.strip():
            break
        name, *rest = line.split()
        rows[name] = rest
    return rows


# ------------------------------------------------- a taut cable is never 0 N


def test_tension_texts_keep_a_taut_cable_off_zero():
    from cdpm.text.format import tension_table, tension_texts

    # taut cables to their own digits, cables at a bound rounded to the largest
    assert tension_texts([31.0921, 3.5e-9, 1e-15], [False, False, True]) == [
        "31.0921",
        "3.5e-09",
        "0",
    ]
    table = tension_table(
        ["c1", "c2", "c3"],
        [1.0, 1.0, 1.0],
        [10.0, 3.5e-9, 2e-14],
        ["taut", "taut", "slack"],
        ["free", "free", "u >= 0"],
        "input",
    )
    assert table[2].split()[:4] == ["c2", "1.000000", "3.5e-09", "taut"]
    assert table[3].split()[:4] == ["c3", "1.000000", "0", "slack"]


def test_analyze_prints_a_tiny_taut_tension_as_it_is(capsys):
    """A cable at 3.5e-9 N beside one at 10 N printed "0 ... taut": the
    state and the value contradicted each other."""
    scipy_linalg = pytest.importorskip("scipy.linalg")
    robot = cdpm.load_robot(PAPER_SPEC)
    q = [0.86, -1.45]  # wrench closure: internal forces that keep every cable taut
    N = scipy_linalg.null_space(robot.cable_jacobian(q).T)  # (4, 2)
    internal = N @ [N[0, 1], -N[0, 0]]  # no tension on c1, the others pull
    internal /= internal[2]
    assert np.all(internal[1:] > 0.05)
    f = 10.0 * internal + 3.5e-9 * (N @ np.linalg.lstsq(N[[0]], [1.0], rcond=None)[0])
    f[0] = 3.5e-9
    tension = [repr(float(x)) for x in f]
    code, out, _ = _run(["analyze", PAPER_SPEC, "--q", *q, "--tension", *tension], capsys)
    assert code == 0
    rows = _cable_rows(out)
    assert rows["c1"][1:3] == ["3.5e-09", "taut"]
    assert rows["c3"][1:3] == ["10", "taut"]
    for name, row in rows.items():
        assert not (row[2] == "taut" and float(row[1]) == 0.0), (name, row)


# --------------------------------------------------------- singular poses


def test_analyze_says_when_a_pose_is_singular(capsys):
    """At the arm stretched out level, tip_x's row of C is zero: cdpm
    analyze says so, in the viewer's words, in its text and its JSON."""
    args = ["analyze", VERTICAL, "--pose", "horizontal"]
    code, out, _ = _run(args, capsys)
    assert code == 0
    note = (
        "singular pose: the output Jacobian dy/dq has rank 1 < p = 2, so to first order "
        "the outputs cannot move in some direction"
    )
    assert f"  note:        {note}" in out.splitlines()
    code, out, _ = _run([*args, "--json"], capsys)
    assert code == 0 and json.loads(out)["notes"] == [note]
    # a regular pose has none
    code, out, _ = _run(["analyze", VERTICAL, "--pose", "nominal"], capsys)
    assert code == 0 and "singular pose" not in out
    code, out, _ = _run(["analyze", VERTICAL, "--pose", "nominal", "--json"], capsys)
    assert json.loads(out)["notes"] == []


def test_the_viewer_and_the_report_note_the_same_singular_pose():
    from cdpm.viewer.panel import pose_panel

    robot = cdpm.load_robot(VERTICAL)
    report = cdpm.analyze_pose(robot, "horizontal")
    assert len(report.singular_notes) == 1
    assert pose_panel(robot, "horizontal").notes == report.singular_notes


def test_the_readme_pretension_example_sits_at_a_regular_pose(capsys):
    lines = [line for line in README.splitlines() if "--tension pretension --pretension" in line]
    assert len(lines) == 1
    argv = shlex.split(lines[0].split("#")[0])
    assert argv[:2] == ["cdpm", "analyze"]
    code, out, _ = _run(argv[1:], capsys)
    assert code == 0
    assert "Equilibrium (pretension, pretension 10 N): statics hold" in out
    assert "singular pose" not in out
    assert "Positive output controllability (Theorem 1): YES" in out


# --------------------------------------------------- singular mass matrix


@pytest.fixture
def massless_elbow(tmp_path):
    """The vertical arm with link 2's mass on the elbow axis and no inertia:
    the elbow moves nothing, so the mass matrix is singular at every pose."""
    folder = tmp_path / "massless_elbow"
    shutil.copytree(VERTICAL, folder)
    urdf = folder / "two_link_vertical.urdf"
    text = urdf.read_text(encoding="utf-8")
    link2 = text.index('<link name="link2">')
    before, after = text[:link2], text[link2:]
    after = after.replace('<origin xyz="0.5 0 0" rpy="0 0 0"/>', '<origin xyz="0 0 0"/>', 1)
    urdf.write_text(before + after, encoding="utf-8")
    return folder


def test_a_singular_mass_matrix_is_named_as_the_cause(massless_elbow, capsys):
    """No tension holds the pose (method zero under gravity) and the mass
    matrix is singular: the report names the mass matrix and its fix, as
    the map status does, not only the missing equilibrium."""
    robot = cdpm.load_robot(massless_elbow)
    assert np.linalg.matrix_rank(robot.mass_matrix(robot.poses["nominal"])) == 1
    args = ["analyze", massless_elbow, "--pose", "nominal", "--tension", "zero"]
    code, out, err = _run(args, capsys)
    assert code == 3
    assert err.startswith("cdpm analyze: error: the mass matrix is singular at this pose")
    assert "give that body inertia about every axis in the URDF" in err
    assert "no equilibrium at this pose" not in err
    assert "status:                 singular_mass_matrix (2)" in out
    section = out.split("No linearisation and no verdicts:", 1)[1].split("\n\n", 1)[0]
    words = " ".join(section.split())
    assert words.startswith("the mass matrix is singular at this pose: a body has zero inertia")
    assert "To fix: give that body inertia" in words
    code, out, _ = _run([*args, "--json"], capsys)
    data = json.loads(out)
    assert data["feasible"] is False
    assert data["reason"].startswith("the mass matrix is singular at this pose")
    report = cdpm.analyze_pose(robot, "nominal", tension="zero", infeasible="report")
    assert report.singular_mass_matrix
    assert "singular mass matrix" in repr(report)


def test_without_a_singular_mass_matrix_the_missing_equilibrium_is_the_cause(capsys):
    code, out, err = _run(["analyze", VERTICAL, "--pose", "nominal", "--tension", "zero"], capsys)
    assert code == 3
    assert err.startswith("cdpm analyze: error: no equilibrium at this pose with method 'zero'")
    assert "mass matrix" not in out + err


CASPR, CASPR_MISSING = caspr_models()


@pytest.mark.skipif(CASPR_MISSING is not None, reason=CASPR_MISSING or "")
def test_carex_names_its_singular_mass_matrix(tmp_path, capsys):
    """CASPR's CAREX: both bodies have izz = 0, so at its initial pose
    the mass matrix is singular (and no tension within [3, 45] N holds it)."""
    pytest.importorskip("yourdfpy")
    import warnings

    from cdpm.caspr import CasprWarning, import_caspr

    folder = CASPR / "MCDM" / "CAREX"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CasprWarning)
        spec = import_caspr(
            folder / "CAREX_bodies.xml", folder / "CAREX_cables.xml", tmp_path / "CAREX"
        ).spec_path
    code, out, err = _run(["analyze", spec], capsys)
    assert code == 3
    assert err.startswith("cdpm analyze: error: the mass matrix is singular at this pose")
    assert "status:                 singular_mass_matrix (2)" in out
    assert "No linearisation and no verdicts:\n  the mass matrix is singular" in out
    code, out, err = _run(["analyze", spec, "--tension", "best"], capsys)
    assert code == 3
    assert err.startswith("cdpm analyze: error: the mass matrix is singular at this pose")


# ------------------------------------------------------ notebook cells


def test_reports_show_in_a_notebook_as_their_text():
    pretty = pytest.importorskip("IPython.lib.pretty").pretty
    robot = cdpm.load_robot(PAPER_SPEC)
    report = cdpm.analyze_pose(robot, "nominal")
    # IPython's text and the html are the report, the repr one short line
    assert pretty(report) == str(report)
    assert report._repr_html_().startswith("<pre>cdpm report: two_link_planar.yaml")
    assert repr(report) == (
        "<PoseReport two_link_planar.yaml, pose 'nominal': POC YES (nilpotent), r_T = 0.1501 m>"
    )
    eq = report.equilibrium
    assert pretty(eq) == str(eq)
    assert repr(eq) == (
        "<EquilibriumResult (min_norm): feasible, statics residual 0, 0 of 4 cables taut>"
    )
    infeasible = cdpm.analyze_pose(
        cdpm.load_robot(VERTICAL), "nominal", tension="zero", infeasible="report"
    )
    assert pretty(infeasible) == str(infeasible)
    assert repr(infeasible) == (
        "<InfeasiblePoseReport two_link_vertical.yaml, pose 'nominal': no equilibrium by "
        "method 'zero', no verdicts>"
    )


def test_a_zero_reach_margin_says_what_cannot_be_reached(capsys):
    """At a NO pose r_T = 0: the sentence says the cables cannot move the
    outputs in some direction, not that they move them 0 m everywhere."""
    spec = ROOT / "models" / "two_link_two_cables" / "two_link_two_cables.yaml"
    main(["analyze", str(spec), "--pose", "nominal"])
    out = capsys.readouterr().out
    assert "cannot move tip_x in some direction of output space" in out
    assert "0 m in every direction" not in out


def test_json_has_no_negative_zero(capsys):
    """At an output-rank NO pose the margin is 0, not -0.0, in JSON too."""
    from cdpm.printing import json_text

    assert json_text({"margin": -0.0, "bracket": [-0.0, 0.0]}, None) == (
        '{"margin": 0.0, "bracket": [0.0, 0.0]}'
    )
    spec = VERTICAL / "two_link_vertical.yaml"
    main(["analyze", str(spec), "--pose", "horizontal", "--json"])
    out = capsys.readouterr().out
    assert "-0.0," not in out and "-0.0]" not in out and "-0.0\n" not in out
