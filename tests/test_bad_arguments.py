"""Bad command-line arguments: every one is a short error naming the
problem (exit 1 or 2), never a traceback, and nothing is left behind."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from cdpm.cli import main

MODELS = Path(__file__).parent.parent / "models"
PLANAR = str(MODELS / "two_link_planar")


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("bad")
    assert main(["map", PLANAR, "--axis", "q1=0:1:4", "--axis", "q2=0:1:4"]
                + ["--out", str(root / "m.zarr"), "--workers", "1", "--quiet"]) == 0  # fmt: skip
    (root / "afolder").mkdir()
    return root


# (arguments with {d} for the folder, text the error must contain)
TABLE = [
    (["picture", PLANAR, "-o", "/proc/x.png"], "cannot"),
    (["picture", PLANAR, "-o", "{d}/nodir/x.png"], "does not exist"),
    (["picture", PLANAR, "-o", "{d}/x.png", "--dpi", "100000"], "from 1 to 1200"),
    (["picture", PLANAR, "-o", "{d}/afolder"], "is a folder"),
    (["plot", "{d}/m.zarr", "-o", "/proc/p.png"], "cannot"),
    (["plot", "{d}/m.zarr", "-o", "{d}/afolder"], "is a folder"),
    (["plot", "{d}/m.zarr", "-o", "{d}/p.png", "--dpi", "1e6"], "from 1 to 1200"),
    (["plot", "{d}/none.zarr", "-o", "{d}/p.png"], "not found"),
    (
        [
            "map",
            PLANAR,
            "--axis",
            "q1=0:1:100000",
            "--axis",
            "q2=0:1:1000000",
            "--out",
            "{d}/big.zarr",
        ],
        "more than the 10,000,000,000",
    ),  # fmt: skip
    (["map", PLANAR, "--axis", "q1=0:1:100000000", "--out", "{d}/big.zarr"], "COUNT must be"),
    (
        ["map", PLANAR, "--axis", "q1=0:1", "--samples", "1000000000000", "--out", "{d}/big.zarr"],
        "GiB for their coordinates",
    ),  # fmt: skip
    (["map", PLANAR, "--axis", "q1=0:1:5", "--out", "/etc/passwd/x.zarr"], "is a file"),
    (["map", PLANAR, "--axis", "q1=0:1:5", "--out", "/proc/x.zarr"], "cannot write"),
    (
        [
            "map",
            PLANAR,
            "--axis",
            "q1=0:1",
            "--samples",
            "5",
            "--seed",
            "-1",
            "--out",
            "{d}/s.zarr",
        ],
        "seed must be",
    ),  # fmt: skip
    (
        ["map", PLANAR, "--axis", "q1=0:1:5", "--out", "{d}/d.zarr", "--scheduler", "garbage"],
        "not HOST:PORT",
    ),  # fmt: skip
    (
        [
            "map",
            PLANAR,
            "--axis",
            "q1=0:1:5",
            "--out",
            "{d}/d.zarr",
            "--scheduler",
            "tcp://127.0.0.1:99999",
        ],
        "outside 1..65535",
    ),  # fmt: skip
    (
        ["map", PLANAR, "--axis", "q1=0:1:5", "--out", "{d}/d.zarr", "--chunk-size", "0"],
        "--chunk-size 0: give a whole number >= 1",
    ),  # fmt: skip
    (
        ["map", PLANAR, "--axis", "q1=0:1", "--samples", "-5", "--out", "{d}/d.zarr"],
        "--samples -5: give a whole number >= 1",
    ),
    (
        ["map", PLANAR, "--axis", "q1=0:1:5", "--out", "{d}/d.zarr", "--horizon", "nan"],
        "horizon",
    ),  # fmt: skip
    (["view", PLANAR, "--seconds", "nan"], "--seconds"),
    (["view", PLANAR, "--port", "99999"], "not a TCP port"),
    (["import-caspr", "--out", "/proc/imp", "x", "y"], "not found"),
    (["analyze", PLANAR, "--q", "1e400", "0"], "too large for a number"),
    (["analyze", PLANAR, "--q", "(-1)**0.5", "0"], "not a real number"),
    (["analyze", PLANAR, "--q", "+".join(["1"] * 3000), "0"], "at most 200"),
    (["analyze", PLANAR, "--tension", "nan", "nan", "nan", "nan"], "not a number"),
    (["analyze", PLANAR, "--output", "/proc/x.json", "--format", "json"], "cannot"),
    (["analyze", PLANAR, "--neighbourhood", "0.1", "--points", "100001"], "give fewer --points"),
    (["analyze", "{d}/nothing.yaml"], "not found"),
    (["analyze", "a\0b"], "NUL"),
    (["path", "{d}/m.zarr", "--from", "0", "0", "--to", "1e300", "1"], "off the map"),
    (["verify", PLANAR, "--radius", "1e300"], "to its size"),
    (["find", PLANAR, "--tries", "100000000"], "at most 1,000,000 poses"),
    (
        ["plot", "{d}/m.zarr", "-o", "{d}/p.png", "--variable", "poc_some_tension"],
        "--tension best",
    ),  # fmt: skip
]


@pytest.mark.slow
@pytest.mark.parametrize(("argv", "expected"), TABLE, ids=[" ".join(a[:3]) for a, _ in TABLE])
def test_bad_argument_is_one_short_error(folder, argv, expected, capsys):
    argv = [a.replace("{d}", str(folder)) for a in argv]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's usage errors
        code = exc.code
    err = capsys.readouterr().err
    assert code in (1, 2), err
    assert "Traceback" not in err
    assert expected in err, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("cdpm"), err
    assert len(err) < 4000
    for leftover in ("big.zarr", "s.zarr", "d.zarr", "nodir"):
        assert not (folder / leftover).exists(), leftover
    shutil.rmtree(folder / "x.png", ignore_errors=True)
