"""The command line, run in-process through cdpm.cli.main."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from cdpm.cli import main
from tests.conftest import PAPER_SPEC


def test_analyze_paper_nominal_text(capsys):
    assert main(["analyze", str(PAPER_SPEC), "--pose", "nominal"]) == 0
    out = capsys.readouterr().out
    assert "two_link_planar.yaml, pose 'nominal'" in out
    poc_line = next(line for line in out.splitlines() if "Positive output controllability" in line)
    pc_line = next(line for line in out.splitlines() if "Positive controllability" in line)
    assert "YES" in poc_line.upper()
    assert "NO" in pc_line.upper()
    # B row 3 of eq 25 and the Remark 11 witness (0, 0, -2, -1) / sqrt(5)
    assert "[ 0.4999 -0.0462 -0.3372 -0.822 ]" in out
    assert "-0.8944, -0.4472]" in out


def test_analyze_json_matches_explicit_q(capsys):
    assert main(["analyze", str(PAPER_SPEC), "--pose", "nominal", "--json"]) == 0
    by_pose = json.loads(capsys.readouterr().out)
    assert main(["analyze", str(PAPER_SPEC), "--q", "pi/6", "pi/3", "--json"]) == 0
    by_q = json.loads(capsys.readouterr().out)
    assert by_pose["pose"] == "nominal" and by_q["pose"] is None
    np.testing.assert_allclose(by_q["linearisation"]["B"], by_pose["linearisation"]["B"], atol=0)
    poc = by_pose["positive_output_controllability"]
    assert poc["verdict"] == "yes"
    pc = by_pose["positive_controllability"]
    assert pc["verdict"] == "no"
    witness = np.array(pc["witness"], dtype=float)
    np.testing.assert_allclose(
        witness / np.linalg.norm(witness), np.array([0, 0, -2, -1]) / np.sqrt(5), atol=1e-9
    )


def test_negative_expressions_are_values_not_options(capsys):
    assert main(["analyze", str(PAPER_SPEC), "--q", "-pi/6", "pi/3", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(report["q"], [-np.pi / 6, np.pi / 3], atol=1e-15)


def test_errors_are_one_line_messages(capsys, tmp_path):
    assert main(["analyze", str(tmp_path / "missing.yaml"), "--pose", "nominal"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("cdpm analyze: error: cable spec file not found")
    assert "Traceback" not in err
    assert main(["analyze", str(PAPER_SPEC), "--q", "1", "2", "3"]) == 1
    assert "expected nq=2" in capsys.readouterr().err
    assert main(["analyze", str(PAPER_SPEC), "--pose", "home"]) == 1
    assert "pose 'home' not in spec; poses: nominal" in capsys.readouterr().err


def test_help_is_useful(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "analyze" in out and "positive output controllability" in out.lower()
    with pytest.raises(SystemExit):
        main(["analyze", "--help"])
    out = capsys.readouterr().out
    assert "--pose NAME" in out and "examples:" in out
    assert main([]) == 2


def test_console_script_entry_point():
    result = subprocess.run(
        [sys.executable, "-m", "cdpm.cli", "analyze", str(PAPER_SPEC), "--pose", "nominal"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "Positive output controllability" in result.stdout


def test_public_names_survive_submodule_imports():
    import importlib
    import pkgutil

    import cdpm

    for info in pkgutil.walk_packages(cdpm.__path__, "cdpm."):
        if info.name.split(".")[-1] in ("viewer", "picture", "plotting"):
            continue  # optional extras, imported by their own tests
        importlib.import_module(info.name)
    assert callable(cdpm.linearise) and callable(cdpm.positive_output_controllability)
    for name in cdpm.__all__:
        assert not isinstance(getattr(cdpm, name), type(cdpm)), name
