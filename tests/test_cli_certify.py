"""``cdpm certify``: a small certified map on the command line, its store,
plot and JSON summary, its help, and its errors (one line, no traceback)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import cdpm
from cdpm.cli import main
from tests.conftest import MODELS, PAPER_SPEC

#: 3 x 3 cells across the edge of the paper arm's proven-NO patch
AXES = ["--axis", "q1=1.40:1.50:3", "--axis", "q2=1.55:1.65:3", "--min-fraction", "1/4"]


def _cli(argv, capsys) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_help_says_what_an_axis_count_means(capsys):
    with pytest.raises(SystemExit) as done:
        main(["certify", "--help"])
    assert done.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "NAME=LOW:HIGH:CELLS: CELLS equal cells from LOW to HIGH (CELLS + 1 edges" in out
    assert "q1=-pi:pi:61 is 61 cells" in out
    assert "Exit status: 0 done" in out and "130 interrupted" in out
    for option in ("--min-fraction", "--out", "--overwrite", "--workers", "--scheduler"):
        assert option in out
    for option in ("--plot", "--compare", "--json", "--horizon", "--tension-budget"):
        assert option in out
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "certify" in capsys.readouterr().out


def test_a_small_map_with_store_plot_and_json(tmp_path, capsys):
    store, image = tmp_path / "c.zarr", tmp_path / "c.png"
    argv = ["certify", str(PAPER_SPEC), *AXES, "--out", str(store), "--workers", "1"]
    code, out, err = _cli([*argv, "--plot", str(image), "--json"], capsys)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["cells"] == [3, 3] and summary["coordinates"] == ["q1", "q2"]
    assert summary["min_fraction"] == 0.25
    f = summary["fractions"]
    assert f["yes"] > 0 and f["no"] > 0 and f["undecided"] > 0
    assert sum(f.values()) == pytest.approx(1.0)
    assert summary["regions"] >= 1 and 0 < summary["largest_region_fraction"] <= f["yes"]
    assert summary["boxes"] == sum(summary["boxes_by_verdict"].values())
    assert summary["store"] == str(store) and summary["plot"] == str(image)
    assert image.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "certifying 9 cells" in err  # what runs where goes to stderr with --json
    m = cdpm.open_certified(store)
    assert m.verdict.size == summary["boxes"]
    assert m.fractions() == pytest.approx(f)
    # the same command again reads the store
    code, out, err = _cli([*argv, "--quiet"], capsys)
    assert code == 0, err
    assert "certified map read from" in out
    assert "proven YES" in out and "certified regions (YES boxes joined" in out
    assert "(3 x 3 cells, least box 0.25 of a cell's width)" in out


def test_other_settings_on_a_store_name_the_fix(tmp_path, capsys):
    store = tmp_path / "c.zarr"
    where = ["--out", str(store), "--workers", "1", "--quiet"]
    assert _cli(["certify", str(PAPER_SPEC), *AXES, *where], capsys)[0] == 0
    half = [*AXES[:-1], "1/2"]
    code, out, err = _cli(["certify", str(PAPER_SPEC), *half, *where], capsys)
    assert code == 1
    assert "min_fraction: stored 0.25, now 0.5" in err and "add --overwrite" in err
    assert "Traceback" not in err
    code, out, err = _cli(["certify", str(PAPER_SPEC), *half, *where, "--overwrite"], capsys)
    assert code == 0, err


def test_a_robot_in_neither_case_is_undecided_with_its_reason(capsys, tmp_path):
    from tests.conftest import neither_case_spec

    vertical = neither_case_spec(tmp_path)
    code, out, err = _cli(
        ["certify", str(vertical), "--axis", "q1=0:1:2", "--axis", "q2=0:1:1", "--quiet"], capsys
    )
    assert code == 0, err
    assert "undecided 100.00%" in out and "under load" in out
    assert "certified regions: none" in out


@pytest.mark.slow
def test_a_compared_plot_draws_the_sampled_outline(tmp_path, capsys):
    sampled = tmp_path / "m.zarr"
    cdpm.workspace_map(
        PAPER_SPEC,
        {"q1": np.linspace(1.40, 1.50, 7), "q2": np.linspace(1.55, 1.65, 7)},
        store=sampled,
        workers=1,
    )
    image = tmp_path / "cmp.png"
    argv = ["certify", str(PAPER_SPEC), *AXES, "--workers", "1", "--quiet"]
    code, out, err = _cli([*argv, "--plot", str(image), "--compare", str(sampled)], capsys)
    assert code == 0, err
    assert image.stat().st_size > 0
    from cdpm.plotting.certified import plot_certified

    m = cdpm.certify_map(
        PAPER_SPEC,
        {"q1": np.linspace(1.40, 1.50, 4), "q2": np.linspace(1.55, 1.65, 4)},
        min_fraction=0.25,
        workers=1,
    )
    fig = plot_certified(m, sampled)
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0].startswith("proven YES (") and "of the volume" in labels[0]
    assert labels[1].startswith("proven NO (") and labels[2].startswith("undecided (")
    assert labels[3] == "sampled map: edge of its YES poses"
    assert ax.get_xlabel() == "q1 [rad]" and ax.get_ylabel() == "q2 [rad]"
    # one polygon per drawn box
    assert sum(len(c.get_paths()) for c in ax.collections[:3]) == m.verdict.size


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--axis", "q1=0:1"], "expected NAME=LOW:HIGH:CELLS"),
        (["--axis", "q1=0:1:0"], "CELLS must be from 1"),
        (["--axis", "q1=1:0:3"], "LOW must be below HIGH"),
        (["--axis", "q1=0,0.5,0.4"], "at least two increasing edges"),
        (["--axis", "q1=0:1:x"], "CELLS of axis 'q1' must be a whole number"),
        (["--axis", "q9=0:1:2"], "unknown coordinate 'q9'"),
        (["--axis", "q1=0:1:2", "--axis", "q1=0:1:3"], "given twice"),
        (["--axis", "q1=0:1:2", "--min-fraction", "2"], "--min-fraction 2: give a fraction"),
        (["--axis", "q1=0:1:2", "--out", "c.png"], "not an image (.png): give --out c.zarr"),
        (["--axis", "q1=0:1:2", "--compare", "m.zarr"], "--compare draws over the plot"),
        (["--axis", "q1=0:1:2", "--plot", "c.xyz"], "unknown image format"),
        (["--axis", "q1=0:1:2", "--workers", "2", "--scheduler", "tcp://h:1"], "--workers 2"),
        (["--axis", "q1=0:9:2"], "leaves the joint limits"),
    ],
)
def test_errors_are_one_line_without_traceback(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = _cli(["certify", str(PAPER_SPEC), *argv, "--quiet"], capsys)
    assert code == 1
    assert err.startswith("cdpm certify: error:") and message in err
    assert "Traceback" not in err


def test_a_missing_spec_is_an_error(tmp_path, capsys):
    code, out, err = _cli(["certify", str(tmp_path / "none.yaml"), "--axis", "q1=0:1:2"], capsys)
    assert code == 1 and err.startswith("cdpm certify: error:") and "Traceback" not in err


def test_an_interrupt_says_how_to_resume(tmp_path, capsys, monkeypatch):
    import cdpm.certify.map as certify_module

    store = tmp_path / "c.zarr"
    (store / ".cdpm" / "done").mkdir(parents=True)
    (store / ".cdpm" / "done" / "0").touch()

    def interrupted(*args, **kwargs):
        exc = KeyboardInterrupt()
        exc.certified_store = str(store)
        raise exc

    monkeypatch.setattr(certify_module, "certify_map", interrupted)
    code, out, err = _cli(["certify", str(PAPER_SPEC), *AXES, "--out", str(store)], capsys)
    assert code == 130
    assert "cdpm certify: interrupted; the 1 finished chunk is kept in" in err
    assert "run the same command again to resume" in err


def _synthetic_map(d: int, verdicts: list[int], reason: str = "a reason"):
    """A certified map of one box per cell over d coordinates (no proofs:
    pictures only), cells of [0, 1] split in len(verdicts) along the first."""
    from cdpm.certify.box import CertifiedBoxes
    from cdpm.certify.map import map_of_boxes

    n = len(verdicts)
    edges = [np.linspace(0.0, 1.0, n + 1)] + [np.array([0.0, 1.0])] * (d - 1)
    lower = np.zeros((n, d))
    upper = np.ones((n, d))
    lower[:, 0], upper[:, 0] = edges[0][:-1], edges[0][1:]
    boxes = CertifiedBoxes(
        lower,
        upper,
        np.array(verdicts, dtype=np.int8),
        np.array([reason] * n),
        np.full(n, np.nan),
        1.0,
        1.0,
        "m",
        np.zeros(n + 1, dtype=np.int64),
        np.zeros(0, dtype=np.int64),
        np.zeros((0, 0, 2)),
        np.zeros(0, dtype=np.int64),
        np.full((n, 1), np.nan),
    )
    names = tuple(f"c{k}" for k in range(d))
    return map_of_boxes(
        boxes, np.arange(n), names, np.full(d, 0.5), tuple(range(d)), edges, 0.5, ("m",) * d
    )


@pytest.mark.parametrize("d", [1, 3])
def test_plots_of_one_and_three_coordinates(d, tmp_path):
    from cdpm.plotting.certified import plot_certified, save_certified_plot
    from cdpm.verdicts import MARGINAL, NO, YES

    m = _synthetic_map(d, [YES, NO, MARGINAL, YES])
    fig = plot_certified(m)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "c0 [m]"
    assert sum(len(c.get_paths()) for c in ax.collections) == 4
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == [
        "proven YES (50.0% of the volume)",
        "proven NO (25.0%)",
        "undecided (25.0%)",
    ]
    if d == 3:
        assert ax.get_title() == "slice through the base pose at c2 = 0.5 m"
        assert ax.get_ylabel() == "c1 [m]"
    undecided = _synthetic_map(d, [MARGINAL, MARGINAL], reason="the robot is under load")
    ax = plot_certified(undecided).axes[0]
    assert "nothing proven: the robot is under load" in ax.get_title()
    out = save_certified_plot(m, tmp_path / "p")
    assert out.name == "p.png" and out.read_bytes()[:4] == b"\x89PNG"


def test_a_compared_map_over_other_coordinates_is_refused_first(tmp_path, capsys):
    sampled = tmp_path / "m.zarr"
    cdpm.workspace_map(PAPER_SPEC, {"q1": [0.4, 0.5]}, store=sampled, workers=1)
    argv = ["certify", str(PAPER_SPEC), *AXES, "--plot", str(tmp_path / "c.png")]
    code, out, err = _cli([*argv, "--compare", str(sampled), "--quiet"], capsys)
    assert code == 1 and "Traceback" not in err
    assert (
        f"--compare {sampled}: the compared map must be a sampled map over a grid of q1, q2" in err
    )
    assert "this one maps q1" in err and not (tmp_path / "c.png").exists()


def test_a_least_box_below_the_floor_is_refused_before_any_work(capsys):
    """A least box of 1e-9 of a cell would bisect along a NO curve for ever:
    refused at once, naming the floor."""
    code, out, err = _cli(
        [
            "certify",
            str(PAPER_SPEC),
            "--axis",
            "q1=0.3:0.7:2",
            "--axis",
            "q2=0.9:1.3:2",
            "--min-fraction",
            "1e-9",
        ],
        capsys,
    )
    assert code == 1 and "[1/4096, 1]" in err and "never finish" in err
    with pytest.raises(cdpm.InputError, match=r"min_fraction must be a number in \[2\^-12"):
        cdpm.certify_map(PAPER_SPEC, {"q1": [0.3, 0.7]}, base=[0.5, 1.0], min_fraction=1e-9)


def test_the_summary_names_the_least_box_made(capsys):
    code, out, _ = _cli(
        [
            "certify",
            str(PAPER_SPEC),
            "--axis",
            "q1=0.3:0.7:2",
            "--axis",
            "q2=0.9:1.3:2",
            "--min-fraction",
            "0.3",
            "--quiet",
        ],
        capsys,
    )
    assert code == 0 and "least box 0.25 of a cell's width" in out


def test_a_map_of_another_spec_is_not_compared(tmp_path, capsys):
    other = MODELS / "two_link_two_cables" / "two_link_two_cables.yaml"
    sampled = tmp_path / "other.zarr"
    cdpm.workspace_map(other, {"q1": [0.0, 1.0], "q2": [0.0, 1.0]}, store=sampled, workers=1)
    code, _, err = _cli(
        [
            "certify",
            str(PAPER_SPEC),
            "--axis",
            "q1=0:1:2",
            "--axis",
            "q2=0:1:2",
            "--plot",
            str(tmp_path / "c.png"),
            "--compare",
            str(sampled),
        ],
        capsys,
    )
    assert code == 1 and "was made from" in err and "two_link_two_cables.yaml" in err
    assert not (tmp_path / "c.png").exists()
