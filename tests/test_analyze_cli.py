"""``cdpm analyze`` at poses without an equilibrium, its printed numbers, its
options (--points, folders as SPEC) and the words of its messages."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import warnings

import numpy as np
import pytest

import cdpm
from cdpm.cli import main
from tests.conftest import MODELS, PAPER_SPEC

VERTICAL = str(MODELS / "two_link_vertical" / "two_link_vertical.yaml")
#: two_link_vertical: zero tension cannot hold the stretched arm against gravity
ZERO_AT_STRETCHED = ["analyze", VERTICAL, "--q", "0", "0", "--tension", "zero"]
#: two_link_vertical: no tension within the bounds holds this pose (min_norm)
NOWHERE = [-0.5, -1.0]
# a number printed in scientific notation with an exponent of -10 or below
TINY = re.compile(r"\d(?:\.\d+)?e-(?:1\d|[2-9]\d|\d{3})\b")


# ----------------------------------------------------- no equilibrium at the pose


def test_the_statics_residual_has_its_unit_at_a_held_pose(capsys):
    assert main(["analyze", VERTICAL, "--pose", "nominal"]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("Equilibrium (min_norm)"))
    assert line.startswith("Equilibrium (min_norm): statics hold, residual |L^T f + G + w_ext| = ")
    assert line.endswith(" (N or N m)")


def test_infeasible_pose_prints_the_report_and_exits_3(capsys):
    assert main(ZERO_AT_STRETCHED) == 3
    out, err = capsys.readouterr()
    assert "coordinates: q1 = 0, q2 = 0" in out
    assert "outputs:     tip_x = 2 m, tip_z = 0 m" in out  # arm of 1 + 1 m along x
    assert "Equilibrium (zero): INFEASIBLE, residual |L^T f + G + w_ext| = 20.2 (N or N m)" in out
    # cable lengths (kinematics) and the closest tensions the method allows
    assert re.search(r"c1 +0\.894427 +0 +slack +\[0, inf\]", out), out
    assert "No linearisation and no verdicts:" in out
    assert "static_feasible is yes" in out  # min_norm holds this pose
    assert "status:                 no_equilibrium (3)" in out
    assert "poc:                    not_analysed (-1)" in out
    assert "Linearisation (state" not in out and "Verdicts" not in out
    # stderr says why and what to change, in the command's words
    assert err.startswith("cdpm analyze: error: no equilibrium at this pose with method 'zero'")
    assert "(--tension min_norm)" in err and "tension=" not in err


def test_infeasible_report_shows_the_solvers_closest_tensions(vertical, capsys):
    with pytest.raises(cdpm.InfeasibleEquilibriumError) as info:
        cdpm.linearise(vertical, NOWHERE)
    closest = info.value.result
    assert main(["analyze", VERTICAL, "--q", "-0.5", "-1", "--json"]) == 3
    report = json.loads(capsys.readouterr().out)
    assert report["feasible"] is False
    tensions = [cable["tension"] for cable in report["cables"]]
    np.testing.assert_allclose(tensions, closest.tension, rtol=0, atol=0)
    assert tensions[0] == pytest.approx(38.6681, abs=1e-4) and tensions[1:] == [0, 0, 0]
    assert report["statics_residual"] == pytest.approx(closest.residual, rel=1e-12)
    assert report["statics_residual"] == pytest.approx(0.346966, abs=1e-6)
    assert report["equilibrium"]["feasible"] is False
    assert report["cables"][0]["length"] == pytest.approx(1.093518, abs=1e-6)
    assert report["cables"][0]["tension_max"] is None  # no upper bound: not Infinity
    for key in ("linearisation", "positive_output_controllability", "reach"):
        assert report[key] is None
    assert report["criteria"]["status"] == cdpm.STATUS_CODES["no_equilibrium"]
    assert report["criteria"]["static_feasible"] == 0  # no method holds it
    assert "no tension" in report["reason"]


def test_feasible_json_says_so(capsys):
    assert main(["analyze", str(PAPER_SPEC), "--pose", "nominal", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["feasible"] is True


def test_analyze_pose_raises_or_reports(vertical):
    with pytest.raises(cdpm.InfeasibleEquilibriumError, match="no equilibrium"):
        cdpm.analyze_pose(vertical, NOWHERE)
    report = cdpm.analyze_pose(vertical, NOWHERE, infeasible="report")
    assert not report.feasible
    assert report.equilibrium.residual == pytest.approx(0.346966, abs=1e-6)
    assert "INFEASIBLE" in str(report) and "INFEASIBLE" in report._repr_html_()
    assert cdpm.analyze_pose(vertical, "nominal", infeasible="report").feasible
    with pytest.raises(cdpm.InputError, match="'raise' or 'report'"):
        cdpm.analyze_pose(vertical, "nominal", infeasible="ignore")


def test_help_documents_the_exit_status(capsys):
    with pytest.raises(SystemExit):
        main(["analyze", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "exit status:" in text and "3 no tension within the cable bounds holds the pose" in text


@pytest.fixture()
def vertical():
    return cdpm.load_robot(VERTICAL)


# ------------------------------------------------------------ printed numbers


@pytest.mark.parametrize(
    ("argv", "outputs", "every_number"),
    [
        ([str(PAPER_SPEC), "--q", "pi/2", "0"], "tip_x = 0 m", True),  # tip_x is 1.2e-16
        # the tip on the shoulder: C is round-off too, and the POC verdict's own
        # numbers show it (an analysis matter, not a printing one)
        ([str(PAPER_SPEC), "--q", "0", "pi"], "tip_x = 0 m", False),
        ([VERTICAL, "--q", "-3*pi/4", "-pi"], "tip_x = 0 m, tip_z = 0 m", True),  # folded
        ([VERTICAL, "--q", "-pi", "-pi"], "tip_x = 0 m, tip_z = 0 m", True),
        (
            [str(MODELS / "double_pendulum_cables"), "--q", "-pi", "-pi"],
            "tip_y = 0 m, tip_z = 0.135 m",
            True,
        ),
    ],
)
def test_round_off_prints_as_zero(argv, outputs, every_number, capsys):
    assert main(["analyze", *argv]) == 0
    out = capsys.readouterr().out
    assert f"outputs:     {outputs}\n" in out
    assert f"y:                      {outputs}\n" in out
    assert not re.search(r"(?<![\w.])-0(\.0*)?(?![\w.])", out)
    if every_number:
        # the residual measures round-off itself; every other number is
        # rounded to its scale (a margin, an eigenvalue, an impulse index too)
        tiny = [line for line in out.splitlines() if TINY.search(line)]
        assert all("residual" in line for line in tiny), tiny


def test_decided_round_off_prints_as_zero(capsys):
    # the folded vertical arm: impulse index -1.6e-16 (NO), and at q2 = -pi
    # the witness eigenvalue 3.8e-22 of a 4x4 A of order 30
    assert main(["analyze", VERTICAL, "--q", "-3*pi/4", "-pi"]) == 0
    assert "NO (output-rank; impulse index 0 on" in capsys.readouterr().out
    assert main(["analyze", VERTICAL, "--q", "0", "-pi"]) == 0
    out = capsys.readouterr().out
    assert "(eigenvalue 0)" in out and "(A^T v = 0 v)" in out


def test_wide_matrices_keep_one_line_per_row(capsys):
    assert main(["analyze", str(MODELS / "spatial_8cable"), "--pose", "offset"]) == 0
    out = capsys.readouterr().out
    a_rows = out[out.index("  A =\n") : out.index("  B =\n")].splitlines()[1:]
    assert len(a_rows) == 12, a_rows  # 12 states, not wrapped
    assert all(len(row) <= 200 for row in a_rows)
    # the states named above A, in the platform's own frame, on lines of at most 100
    states = out[out.index("  states: ") : out.index("  A =\n")]
    assert "platform_joint.d_x, " in states and states.rstrip().endswith("platform_joint.w_z")
    assert all(len(line) <= 100 for line in states.splitlines())
    # B is of order 0.03: more decimals keep its small entries readable
    assert "-0.028443" in out


# ---------------------------------------------------------------- the command


@pytest.mark.slow
def test_python_dash_m_runs_the_cli():
    result = subprocess.run(
        [sys.executable, "-m", "cdpm", "analyze", str(PAPER_SPEC), "--pose", "nominal"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "Positive output controllability (Theorem 1): YES" in result.stdout


def test_a_folder_of_specs_lists_them(capsys, tmp_path):
    assert main(["analyze", str(MODELS) + "/"]) == 1
    err = capsys.readouterr().err
    head = f"cdpm analyze: error: {MODELS}/ is a folder; give one of the specs in it: "
    assert err.startswith(head + f"{MODELS}/double_pendulum_cables/double_pendulum_cables.yaml, ")
    assert f"{MODELS}/spatial_8cable/spatial_8cable_pose.yaml, " in err
    assert "not found" not in err
    # a model folder is its spec, named after it or the only one
    assert main(["analyze", str(MODELS / "two_link_planar"), "--pose", "nominal"]) == 0
    assert "two_link_planar.yaml, pose 'nominal'" in capsys.readouterr().out
    arm = tmp_path / "arm"
    arm.mkdir()
    shutil.copy(PAPER_SPEC, arm / "paper.yaml")
    shutil.copy(PAPER_SPEC.with_suffix(".urdf"), arm)
    assert main(["analyze", str(arm), "--pose", "nominal"]) == 0
    assert "paper.yaml, pose 'nominal'" in capsys.readouterr().out
    assert main(["analyze", str(tmp_path / "arm" / ".."), "--pose", "nominal"]) == 0
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["analyze", str(empty)]) == 1
    assert f"{empty} is a folder with no cable spec" in capsys.readouterr().err


def test_neighbourhood_points_reach_the_map(capsys):
    argv = ["analyze", str(PAPER_SPEC), "--pose", "nominal", "--neighbourhood", "0.5"]
    assert main([*argv, "--points", "11", "--json"]) == 0
    ball = json.loads(capsys.readouterr().out)["neighbourhood"]
    assert ball["points"] == 11 and ball["pose"] == "nominal"
    assert main([*argv, "--points", "11"]) == 0
    assert "11x11 grid" in capsys.readouterr().out
    report = cdpm.analyze_pose(
        cdpm.load_robot(PAPER_SPEC), "nominal", neighbourhood=0.5, neighbourhood_points=5
    )
    assert report.neighbourhood.points == 5
    for points, message in (
        ("4", "--points must be an odd integer >= 1"),
        ("-3", "--points must be an odd integer >= 1"),
        ("2001", "--points 2001 over 2 coordinates is a grid of 4,004,001 poses"),
    ):
        assert main([*argv, "--points", points]) == 1
        assert message in capsys.readouterr().err
    assert main(["analyze", str(PAPER_SPEC), "--points", "11"]) == 1
    assert "add --neighbourhood R" in capsys.readouterr().err
    assert main(["analyze", str(PAPER_SPEC), "--neighbourhood", "-1"]) == 1
    assert "--neighbourhood must be a positive number" in capsys.readouterr().err


# ------------------------------------------------- messages name CLI options


PYTHON_WORDS = re.compile(r"=None|pretension=|tension=|\w+=N\b")


@pytest.mark.parametrize(
    ("argv", "code", "expected"),
    [
        (
            ["analyze", VERTICAL, "--tension", "1", "2", "3", "4"],
            1,
            "leave out --tension or name a method (--tension zero, --tension min_norm",
        ),
        (
            ["steer", VERTICAL, "--tension", "1", "2", "3", "4", "--by", "0.001", "0.001"],
            1,
            "leave out --tension or name a method",
        ),
        (ZERO_AT_STRETCHED, 3, "let the cables take the load (--tension min_norm)"),
        (
            ["analyze", VERTICAL, "--pose", "nominal", "--tension", "pretension"],
            3,
            "try a lower pretension (--pretension N, now 10 N)",
        ),
        (
            ["analyze", str(PAPER_SPEC), "--tension", "pretension", "--pretension", "0"],
            0,
            "cdpm analyze: warning: the 'pretension' method with a pretension of 0 N",
        ),
    ],
)
def test_cli_messages_name_options_not_python_arguments(argv, code, expected, capsys):
    assert main(argv) == code
    err = capsys.readouterr().err
    assert expected in err
    assert not PYTHON_WORDS.search(err), err


def test_python_messages_keep_naming_arguments(vertical):
    with pytest.raises(cdpm.InputError, match=r"omit the tension \(tension=None\)") as info:
        cdpm.linearise(vertical, "nominal", tension=[1, 2, 3, 4])
    assert "tension='min_norm'" in str(info.value) and info.value.result.residual > 1
    with pytest.warns(cdpm.EquilibriumWarning, match=r"\(pretension=N or the spec"):
        cdpm.equilibrium_tension(vertical, "nominal", method="pretension", pretension=0)


def test_cli_equilibrium_respells_warnings_for_every_command(vertical, capsys):
    from cdpm.cli._tension import cli_equilibrium

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing may escape as a Python warning
        eq = cli_equilibrium(
            cdpm.equilibrium_tension, vertical, "nominal", method="pretension", pretension=0
        )
    assert eq.feasible
    err = capsys.readouterr().err
    assert err.startswith("cdpm: warning: the 'pretension' method with a pretension of 0 N")
    assert "(--pretension N or the spec's equilibrium.pretension)" in err
    assert err.count("warning") == 1


def test_json_output_is_strict_json_at_an_infeasible_pose(capsys):
    """NaN is not JSON: non-finite numbers are written as null."""
    vertical = str(MODELS / "two_link_vertical" / "two_link_vertical.yaml")
    code = main(["analyze", vertical, "--q", "0", "0", "--tension", "zero", "--format", "json"])
    assert code == 3
    text = capsys.readouterr().out
    assert "NaN" not in text and "Infinity" not in text
    data = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert data["criteria"]["reach_margin"] is None


def test_submodules_are_attributes_after_a_plain_import():
    import cdpm

    assert callable(cdpm.maps.open_map) and callable(cdpm.dynamics.reach.reach_settings)


def test_analyze_without_the_reach_margin(capsys):
    import math

    spec = str(MODELS / "spatial_8cable" / "spatial_8cable_pose.yaml")
    assert main(["analyze", spec, "--pose", "centre", "--no-margin"]) == 0
    out = capsys.readouterr().out
    assert "Positive output controllability (Theorem 1): YES" in out
    assert "Reach margin" not in out and "reach_margin" not in out
    report = cdpm.analyze_pose(cdpm.load_robot(spec), "centre", margin=False)
    assert report.reach is None and math.isnan(report.reach_margin[0])
    assert report.as_dict()["reach"] is None


def test_more_outputs_than_degrees_of_freedom_is_said(tmp_path, capsys):
    folder = tmp_path / "arm"
    shutil.copytree(MODELS / "two_link_vertical", folder)
    spec = folder / "two_link_vertical.yaml"
    text = re.sub(
        r"(?ms)^outputs:.*?(?=^\w)",
        "outputs:\n  - {frame: tip, component: x}\n  - {frame: tip, component: z}\n"
        "  - {joint: q2}\n",
        spec.read_text(),
    )
    spec.write_text(text)
    assert main(["analyze", str(spec), "--pose", "nominal", "--no-margin"]) == 0
    out = capsys.readouterr().out
    assert "(3 outputs, 2 degrees of freedom: never output controllable)" in out
    assert "Positive output controllability (Theorem 1): NO" in out


def test_wrench_closure_certificate_names_the_cables():
    """The report's wrench-closure certificate names the cables as the spec
    does (c1...), not by 0-based column numbers, which read as the wrong
    cable (column 2 is c3); the API's text keeps the column numbers."""
    from pathlib import Path

    spec = Path(__file__).resolve().parents[1] / "models" / "spatial_8cable" / "spatial_8cable.yaml"
    robot = cdpm.load_robot(spec)
    report = cdpm.analyze_pose(robot, robot.poses[next(iter(robot.poses))], margin=False)
    text = str(report)
    line = next(x for x in text.splitlines() if "with weights (largest 1)" in x)
    names = ", ".join(report.linearisation.cable_names)
    assert line.strip().startswith(f"cables [{names}]")
    assert str(report.wrench_closure).splitlines()[-1].strip().startswith("columns [0, 1")
    # the JSON keeps the 0-based indices and names the cables beside them
    cert = report.as_dict()["wrench_closure"]["certificate"]
    assert cert["cables"] == [report.linearisation.cable_names[i] for i in cert["indices"]]
    assert cert["cables"][:2] == list(report.linearisation.cable_names[:2])
