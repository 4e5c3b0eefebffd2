"""What a new user stumbled on: a compile notice on a busy machine that
compiled nothing, a CASPR body without inertia imported silently, a default
reach horizon too long to resolve, a steering target beyond the robot's
reach simulated a dozen times, and the thin-NO-set estimate of regions
read as a fact."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cdpm.pipeline import compiled

ROOT = Path(__file__).resolve().parents[1]

# --------------------------------------------------------------------------
# 1. the compile notice: said when numba compiles, not when loading is slow


def test_no_compile_notice_when_a_warm_load_is_slow(monkeypatch):
    """A slow first call on a busy machine that loads every kernel from the
    cache (here: already loaded) is no compile: nothing is said. (The old
    notice was a timer; with its delay at 0 s it fired here.)"""
    notices = []
    real = compiled._load_kernels

    def slow_load():
        real()
        time.sleep(0.2)  # a busy machine

    monkeypatch.setattr(compiled, "_LOADED", compiled.threading.Event())  # a new process
    monkeypatch.setattr(compiled, "_load_kernels", slow_load)
    monkeypatch.setattr(compiled, "COMPILE_NOTICE_SECONDS", 0.0, raising=False)
    compiled.load_kernels(notices.append)
    time.sleep(0.1)  # a timer thread would have spoken by now
    assert notices == []
    assert compiled._LOADED.is_set()


def test_compiling_other_numba_code_gives_no_notice():
    """The notice speaks of cdpm's kernels: a program's own numba function
    compiled meanwhile does not trigger it."""
    numba = pytest.importorskip("numba")
    from cdpm.jit import compile_notice

    @numba.njit
    def own(x):  # compiled in this test module, not in cdpm
        return x + 1

    notices = []
    with compile_notice(notices.append):
        assert own(1) == 2
    assert notices == []


@pytest.mark.slow
def test_compile_notice_once_with_a_cold_cache(tmp_path):
    """With an empty numba cache (NUMBA_CACHE_DIR a new folder) the kernels
    are compiled, and the notice is given exactly once."""
    code = (
        "from cdpm.pipeline.compiled import load_kernels\n"
        "said = []\n"
        "load_kernels(said.append)\n"
        "print(len(said)); print(said[0] if said else '')\n"
    )
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    proc = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    count, text = proc.stdout.splitlines()[:2]
    assert count == "1"
    assert "compiling cdpm's numba kernels" in text
    assert any((tmp_path / "numba-cache").rglob("*.nbi"))  # it did compile there


# --------------------------------------------------------------------------
# 5. the thin-NO-set estimate of regions: said to be one, and checked


def test_neighbourhood_resamples_steps_where_r_t_only_looked_steep(paper_robot):
    """`cdpm analyze --neighbourhood 0.5` at the paper's pose: all 10,201
    sampled poses are YES. The slope estimate flagged 518 steps; resampled
    along each, 363 clear (r_T falls steeply but stays clear of 0) and the
    radius grows from 0.16 to 0.17 rad; the 155 left straddle the NO line
    0.1745 rad away (r_T falls to 2e-5 m between samples), which the text
    says is an estimate, not a proof."""
    import cdpm
    from cdpm.text import neighbourhood_lines

    nb = cdpm.poc_neighbourhood(paper_robot, "nominal", 0.5)
    assert nb.counts["yes"] == nb.n_poses == 101**2
    assert nb.box_bracket == pytest.approx((0.17, 0.18), abs=1e-12)
    assert (nb.suspect_cleared, nb.suspect_edges) == (363, 155)
    assert nb.suspect_least.margin < 1e-4
    lines = neighbourhood_lines(nb)
    assert "not a proof; every sampled pose is YES" in lines[1]
    assert any("518 step(s) flagged, resampled at 7770 more poses: 363 cleared" in x for x in lines)


def test_no_thin_no_set_line_when_nothing_was_flagged(paper_robot):
    import cdpm
    from cdpm.text import neighbourhood_lines

    nb = cdpm.poc_neighbourhood(paper_robot, "nominal", 0.1, points=21)
    assert nb.whole_box_yes and nb.suspect_edges == nb.suspect_cleared == 0
    text = "\n".join(neighbourhood_lines(nb))
    assert "suspect" not in text and "thin NO" not in text


def test_map_summary_calls_the_thin_no_set_count_an_estimate(tmp_path, capsys):
    """A 100 % YES map of the paper's arm: the steps where a thin NO set may
    pass are counted, as an estimate (a NO line does cross it)."""
    from cdpm.cli import main
    from tests.conftest import PAPER_SPEC

    store = tmp_path / "m.zarr"
    axes = ["--axis", "q1=0:1:11", "--axis", "q2=0.8:1.8:11"]
    assert main(["map", str(PAPER_SPEC), *axes, "--out", str(store), "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "yes 121 (100.0%)" in out
    assert "an estimate from its sampled slopes, not a proof" in out
