"""The command line, run in-process through cdpm.cli.main."""

from __future__ import annotations

import json
import re
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


# ------------------------------------------------------------------ cdpm map


@pytest.mark.parametrize(
    ("axis", "message"),
    [
        ("q1=0,1,", r"value 3 of axis 'q1' is empty; remove the stray ','"),
        ("q1=0,,1", r"value 2 of axis 'q1' is empty"),
        ("q1=,", r"value 1 of axis 'q1' is empty"),
        ("q1=:1:3", r"LOW of axis 'q1' is empty"),
        ("q1=0:1:5,", r"axis 'q1' mixes a range \(':'\) and a list \(','\)"),
        ("q1=0:inf:3", r"HIGH of axis 'q1' is inf; axis values must be finite"),
        ("q1=-inf,1", r"value 1 of axis 'q1' is -inf; axis values must be finite"),
        ("q1=0:1:x", r"COUNT of axis 'q1' must be an integer, got 'x'"),
    ],
)
def test_map_axis_items_are_all_checked(axis, message, capsys):
    import re

    assert main(["map", str(PAPER_SPEC), "--axis", axis, "--quiet", "--workers", "1"]) == 1
    out, err = capsys.readouterr()
    assert re.search(message, err), err
    assert err.startswith(f"cdpm map: error: --axis {axis!r}") and "Warning" not in err
    assert out == ""


def test_map_axis_given_twice_is_an_error(capsys):
    argv = ["map", str(PAPER_SPEC), "--axis", "q1=0:1:3", "--axis", "q1=0,1", "--quiet"]
    assert main(argv) == 1
    out, err = capsys.readouterr()
    assert "--axis q1 is given twice ('q1=0:1:3' and 'q1=0,1')" in err
    assert "NAME=V1,V2" in err and out == ""


def test_map_plot_is_checked_before_computing(tmp_path, capsys, monkeypatch):
    store = tmp_path / "m.zarr"
    argv = ["map", str(PAPER_SPEC), "--axis", "q1=0:1:3", "--out", str(store), "--quiet"]
    assert main([*argv, "--plot", str(tmp_path / "m.xyz")]) == 1
    err = capsys.readouterr().err
    assert "--plot" in err and "unknown image format '.xyz'" in err and "png" in err
    assert not store.exists()
    # matplotlib missing: the install hint, and nothing computed
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setitem(sys.modules, "matplotlib.backend_bases", None)
    assert main([*argv, "--plot", str(tmp_path / "m.png")]) == 1
    err = capsys.readouterr().err
    assert "--plot needs matplotlib: pip install 'cdpm[maps]'" in err
    assert not store.exists()


def test_map_store_with_other_settings_names_the_fix(tmp_path, capsys):
    store = str(tmp_path / "m.zarr")
    common = ["--out", store, "--quiet", "--workers", "1"]
    assert main(["map", str(PAPER_SPEC), "--axis", "q1=0:1:3", *common]) == 0
    capsys.readouterr()
    assert main(["map", str(PAPER_SPEC), "--axis", "q1=0:1:4", *common]) == 1
    err = capsys.readouterr().err
    assert "axis 'q1': stored 3 values" in err and "add --overwrite" in err
    assert "re-run with the stored settings" in err and "overwrite=True" not in err


def test_map_interrupted_ends_the_progress_line_and_resumes(tmp_path, capsys, monkeypatch):
    import cdpm.maps

    real = cdpm.maps.workspace_map

    def interrupted_after_one_chunk(robot, axes, **kwargs):
        def progress(done, total, index):
            sys.stderr.write(f"\rmap {done}/{total} poses")  # a bar redrawn in place
            if index >= 0:
                sys.stderr.write("\n")  # as the real bar ends its line when interrupted
                raise KeyboardInterrupt

        return real(robot, axes, **{**kwargs, "progress": progress})

    store = tmp_path / "m.zarr"
    argv = ["map", str(PAPER_SPEC), "--axis", "q1=0:1:12", "--out", str(store)]
    argv += ["--workers", "1", "--chunk-size", "4"]
    monkeypatch.setattr(cdpm.maps, "workspace_map", interrupted_after_one_chunk)
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert "map 4/12 poses\ncdpm map: interrupted; " in err and "\n\n" not in err
    assert f"the 1 finished chunk is kept in {store}: run the same command again" in err
    # the same command again computes only the 8 poses of the two chunks left
    totals = []

    def recording(robot, axes, **kwargs):
        progress = lambda done, total, index: totals.append(total)  # noqa: E731
        return real(robot, axes, **{**kwargs, "progress": progress})

    monkeypatch.setattr(cdpm.maps, "workspace_map", recording)
    assert main(argv) == 0
    assert "12 poses" in capsys.readouterr().out
    assert totals and set(totals) == {8}


# -------------------------------------------------------------- cdpm analyze


@pytest.mark.parametrize(
    ("q", "message"),
    [
        (["abc"], r"--q value: 'abc' is not a number .*one number per coordinate \(q1, q2\)"),
        (["0.5", "x"], r"--q value 2 of 2: 'x' is not a number"),
        (["1", "2", "3"], r"--q 1 2 3: q has 3 entries, expected nq=2"),
        (["1", "inf"], r"--q 1 inf: q\[1\] = inf: coordinates must be finite"),
        (
            ["1", "1e300"],
            r"--q 1 1e300: q\[1\] = 1e\+300: coordinates must be finite numbers of at most 100000",
        ),
    ],
)
def test_analyze_bad_q_names_the_option(q, message, capsys):
    import re

    assert main(["analyze", str(PAPER_SPEC), "--q", *q]) == 1
    err = capsys.readouterr().err
    assert re.search(f"^cdpm analyze: error: {message}", err), err


def test_analyze_prints_no_negative_zeros(capsys):
    import re

    from tests.conftest import MODELS

    # q1 = -0 exactly, and the spatial robot's pitch (and many matrix entries)
    # are -0.0 or round to it; numpy prints those as "-0."
    for argv in (
        ["analyze", str(PAPER_SPEC), "--q", "-0", "pi/3"],
        ["analyze", str(MODELS / "spatial_8cable")],
        ["analyze", str(MODELS / "multilink_arm")],
    ):
        assert main(argv) == 0
        out = capsys.readouterr().out
        assert not re.search(r"(?<![\w.])-0(\.0*)?(?![\w.])", out), out
    assert main(["analyze", str(PAPER_SPEC), "--q", "-0", "pi/3"]) == 0
    out = capsys.readouterr().out
    assert "coordinates: q1 = 0, q2 = 1.0472" in out
    # numbers that are not zero keep their sign, columns stay aligned
    assert main(["analyze", str(MODELS / "multilink_arm")]) == 0
    out = capsys.readouterr().out
    b_rows = out[out.index("  B =\n") : out.index("  C =\n")].splitlines()[1:]
    assert len({len(row.rstrip("]")) for row in b_rows}) == 1, b_rows
    assert any("-0.3192" in row for row in b_rows) and any(" 0.  " in row for row in b_rows)


def test_analyze_pretension_flag_is_never_silently_ignored(capsys):
    from tests.conftest import MODELS

    vertical = str(MODELS / "two_link_vertical")  # spec: method min_norm, pretension 10
    assert main(["analyze", vertical, "--pose", "nominal", "--pretension", "5"]) == 1
    err = capsys.readouterr().err
    assert (
        "--pretension 5 only applies to --tension pretension, and this analysis uses method "
        "'min_norm' (two_link_vertical.yaml's equilibrium.method): add --tension pretension"
    ) in err
    argv = ["analyze", vertical, "--pose", "horizontal", "--tension", "zero", "--pretension", "5"]
    assert main(argv) == 1
    assert "this analysis uses method 'zero': add --tension pretension" in capsys.readouterr().err
    argv = ["analyze", str(PAPER_SPEC), "--tension", "0", "0", "0", "0", "--pretension", "5"]
    assert main(argv) == 1
    assert "this analysis uses given tensions" in capsys.readouterr().err
    # the pretension method with no pretension anywhere is min_norm in disguise
    assert main(["analyze", str(PAPER_SPEC), "--tension", "pretension"]) == 1
    err = capsys.readouterr().err
    assert (
        "--tension pretension needs a pretension > 0 N and two_link_planar.yaml gives none" in err
    )
    assert "add --pretension N" in err
    # ... asked for explicitly, it runs, with a warning on stderr
    argv = ["analyze", str(PAPER_SPEC), "--tension", "pretension", "--pretension", "0", "--json"]
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["equilibrium"]["method"] == "pretension"
    assert err.startswith("cdpm analyze: warning: the 'pretension' method with a pretension of 0")
    assert "(--pretension N or the spec's equilibrium.pretension)" in err


def test_analyze_infeasible_names_the_options(capsys):
    from tests.conftest import MODELS

    vertical = str(MODELS / "two_link_vertical")
    argv = ["analyze", vertical, "--pose", "nominal", "--tension", "pretension"]
    assert main([*argv, "--pretension", "10"]) == 3  # the report, marked infeasible
    err = capsys.readouterr().err
    assert err.startswith("cdpm analyze: error: no equilibrium at this pose")
    assert "try a lower pretension (--pretension N, now 10 N), --tension min_norm" in err
    assert "pretension=" not in err and "(QP exit flag" not in err


def test_map_pretension_method_needs_the_spec_pretension(tmp_path, capsys):
    argv = ["map", str(PAPER_SPEC), "--axis", "q1=0:1:3", "--tension", "pretension", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "m.zarr")]) == 1
    err = capsys.readouterr().err
    assert (
        "--tension pretension needs a pretension > 0 N, and two_link_planar.yaml gives none" in err
    )
    assert "set equilibrium: {pretension: N} in the spec" in err
    assert not (tmp_path / "m.zarr").exists()


def _map_raising(exc: BaseException, store, monkeypatch) -> int:
    """``cdpm map`` to ``store`` with a workspace_map that raises ``exc``
    at once; the exit status."""
    import cdpm.maps

    def raising(robot, axes, **kwargs):
        raise exc

    monkeypatch.setattr(cdpm.maps, "workspace_map", raising)
    return main(["map", str(PAPER_SPEC), "--axis", "q1=0:1:12", "--out", str(store)])


def test_map_interrupted_before_a_chunk_says_nothing_was_kept(tmp_path, capsys, monkeypatch):
    """Ctrl-C before the first chunk is finished (or before the store is
    made) does not claim finished chunks in a store that may not exist."""
    store = tmp_path / "m.zarr"
    assert _map_raising(KeyboardInterrupt(), store, monkeypatch) == 130
    err = capsys.readouterr().err
    assert f"{store} was not opened yet: run the same command again to make or resume it" in err
    assert "kept" not in err and not store.exists()


def test_a_full_disk_names_the_output_and_the_fix(tmp_path, capsys, monkeypatch):
    """A write the system refuses for want of space names the output being
    written (the error itself names no file) and says to free space, not to
    choose a path whose folder exists."""
    import errno

    store = tmp_path / "m.zarr"
    full = OSError(errno.ENOSPC, "No space left on device")
    assert _map_raising(full, store, monkeypatch) == 1
    err = capsys.readouterr().err
    assert f"cannot write {str(store)!r}: No space left on device; free some space" in err
    assert "folder must exist" not in err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["anlyze", "x.yaml"], r"unknown command 'anlyze'; did you mean 'analyze'\?"),
        (["mpa"], r"unknown command 'mpa'; did you mean 'map'\?"),
        (["zzz"], r"unknown command 'zzz'; commands: analyze, .*import-caspr \(cdpm --help\)"),
    ],
)
def test_a_misspelt_command_gets_the_nearest_names(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, err  # one line, no usage text
    assert re.search(message, err), err


def test_top_level_help_shows_examples_of_the_main_commands(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for command in ("analyze", "map", "path", "find", "verify", "view"):
        assert f"\n  cdpm {command} " in out, command
