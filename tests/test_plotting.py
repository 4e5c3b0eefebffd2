"""Map pictures and the map / plot commands (in-process via cdpm.cli.main)."""

from __future__ import annotations

import re

import numpy as np
import pytest

import cdpm
from cdpm.cli import main
from cdpm.maps import open_map, workspace_map
from tests.conftest import PAPER_SPEC

pytest.importorskip("matplotlib")


def _check_image(path, min_bytes=10_000, max_bytes=1_500_000):
    """The PNG exists, has a sensible size and is not blank."""
    import matplotlib.image as mpimg

    assert path.is_file()
    size = path.stat().st_size
    assert min_bytes < size < max_bytes, size
    pixels = mpimg.imread(path)[..., :3]
    assert pixels.shape[0] > 200 and pixels.shape[1] > 300
    assert pixels.std() > 0.05  # several colours, not a blank canvas
    # the verdict colours appear: green for YES
    green = (pixels[..., 1] > 0.5) & (pixels[..., 0] < 0.35) & (pixels[..., 2] < 0.4)
    assert green.mean() > 0.003


@pytest.mark.slow
def test_grid_map_plot(paper_robot, tmp_path):
    from cdpm.plotting import plot_map, save_map_plot

    ds = workspace_map(
        paper_robot, {"q1": np.linspace(-3, 3, 61), "q2": np.linspace(-3, 3, 61)}, workers=1
    )
    fig = plot_map(ds)
    verdict, margin, output = fig.axes
    assert verdict.get_xlabel() == "q1 [rad]" and verdict.get_ylabel() == "q2 [rad]"
    # one output (tip_x): plotted against the first joint
    assert output.get_xlabel() == "q1 [rad]" and output.get_ylabel() == "output tip_x [m]"
    assert verdict.get_legend() is not None
    _check_image(save_map_plot(ds, tmp_path / "map.png"))


@pytest.mark.slow
def test_sample_and_slice_plots(tmp_path, write_spec):
    from cdpm.plotting import save_map_plot

    robot = cdpm.load_robot(PAPER_SPEC)
    ds = workspace_map(robot, {"q1": (-3, 3), "q2": (-3, 3)}, samples=2000, seed=2, workers=1)
    _check_image(save_map_plot(ds, tmp_path / "samples.png"))
    # three axes: slices of the verdict along the third
    spec = write_spec(
        """\
        urdf: arm.urdf
        gravity: [0, 0, 0]
        cables:
          - name: c1
            route:
              - {frame: base, point: [0, 0.5, 0]}
              - {frame: link1, point: [0.3, 0.1, 0], relative_to: com}
          - name: c2
            route:
              - {frame: base, point: [0, 1.5, 0]}
              - {frame: link2, point: [0.3, 0.1, 0], relative_to: com}
          - name: c3
            route:
              - {frame: base, point: [0, -0.5, 0]}
              - {frame: link1, point: [0.3, -0.1, 0], relative_to: com}
          - name: c4
            route:
              - {frame: base, point: [0, -1.5, 0]}
              - {frame: link2, point: [0.3, -0.1, 0], relative_to: com}
        outputs:
          - {name: tip_x, frame: tip, component: x}
          - {name: tip_y, frame: tip, component: y}
        """
    )
    ds3 = workspace_map(
        spec, {"q1": np.linspace(-3, 3, 31), "q2": np.linspace(-3, 3, 31)}, workers=1
    )
    assert ds3.sizes["output"] == 2
    _check_image(save_map_plot(ds3, tmp_path / "two_outputs.png"))


def test_plot_of_more_than_two_axes(tmp_path):
    import xarray as xr

    from cdpm.plotting import plot_map

    robot = cdpm.load_robot(PAPER_SPEC)
    ds = workspace_map(
        robot, {"q1": np.linspace(-3, 3, 21), "q2": np.linspace(-3, 3, 21)}, workers=1
    )
    # stack three copies along a third (synthetic) axis to exercise slicing
    stacked = xr.concat([ds, ds, ds], dim=xr.DataArray([0.0, 1.0, 2.0], dims="z", name="z"))
    stacked = stacked.transpose("q1", "q2", "z", ...)
    fig = plot_map(stacked, max_slices=3)
    titles = [ax.get_title() for ax in fig.axes]
    assert sum("z = " in t for t in titles) >= 3
    assert "\n" not in fig.get_suptitle()  # every slice drawn: nothing to say
    # the output panel (tip_x against q1): the poses fall on fewer points
    # (q2 and -q2 give one tip_x), the three copies on the points of one
    one = re.search(r"441 poses on (\d+) points", plot_map(ds).axes[-1].get_title())
    assert one and int(one.group(1)) < 441
    assert (
        f"1323 poses on {one.group(1)} points,\nno drawn over yes over not analysed"
        in fig.axes[-1].get_title()
    )
    # four axes: 2 of the 3 slices of z, and w at its middle value only, said in
    # the figure title; the panels name their z only (their titles ran off the figure)
    four = xr.concat(
        [stacked, stacked, stacked], dim=xr.DataArray([-1.0, 0.0, 1.0], dims="w", name="w")
    ).transpose("q1", "q2", "z", "w", ...)
    fig = plot_map(four, max_slices=2, output_view=False)
    assert fig.get_suptitle().endswith(
        "\nslices: 2 of the 3 values of z (not drawn: 1); w = 0 only (the middle of its 3 values)"
    )
    titles = [ax.get_title() for ax in fig.axes if ax.get_title().startswith("POC verdict")]
    assert titles == ["POC verdict (z = 0)", "POC verdict (z = 2)"]


def test_a_sampled_map_of_three_axes_is_drawn_in_slabs_of_its_third():
    """Samples of three coordinates were all drawn over the first two, every
    value of the third over the others: they are cut along the third into
    slabs of equal width (about MIN_SLAB_SAMPLES samples each at least), a
    panel each, the path solid in the slab it lies in; a fourth coordinate
    is projected, which the figure title says."""
    from cdpm.plotting import plot_map
    from cdpm.plotting._slabs import MIN_SLAB_SAMPLES
    from tests.conftest import MODELS

    spec = MODELS / "multilink_arm" / "multilink_arm.yaml"
    ranges = {"shoulder_x": (-0.6, 0.6), "shoulder_y": (-0.6, 0.6), "elbow": (-1.5, 0.0)}
    ds = workspace_map(spec, ranges, samples=1000, seed=1, base="reach", workers=1)
    path = {
        "shoulder_x": [-0.4, -0.4, -0.3],
        "shoulder_y": [0.4, 0.0, -0.5],
        "elbow": [-1.4, -0.8, -0.1],
    }
    fig = plot_map(ds, path=path)
    assert MIN_SLAB_SAMPLES == 300  # 1000 samples: 3 slabs
    assert fig.get_suptitle().endswith("\nelbow cut into 3 slabs of equal width, one a panel")
    panels = [ax for ax in fig.axes if ax.get_title().startswith("POC verdict")]
    elbow = ds["elbow"].values
    low, high = elbow.min(), elbow.max()
    edges = np.linspace(low, high, 4)
    counts = []
    for k, ax in enumerate(panels):
        inside = (elbow >= edges[k]) & (
            (elbow <= edges[k + 1]) if k == 2 else (elbow < edges[k + 1])
        )
        counts.append(int(inside.sum()))
        close = "]" if k == 2 else ")"
        assert ax.get_title() == (
            f"POC verdict\n(elbow in [{edges[k] + 0.0:.2f}, {edges[k + 1] + 0.0:.2f}{close} rad: "
            f"{counts[-1]} samples)"
        )
        drawn = sum(len(c.get_offsets()) for c in ax.collections if c.get_gid() == "verdict")
        assert drawn == counts[-1]
        (line,) = [ln for ln in ax.get_lines() if ln.get_gid() == "path"]
        solid = np.isfinite(np.asarray(line.get_xdata(), dtype=float))
        np.testing.assert_array_equal(solid, np.arange(3) == k)
    assert sum(counts) == 1000
    margin = [ax for ax in fig.axes if ax.get_title().startswith("reach margin")]
    assert margin[0].get_title().splitlines()[-1] == panels[1].get_title().splitlines()[-1]
    # too few samples to cut: one panel, said so; a fourth axis projected
    ranges["wrist_x"] = (-0.2, 0.2)
    few = workspace_map(spec, ranges, samples=200, seed=1, base="reach", workers=1, margin=False)
    fig = plot_map(few, output_view=False)
    assert (
        "elbow: every sample in one panel (too few samples to cut); wrist_x projected "
        "(every value drawn)" in " ".join(fig.get_suptitle().split())
    )
    (panel,) = [ax for ax in fig.axes if ax.get_title().startswith("POC verdict")]
    assert panel.get_title().endswith(": 200 samples)")


def test_plot_title_names_the_maps_overrides_of_its_spec(paper_robot):
    """A map of a robot whose gravity, bounds or pretension differ from its
    spec says so in the figure title, as `cdpm map` printed it."""
    from cdpm.maps import override_robot
    from cdpm.plotting import plot_map

    axes = {"q1": np.linspace(-3, 3, 5), "q2": np.linspace(-3, 3, 5)}
    robot = override_robot(paper_robot, gravity=[0, 0, -5], tension_bounds=(0, 60))
    title = plot_map(workspace_map(robot, axes, workers=1)).get_suptitle()
    assert title.splitlines()[1] == (
        "overrides of the spec: gravity [0, 0, -5] m/s^2; tension bounds [N] c1 [0, 60], "
        "c2 [0, 60], c3 [0, 60], c4 [0, 60]"
    )
    assert "overrides" not in plot_map(workspace_map(paper_robot, axes, workers=1)).get_suptitle()


def test_plot_rejects_unknown_variable(paper_robot):
    from cdpm.errors import InputError
    from cdpm.plotting import plot_map

    ds = workspace_map(paper_robot, {"q1": [0.1, 0.2]}, workers=1)
    # the choices are the map's verdicts, the tension search's only when it ran
    with pytest.raises(InputError, match="not a verdict of this map") as info:
        plot_map(ds, variable="tension_max")
    assert str(info.value).endswith(
        "choose one of ['output_controllable', 'poc', 'positive_controllable', "
        "'static_feasible', 'wrench_closure']"
    )
    # status has flag meanings too, but its codes are not verdicts
    with pytest.raises(InputError, match="'status' is not a verdict of this map"):
        plot_map(ds, variable="status")


@pytest.mark.slow
def test_cli_map_and_plot(tmp_path, capsys):
    store, png = tmp_path / "m.zarr", tmp_path / "m.png"
    argv = [
        "map",
        str(PAPER_SPEC),
        "--axis",
        "q1=-pi:pi:41",
        "--axis",
        "q2=-pi:pi:31",
        "--out",
        str(store),
        "--plot",
        str(png),
        "--workers",
        "1",
    ]
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert "1271 poses; positive output controllable: yes" in out
    assert "poses/s" in err and "ETA" in err
    ds = open_map(store)
    assert ds.sizes == {"q1": 41, "q2": 31, "output": 1, "xyz": 3, "cable": 4}
    _check_image(png)
    # the same command again resumes a complete map: nothing to compute
    assert main(argv + ["--quiet"]) == 0
    out2 = tmp_path / "again.png"
    assert main(["plot", str(store), "-o", str(out2), "--variable", "wrench_closure"]) == 0
    _check_image(out2)


def test_cli_map_samples_and_errors(tmp_path, capsys):
    store = tmp_path / "s.zarr"
    assert (
        main(
            [
                "map",
                str(PAPER_SPEC),
                "--axis",
                "q1=-pi:pi",
                "--axis",
                "q2=-1:1",
                "--samples",
                "500",
                "--seed",
                "3",
                "--out",
                str(store),
                "--quiet",
                "--workers",
                "1",
            ]
        )
        == 0
    )
    ds = open_map(store)
    assert ds["poc"].dims == ("sample",) and ds.sizes["sample"] == 500
    assert "q1" in ds.coords and ds["q1"].dims == ("sample",)
    capsys.readouterr()
    assert (
        main(["map", str(PAPER_SPEC), "--axis", "q1=-pi:pi:21", "--out", str(store), "--quiet"])
        == 1
    )
    assert "different settings" in capsys.readouterr().err
    other = ["--out", str(tmp_path / "other.zarr"), "--quiet"]
    assert main(["map", str(PAPER_SPEC), "--axis", "q9=0:1:3", *other]) == 1
    assert "'q9' is not a coordinate of the robot" in capsys.readouterr().err
    assert main(["map", str(PAPER_SPEC), "--axis", "q1=0:1", *other]) == 1
    assert "NAME=LOW:HIGH:COUNT" in capsys.readouterr().err
    assert (
        main(
            [
                "map",
                str(PAPER_SPEC),
                "--axis",
                "q1=0,0.5,1",
                "--base",
                "q2=pi/3",
                *other,
                "--workers",
                "1",
            ]
        )
        == 0
    )
    assert "3 poses" in capsys.readouterr().out
    assert main(["plot", str(tmp_path / "missing.zarr"), "-o", str(tmp_path / "x.png")]) == 1
    assert "missing.zarr not found" in capsys.readouterr().err


@pytest.mark.slow
def test_map_command_without_margin_keeps_verdicts(tmp_path):
    import xarray as xr

    from tests.conftest import MODELS

    spec = str(MODELS / "two_link_vertical" / "two_link_vertical.yaml")
    common = ["--axis", "q1=-pi:pi:7", "--axis", "q2=-pi:pi:9", "--workers", "1", "--quiet"]
    assert main(["map", spec, *common, "--out", str(tmp_path / "full.zarr")]) == 0
    assert main(["map", spec, *common, "--out", str(tmp_path / "fast.zarr"), "--no-margin"]) == 0
    full = xr.open_zarr(tmp_path / "full.zarr")
    fast = xr.open_zarr(tmp_path / "fast.zarr")
    np.testing.assert_array_equal(full["poc"].values, fast["poc"].values)
    assert (full["poc"].values == 1).any() and (full["poc"].values == 0).any()
    margin = "reach_margin" if "reach_margin" in full else "poc_margin"
    assert np.isnan(fast[margin].values).all()
    assert np.isfinite(full[margin].values[full["status"].values == 0]).all()
    # the picture of the map without margins has no margin panel and says why
    from cdpm.plotting import plot_map

    fig = plot_map(fast)
    titles = [ax.get_title() for ax in fig.axes]
    assert len(fig.axes) == 2 and titles[0] == "POC verdict", titles
    assert not any("log scale" in t or "margin" in t for t in titles), titles
    assert "reach margin not computed (map made with --no-margin)" in fig.get_suptitle()
    fig = plot_map(full)
    assert "reach margin" in fig.axes[1].get_title() and len(fig.axes) == 3
    assert "not computed" not in fig.get_suptitle()
    # one axis: the band and the output view, no empty log-scale margin line
    one = ["--axis", "q1=-pi:pi:31", "--base", "q2=0.8", "--workers", "1", "--quiet"]
    assert main(["map", spec, *one, "--out", str(tmp_path / "one.zarr"), "--no-margin"]) == 0
    fig = plot_map(open_map(tmp_path / "one.zarr"))
    assert [ax.get_ylabel() for ax in fig.axes] == ["POC\nverdict", "output tip_z [m]"]
    assert not any("log" in ax.get_yscale() for ax in fig.axes)
    assert "reach margin not computed (map made with --no-margin)" in fig.get_suptitle()


def test_plot_legend_takes_verdict_labels_and_colours_from_cdpm_verdicts():
    xr = pytest.importorskip("xarray")
    import cdpm.verdicts
    from cdpm.plotting import VERDICT_COLORS, plot_map

    assert VERDICT_COLORS is cdpm.verdicts.VERDICT_COLORS  # one table, re-exported
    codes = np.array([[-1, 2], [0, 1]], dtype=np.int8)
    ds = xr.Dataset(
        {"poc": (("q1", "q2"), codes, {"flag_values": [1, 0, 2, -1]})},
        coords={"q1": [0.0, 1.0], "q2": [0.0, 1.0]},
    )
    legend = plot_map(ds, margin=False, output_view=False).axes[0].get_legend()
    assert [t.get_text() for t in legend.get_texts()] == ["yes", "no", "marginal", "not analysed"]
    for handle, code in zip(legend.legend_handles, (1, 0, 2, -1), strict=True):
        assert handle.get_facecolor()[:3] == pytest.approx(cdpm.verdicts.VERDICT_RGB[code])


# ------------------------------------------------- command-line input errors


def _bad_stores(tmp_path):
    """Paths that are not cdpm maps, each with a phrase its error must name."""
    import xarray as xr
    import zarr

    (tmp_path / "folder").mkdir()
    (tmp_path / "folder" / "notes.txt").write_text("hi")
    (tmp_path / "plain.txt").write_text("hi")
    xr.Dataset({"a": ("x", np.arange(3))}).to_zarr(tmp_path / "foreign.zarr", consolidated=False)
    zarr.create_array(str(tmp_path / "array.zarr"), shape=(3,), dtype="f8")
    (tmp_path / "corrupt.zarr").mkdir()
    (tmp_path / "corrupt.zarr" / "zarr.json").write_text("{not json")
    group = zarr.open_group(str(tmp_path / "skeleton.zarr"), mode="w")
    group.attrs["cdpm_settings"] = "{}"  # a `cdpm map` stopped while creating its store
    return {
        "missing.zarr": "not found",
        "folder": "not a zarr store",
        "plain.txt": "not a zarr store",
        "foreign.zarr": "not a cdpm map",
        "array.zarr": "cannot be read as a zarr group",
        "corrupt.zarr": "cannot be read as a zarr group",
        "skeleton.zarr": "incomplete",
    }


def test_plot_command_bad_store_is_a_one_line_input_error(tmp_path, capsys):
    from cdpm.errors import InputError
    from cdpm.plotting import save_map_plot

    for name, phrase in _bad_stores(tmp_path).items():
        store = tmp_path / name
        assert main(["plot", str(store), "-o", str(tmp_path / "m.png")]) == 1, name
        err = capsys.readouterr().err
        assert err.startswith(f"cdpm plot: error: map store {store} "), err
        assert phrase in err and "cdpm map SPEC" in err, err
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
        with pytest.raises(InputError, match=phrase):
            save_map_plot(store, tmp_path / "m.png")
    assert not (tmp_path / "m.png").exists()


@pytest.fixture(scope="module")
def small_store(tmp_path_factory):
    store = tmp_path_factory.mktemp("maps") / "small.zarr"
    robot = cdpm.load_robot(PAPER_SPEC)
    workspace_map(robot, {"q1": np.linspace(-3, 3, 9), "q2": [0.5, 1.0]}, store=store, workers=1)
    return store


@pytest.mark.slow
def test_plot_command_checks_the_image_name_before_any_work(small_store, tmp_path, capsys):
    import shutil

    import matplotlib

    from cdpm.plotting import image_formats, save_map_plot

    formats = image_formats()
    assert {"png", "pdf", "svg", "jpg"} <= set(formats) and "xyz" not in formats
    with pytest.raises(SystemExit) as info:
        main(["plot", str(tmp_path / "missing.zarr"), "-o", str(tmp_path / "map.xyz")])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "argument -o/--output: cannot write map.xyz: unknown image format '.xyz'" in err
    assert "png, ps, raw" in err and "Traceback" not in err
    with pytest.raises(cdpm.InputError, match="unknown image format '.xyz'"):
        save_map_plot(tmp_path / "missing.zarr", tmp_path / "map.xyz")  # before reading
    if shutil.which(matplotlib.rcParams["pgf.texsystem"]) is None:  # .pgf runs TeX
        with pytest.raises(cdpm.InputError, match=r"\.pgf needs \w+, not found; use \.pdf"):
            save_map_plot(small_store, tmp_path / "map.pgf")
    # no extension: matplotlib writes a PNG at NAME.png; that is the path reported
    assert main(["plot", str(small_store), "-o", str(tmp_path / "map")]) == 0
    assert f"plot written to {tmp_path / 'map.png'}" in capsys.readouterr().out
    assert (tmp_path / "map.png").is_file()
    assert main(["plot", str(small_store), "-o", str(tmp_path / "map.svg")]) == 0
    assert (tmp_path / "map.svg").read_text().lstrip().startswith("<?xml")


@pytest.mark.parametrize("dpi", ["0", "-3", "nan", "ten", "1e6", "100000"])
def test_plot_and_picture_reject_a_dpi_that_is_not_positive_or_huge(dpi, tmp_path, capsys):
    from cdpm.plotting import save_map_plot
    from cdpm.plotting.picture import render_pose

    for command in (["plot", str(tmp_path / "m.zarr")], ["picture", str(PAPER_SPEC)]):
        with pytest.raises(SystemExit) as info:
            main([*command, "-o", str(tmp_path / "x.png"), "--dpi", dpi])
        assert info.value.code == 2
        err = capsys.readouterr().err
        assert f"argument --dpi: dpi={dpi} must be a number of dots per inch from 1 to 1200" in err
    if dpi != "ten":
        with pytest.raises(cdpm.InputError, match="must be a number of dots per inch from 1"):
            save_map_plot(tmp_path / "m.zarr", tmp_path / "x.png", dpi=float(dpi))
        with pytest.raises(cdpm.InputError, match="must be a number of dots per inch from 1"):
            render_pose(cdpm.load_robot(PAPER_SPEC), "nominal", dpi=float(dpi))


# ---------------------------------------------------------------- one axis


@pytest.mark.slow
@pytest.mark.parametrize("sample", [False, True])
def test_one_axis_map_is_a_strip_and_a_margin_line(paper_robot, tmp_path, sample):
    from matplotlib.collections import PathCollection, QuadMesh
    from matplotlib.colors import to_rgb

    from cdpm.plotting import VERDICT_COLORS, plot_map, save_map_plot

    if sample:
        ds = workspace_map(paper_robot, {"q1": (-3, 3)}, samples=80, seed=1, workers=1)
    else:
        ds = workspace_map(paper_robot, {"q1": np.linspace(-3, 3, 61)}, workers=1)
    ds = _with_regions(ds)
    order = np.argsort(ds["q1"].values)
    path = {"q1": [-2.0, -1.0, 0.5]}
    fig = plot_map(ds, path=path)
    strip, line, output = fig.axes[:3]
    # the verdict: one coloured band along q1, cell k in the verdict colour of pose k
    (mesh,) = [c for c in strip.collections if isinstance(c, QuadMesh)]
    colors = mesh.to_rgba(np.asarray(mesh.get_array()).reshape(-1))[:, :3]
    assert colors.shape == (ds.sizes[ds["poc"].dims[0]], 3)
    expected = [VERDICT_COLORS[int(c)] for c in ds["poc"].values[order]]
    np.testing.assert_allclose(colors, [to_rgb(c) for c in expected], atol=1e-6)
    assert not [c for c in strip.collections if isinstance(c, PathCollection)]  # no dots
    assert strip.get_yticks().size == 0 and strip.get_legend() is not None
    assert strip.get_ylabel() == "POC\nverdict"
    # the regions and the path on the band
    assert "1" in _region_numbers(strip)
    (drawn,) = [ln for ln in strip.get_lines() if ln.get_gid() == "path"]
    np.testing.assert_allclose(drawn.get_xdata(), path["q1"])
    # the margin: a line of the positive margins over q1 on a log axis, same x axis
    (margin,) = [ln for ln in line.get_lines() if ln.get_gid() == "margin"]
    values = ds[_margin_name(ds)].values[order]
    np.testing.assert_allclose(margin.get_xdata(), ds["q1"].values[order])
    np.testing.assert_allclose(margin.get_ydata(), np.where(values > 0, values, np.nan))
    assert line.get_yscale() == "log" and "log scale" in line.get_ylabel()
    assert line.get_xlabel() == "q1 [rad]" and "[m]" in line.get_ylabel()
    assert strip.get_shared_x_axes().joined(strip, line)
    # the path along the margin line: at the margins of its nearest poses
    (on_line,) = [ln for ln in line.get_lines() if ln.get_gid() == "path"]
    q1 = ds["q1"].values[order]
    nearest = [int(np.argmin(np.abs(q1 - v))) for v in path["q1"]]
    np.testing.assert_allclose(on_line.get_xdata(), path["q1"])
    bottom = line.get_ylim()[0]  # a zero margin: on the bottom edge, with the red ticks
    expected = np.where(values[nearest] > 0, values[nearest], bottom)
    np.testing.assert_allclose(on_line.get_ydata(), np.clip(expected, *line.get_ylim()))
    # the title names the axis, its poses and the other coordinate's base value
    poses = "80 random poses" if sample else "q1: 61 poses"
    assert fig.get_suptitle().startswith(f"two_link_planar.yaml: {poses}, q2 = 1.047 (base), ")
    # the paper's one output against the axis
    assert output.get_xlabel() == "q1 [rad]" and output.get_ylabel() == "output tip_x [m]"
    _assert_legends_outside(fig)
    _check_image(save_map_plot(ds, tmp_path / "line.png"))
    # without the margin panel the band carries the axis label itself
    fig = plot_map(ds, margin=False, output_view=False)
    assert len(fig.axes) == 1 and fig.axes[0].get_xlabel() == "q1 [rad]"


@pytest.mark.slow
def test_one_axis_margin_line_splits_poses_without_a_margin(tmp_path):
    """two_link_vertical along q1: zero margins as red ticks, poses without
    an equilibrium as grey spans, each in the legend."""
    from matplotlib.colors import to_rgb

    from cdpm.plotting import plot_map, save_map_plot
    from cdpm.plotting._common import STATUS_COLORS, ZERO_MARGIN_COLOR
    from tests.conftest import MODELS

    spec = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
    q1 = {"q1": np.linspace(-np.pi, np.pi, 91)}
    ds = workspace_map(spec, q1, base={"q2": 0.0}, workers=1)
    status = ds["status"].values
    assert (status == 3).any() and (status == 0).any()
    margin_values = ds[_margin_name(ds)].values
    assert (margin_values[status == 0] <= 0).any()  # q2 = 0: the arm stretched, no POC
    line = plot_map(ds).axes[1]
    (ticks,) = [ln for ln in line.get_lines() if ln.get_gid() == "zero margin"]
    assert ticks.get_xdata().size == int(np.sum(margin_values[status == 0] <= 0))
    assert to_rgb(ticks.get_color()) == pytest.approx(to_rgb(ZERO_MARGIN_COLOR))
    spans = [p for p in line.patches if p.get_facecolor()[:3] == to_rgb(STATUS_COLORS[3])]
    assert spans  # no equilibrium: grey spans behind the line
    labels = [t.get_text() for t in line.get_legend().get_texts()]
    assert any("not POC" in t for t in labels)
    assert f"not analysed: no equilibrium ({int((status == 3).sum())})" in labels
    assert save_map_plot(ds, tmp_path / "vertical_line.png").stat().st_size > 5_000
    # a bent elbow: POC regions end where poses without an equilibrium begin
    ds = _with_regions(workspace_map(spec, q1, base={"q2": 0.8}, workers=1))
    strip = plot_map(ds).axes[0]
    assert _gids(strip, "region outlines") is not None
    assert {"1", "2"} <= set(_region_numbers(strip))


# ------------------------------------------------- pictures that read at a glance


def _margin_name(ds) -> str:
    return "reach_margin" if "reach_margin" in ds else "poc_margin"


def _with_regions(ds):
    """The map with its POC regions (cdpm.maps.regions) attached."""
    from cdpm.maps.regions import attach_regions

    return attach_regions(ds)


def _grid(spec, n=41):
    """A map over full turns of q1 and q2, with reach_margin and poc_region."""
    turn = np.linspace(-np.pi, np.pi, n)
    ds = _with_regions(workspace_map(spec, {"q1": turn, "q2": turn}, workers=1).load())
    assert "reach_margin" in ds, "maps carry the reach margin r_T"
    return ds


@pytest.fixture(scope="module")
def paper_map():
    return _grid(PAPER_SPEC)


@pytest.fixture(scope="module")
def vertical_map():
    from tests.conftest import MODELS

    return _grid(MODELS / "two_link_vertical" / "two_link_vertical.yaml")


def _gids(ax, gid):
    """The first artist of ``ax`` with this gid, or None."""
    for artist in ax.get_children():
        if artist.get_gid() == gid:
            return artist
    return None


def _region_numbers(ax) -> list[str]:
    return [t.get_text() for t in ax.texts if t.get_gid() == "region number"]


def _render(fig) -> np.ndarray:
    """The figure's pixels, (H, W, 4) uint8, top row first."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())


def _inked_fraction(pixels: np.ndarray, ax) -> float:
    """Fraction of the pixels inside ``ax``'s frame that are not white."""
    box = ax.get_window_extent()
    height = pixels.shape[0]
    inside = pixels[
        int(height - box.y1) + 2 : int(height - box.y0) - 2, int(box.x0) + 2 : int(box.x1) - 2, :3
    ]
    return float(np.mean(np.any(inside < 245, axis=-1)))


def legend_texts_of(ax) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]


def _assert_legends_outside(fig) -> None:
    """No legend overlaps the data area of any panel."""
    _render(fig)
    renderer = fig.canvas.get_renderer()
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    assert legends
    for legend in legends:
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            assert not box.overlaps(ax.get_window_extent(renderer)), (legend, ax)


@pytest.mark.slow
@pytest.mark.parametrize("which", ["paper", "vertical"])
def test_map_panels_read_at_a_glance(which, paper_map, vertical_map, tmp_path):
    from matplotlib.colors import LogNorm, to_rgb

    from cdpm.plotting import plot_map, save_map_plot
    from cdpm.plotting._common import STATUS_COLORS, ZERO_MARGIN_COLOR

    ds = paper_map if which == "paper" else vertical_map
    path = {"q1": np.linspace(-2.5, 1.0, 25), "q2": np.linspace(0.5, 2.4, 25)}
    fig = plot_map(ds, path=path)
    verdict, margin, output = fig.axes
    pixels = _render(fig)
    # every panel shows data (the vertical margin panel used to be blank)
    assert _inked_fraction(pixels, verdict) > 0.95
    assert _inked_fraction(pixels, margin) > 0.95
    assert _inked_fraction(pixels, output) > 0.05
    # the first joint on x, titles and labels in words with units
    for ax in (verdict, margin):
        assert ax.get_xlabel() == "q1 [rad]" and ax.get_ylabel() == "q2 [rad]"
    mesh = _gids(verdict, "verdict")
    q1_edges = mesh.get_coordinates()[:, 0, 0]
    assert q1_edges[0] < ds["q1"].values[0] < q1_edges[1] < ds["q1"].values[1]
    assert verdict.get_title() == "POC verdict"
    horizon = ds.attrs["reach_horizon"]
    assert "reach margin" in margin.get_title() and "[m]" in margin.get_title()
    assert f"= {horizon:.3g} s" in margin.get_title() and "log scale" in margin.get_title()
    budget = ds.attrs["tension_budget"]
    assert f"tension changes up to ±{budget:.3g} N\nfor cables without an upper bound" in (
        margin.get_title()
    )
    # margins on a log scale spanning their positive range
    positive_mesh = _gids(margin, "margin")
    norm = positive_mesh.norm
    assert isinstance(norm, LogNorm)
    values = ds["reach_margin"].values
    positive = values[values > 0]
    assert np.isfinite(np.asarray(positive_mesh.get_array())).sum() == positive.size
    (colorbar,) = margin.child_axes
    assert "log scale" in colorbar.get_ylabel() and "[m]" in colorbar.get_ylabel()
    # the colour scale ends at margins of the map; the few beyond it (stragglers,
    # each more than a decade beyond the 1st or 99th percentile) are said so
    p1, p99 = np.quantile(np.log10(positive), [0.01, 0.99])
    below, above = positive[positive < norm.vmin], positive[positive > norm.vmax]
    assert norm.vmin in positive and norm.vmax in positive
    assert below.size <= 0.01 * positive.size and above.size <= 0.01 * positive.size
    assert np.all(np.log10(below) < p1 - 1) and np.all(np.log10(above) > p99 + 1)
    ends = {(False, False): "neither", (True, False): "min", (False, True): "max"}
    assert positive_mesh.colorbar.extend == ends.get((below.size > 0, above.size > 0), "both")
    assert ("clipped" in colorbar.get_ylabel()) == (below.size + above.size > 0)
    # zero margins and poses not analysed: cells of their own colours, not in the colour map
    categories = _gids(margin, "margin categories")
    cells = np.asarray(categories.get_array())
    rgb = categories.to_rgba(cells.reshape(-1))[:, :3].reshape(*cells.shape, 3)
    status = ds["status"].values
    zero = (status == 0) & (values <= 0)
    assert zero.any()
    np.testing.assert_allclose(rgb[zero], [to_rgb(ZERO_MARGIN_COLOR)] * int(zero.sum()))
    ramp = positive_mesh.cmap(np.linspace(0, 1, 256))[:, :3]
    assert np.min(np.linalg.norm(ramp - to_rgb(ZERO_MARGIN_COLOR), axis=1)) > 0.3
    legend_texts = [t.get_text() for t in margin.get_legend().get_texts()]
    # each category with its count of poses
    assert f"$r_T$ = 0 (not POC, or $T$ too short) ({int(zero.sum())})" in legend_texts
    if which == "vertical":  # poses without an equilibrium, grey, named by reason
        unanalysed = status == 3
        assert unanalysed.any()
        expected = to_rgb(STATUS_COLORS[3])
        np.testing.assert_allclose(rgb[unanalysed], [expected] * int(unanalysed.sum()))
        assert np.linalg.norm(np.subtract(expected, to_rgb(ZERO_MARGIN_COLOR))) > 0.3
        assert f"not analysed: no equilibrium ({int(unanalysed.sum())})" in legend_texts
    # the regions: numbered, the largest first; outlined where they meet the
    # wide grey areas of poses without an equilibrium (the paper's arm has
    # only thin or small NO pieces at 41 x 41: no outline)
    assert (_gids(verdict, "region outlines") is not None) == (which == "vertical")
    assert "1" in _region_numbers(verdict)
    # the path, from its start to its goal
    (line,) = [ln for ln in verdict.get_lines() if ln.get_gid() == "path"]
    np.testing.assert_allclose(line.get_xdata(), path["q1"])
    np.testing.assert_allclose(line.get_ydata(), path["q2"])
    (start,) = [ln for ln in verdict.get_lines() if ln.get_gid() == "start"]
    (goal,) = [ln for ln in verdict.get_lines() if ln.get_gid() == "goal"]
    assert start.get_xdata()[0] == path["q1"][0] and goal.get_ydata()[0] == path["q2"][-1]
    labels = [t.get_text() for t in verdict.get_legend().get_texts()]
    assert {"start", "goal", "path (25 poses)"} <= set(labels)
    assert any(t.startswith("POC regions") for t in labels)
    # the path over the margins too, where a maximin path matters
    (on_margin,) = [ln for ln in margin.get_lines() if ln.get_gid() == "path"]
    np.testing.assert_allclose(on_margin.get_xdata(), path["q1"])
    np.testing.assert_allclose(on_margin.get_ydata(), path["q2"])
    assert {"start", "goal"} <= {ln.get_gid() for ln in margin.get_lines()}
    assert "path (25 poses)" in legend_texts_of(margin)
    _assert_legends_outside(fig)
    save_map_plot(ds, tmp_path / f"{which}.png", path=path)
    _check_image(tmp_path / f"{which}.png")


def test_maps_made_before_the_reach_margin_show_the_unit_impulse_index(paper_map):
    from cdpm.plotting import plot_map

    old = paper_map.drop_vars(["reach_margin", "poc_region"])
    old.attrs = {k: v for k, v in old.attrs.items() if k not in ("reach_horizon", "tension_budget")}
    # an old map's poc_margin: > 0 where POC, <= 0 elsewhere (unitless)
    old["poc_margin"] = (("q1", "q2"), np.where(old["poc"].values == 1, 0.3, -1e-17))
    margin = plot_map(old).axes[1]
    title = margin.get_title()
    assert "POC margin" in title and "unit-impulse index, unitless" in title
    assert "log scale" in title and "[m]" not in title
    assert "unitless" in margin.child_axes[0].get_ylabel()


@pytest.mark.slow
def test_output_panel_plots_the_outputs_asked_for(paper_map, vertical_map, tmp_path, capsys):
    import xarray as xr

    from cdpm.plotting import plot_map

    def output_axes(ds, **kw):
        return plot_map(ds, margin=False, **kw).axes[-1]

    # defaults: the paper's one output against q1; two outputs against each other
    ax = output_axes(paper_map)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("q1 [rad]", "output tip_x [m]")
    assert "output tip_x against q1" in ax.get_title()
    ax = output_axes(vertical_map)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("output tip_x [m]", "output tip_z [m]")
    points = np.vstack([c.get_offsets() for c in ax.collections if c.get_gid() == "outputs"])
    assert len(points) == vertical_map["poc"].size and np.isfinite(points).all()
    # one chosen output against the first joint; the frame's position, named as such
    ax = output_axes(vertical_map, outputs=["tip_z"])
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("q1 [rad]", "output tip_z [m]")
    ax = output_axes(paper_map, outputs=("tip.x", "tip.y"))
    assert ax.get_xlabel() == "x of frame 'tip' (world) [m]"
    assert "world position (x, y) of frame 'tip'" in ax.get_title()
    # three outputs: the first two, stated
    y = vertical_map["y"]
    y = xr.concat([y, y.isel(output=[0]).assign_coords(output=["tip_w"])], "output")
    three = vertical_map.drop_vars(["y", "output"]).assign(y=y)
    assert three.sizes["output"] == 3
    ax = output_axes(three)
    assert "first 2 of 3 outputs" in ax.get_title()
    # bad names: the message lists the map's outputs
    with pytest.raises(
        cdpm.InputError, match=r"'tip_y' is not an output of this map; its outputs: tip_x \("
    ):
        plot_map(paper_map, outputs=["tip_y"])
    with pytest.raises(cdpm.InputError, match="one or two names"):
        plot_map(three, outputs=["tip_x", "tip_z", "tip_w"])
    with pytest.raises(cdpm.InputError, match="twice"):
        plot_map(three, outputs=["tip_x", "tip_x"])
    # the command line
    from tests.conftest import MODELS

    store = tmp_path / "v.zarr"
    spec = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
    workspace_map(spec, {"q1": np.linspace(-3, 3, 15), "q2": [0.5, 1.0]}, store=store, workers=1)
    png = tmp_path / "v.png"
    assert main(["plot", str(store), "-o", str(png), "--outputs", "tip_z"]) == 0
    _check_image(png)
    capsys.readouterr()
    assert main(["plot", str(store), "-o", str(png), "--outputs", "tip_q"]) == 1
    assert "'tip_q' is not an output of this map; its outputs: tip_x, tip_z" in (
        capsys.readouterr().err
    )


def test_plot_path_errors_name_the_fix(paper_map):
    from cdpm.plotting import plot_map

    with pytest.raises(cdpm.InputError, match="path lacks q2"):
        plot_map(paper_map, path={"q1": [0.0, 1.0]})
    with pytest.raises(cdpm.InputError, match=r"\['q9'\] are not coordinates of this map"):
        plot_map(paper_map, path={"q1": [0.0], "q2": [0.0], "q9": [1.0]})
    with pytest.raises(cdpm.InputError, match="differ in length"):
        plot_map(paper_map, path={"q1": [0.0, 1.0], "q2": [0.0]})
    with pytest.raises(cdpm.InputError, match="finite numbers"):
        plot_map(paper_map, path={"q1": [0.0, np.nan], "q2": [0.0, 1.0]})
    with pytest.raises(cdpm.InputError, match="must map coordinate names"):
        plot_map(paper_map, path=[0.0, 1.0])


@pytest.mark.slow
def test_slices_of_a_three_axis_map_carry_regions_and_the_path(paper_map):
    import xarray as xr

    from cdpm.plotting import plot_map
    from cdpm.plotting._overlays import AWAY_ALPHA

    ds = paper_map.drop_vars("poc_region")
    stacked = xr.concat([ds, ds, ds], dim=xr.DataArray([0.0, 1.0, 2.0], dims="z", name="z"))
    stacked = stacked.transpose("q1", "q2", "z", ...)
    stacked.attrs["axes"] = ["q1", "q2", "z"]
    stacked = _with_regions(stacked)
    path = {"q1": [-1.0, 0.0, 1.0], "q2": [0.5, 1.0, 1.5], "z": [0.0, 0.1, 2.0]}
    fig = plot_map(stacked, path=path, max_slices=3)
    slices = [ax for ax in fig.axes if ax.get_title().startswith("POC verdict (z = ")]
    assert len(slices) == 3
    for k, ax in enumerate(slices):
        assert ax.get_xlabel() == "q1 [rad]"
        assert _region_numbers(ax) == ["1"]
        (line,) = [ln for ln in ax.get_lines() if ln.get_gid() == "path"]
        # solid where the path is nearest this slice: z = 0 (twice), z = 2
        solid = np.isfinite(np.asarray(line.get_xdata(), dtype=float))
        np.testing.assert_array_equal(
            solid, [[True, True, False], [False] * 3, [False, False, True]][k]
        )
    labels = [t.get_text() for t in slices[0].get_legend().get_texts()]
    assert "path (3 poses); dashed: away from this slice" in labels
    _assert_legends_outside(fig)
    # eight values of z, six slices: the slices of the path's start and goal
    # are drawn, and the path is solid only in the slice it lies in (it was
    # drawn solid in the nearest slice drawn, which it never entered)
    eight = xr.concat([ds] * 8, dim=xr.DataArray(np.arange(8.0), dims="z", name="z"))
    eight = _with_regions(
        eight.transpose("q1", "q2", "z", ...).assign_attrs(axes=["q1", "q2", "z"])
    )
    path = {"q1": [-1.0, 0.0, 1.0], "q2": [0.5, 1.0, 1.5], "z": [2.0, 2.0, 5.0]}
    fig = plot_map(eight, path=path, max_slices=6)
    slices = [ax for ax in fig.axes if ax.get_title().startswith("POC verdict (z = ")]
    drawn = [float(ax.get_title()[len("POC verdict (z = ") : -1]) for ax in slices]
    assert len(drawn) == 6 and {0.0, 2.0, 5.0, 7.0} <= set(drawn)  # the path's ends, spread
    for ax, z in zip(slices, drawn, strict=True):
        (line,) = [ln for ln in ax.get_lines() if ln.get_gid() == "path"]
        solid = np.isfinite(np.asarray(line.get_xdata(), dtype=float))
        np.testing.assert_array_equal(solid, np.array(path["z"]) == z)
    assert "(not drawn: " in fig.get_suptitle()
    with pytest.raises(cdpm.InputError, match="max_slices must be a positive integer, got 0"):
        plot_map(eight, max_slices=0)
    # a third axis over a full turn with both ends: pi and -pi are one pose,
    # so a path pose at pi lies in the -pi slice (it was dashed there)
    turn = xr.DataArray(np.linspace(-np.pi, np.pi, 5), dims="q3", name="q3", attrs={"units": "rad"})
    closed = xr.concat([ds] * 5, dim=turn).transpose("q1", "q2", "q3", ...)
    closed = _with_regions(closed.assign_attrs(axes=["q1", "q2", "q3"]))
    path = {"q1": [-1.0, 0.0, 1.0], "q2": [0.5, 1.0, 1.5], "q3": [np.pi, np.pi, 0.1]}
    fig = plot_map(closed, path=path, max_slices=3)
    slices = [ax for ax in fig.axes if ax.get_title().startswith("POC verdict (q3 = ")]
    drawn = [ax.get_title()[len("POC verdict (q3 = ") : -1] for ax in slices]
    # pi is drawn as -pi; three of the four distinct poses, spread round the
    # turn, the path's two among them
    assert drawn == ["-3.14 rad", "0 rad", "1.57 rad"]
    assert fig.get_suptitle().splitlines()[-1] == (
        "slices: 3 of the 4 distinct values of q3 (3.14 = -3.14 rad; not drawn: -1.57 rad)"
    )
    # the margin panel shows the path's start's slice (it showed the middle one)
    (margin,) = [ax for ax in fig.axes if ax.get_title().startswith("reach margin")]
    assert margin.get_title().endswith("(q3 = -3.14 rad)")
    # a full turn without its upper end wraps too: slices spread round it
    # (5 pi / 6 is next to -pi), 0 among them
    turn = xr.DataArray(
        np.linspace(-np.pi, 5 * np.pi / 6, 12), dims="q3", name="q3", attrs={"units": "rad"}
    )
    open_turn = xr.concat([ds] * 12, dim=turn).transpose("q1", "q2", "q3", ...)
    open_turn = _with_regions(open_turn.assign_attrs(axes=["q1", "q2", "q3"]))
    titles = [ax.get_title() for ax in plot_map(open_turn, max_slices=6).axes]
    assert [t for t in titles if t.startswith("POC verdict")] == [
        f"POC verdict (q3 = {v} rad)" for v in ("-3.14", "-2.09", "-1.05", "0", "1.05", "2.09")
    ]
    for ax, expected in zip(slices, [[1, 1, 0], [0, 0, 1], [0, 0, 0]], strict=True):
        (line,) = [ln for ln in ax.get_lines() if ln.get_gid() == "path"]
        solid = np.isfinite(np.asarray(line.get_xdata(), dtype=float))
        np.testing.assert_array_equal(solid, np.array(expected, dtype=bool))
        # the start and goal markers are faint where they are away from the slice
        alpha = {ln.get_gid(): ln.get_alpha() for ln in ax.get_lines()}
        assert alpha["start"] == (1.0 if expected[0] else AWAY_ALPHA)
        assert alpha["goal"] == (1.0 if expected[-1] else AWAY_ALPHA)
    titles = [ax.get_title() for ax in plot_map(closed, max_slices=4).axes]
    assert [t for t in titles if t.startswith("POC verdict")] == [
        f"POC verdict (q3 = {v} rad)" for v in ("-3.14", "-1.57", "0", "1.57")
    ]
    # a dataset without poc (another verdict plotted) draws its path: the
    # wrap is read from the axis alone, not from the map's layout
    other = closed.drop_vars(["poc", "poc_region"])
    fig = plot_map(other, variable="wrench_closure", path=path, max_slices=3, margin=False)
    assert len([ax for ax in fig.axes if ax.get_title().startswith("wrench")]) == 3


def test_slice_values_that_are_round_off_of_zero_read_zero():
    """np.linspace(-pi, 5 pi / 6, 12) has 4.4e-16 for 0: a slice title
    said "q3 = 4.44e-16 rad"."""
    import xarray as xr

    from cdpm.plotting._common import coordinate_value

    values = np.linspace(-np.pi, 5 * np.pi / 6, 12)
    assert 0 < abs(values[6]) < 1e-15
    ds = xr.Dataset(coords={"q3": ("q3", values, {"units": "rad"})})
    assert coordinate_value(ds, "q3", values[6]) == "q3 = 0 rad"
    assert coordinate_value(ds, "q3", values[7]) == "q3 = 0.524 rad"
    assert coordinate_value(ds, "q3", 1e-9) == "q3 = 1e-09 rad"  # small, not round-off


def test_a_wide_area_outside_the_regions_is_outlined_all_round():
    """Where a wide area of poses outside every region narrows to one cell,
    its outline went on (it broke off cell by cell); a line one cell thin
    on its own and a piece of at most SMALL_HOLE_POSES poses are not outlined."""
    from cdpm.plotting._overlays import _not_outlined

    ids = np.ones((12, 12), dtype=int)
    ids[1:4, 1:4] = 0  # a 3 x 3 area ...
    ids[4:8, 2] = 0  # ... with a tail one cell wide
    ids[9, 5:11] = 0  # a thin line on its own
    ids[10:12, 0:2] = 0  # four poses
    skipped = _not_outlined(ids)
    assert not skipped[1:4, 1:4].any() and not skipped[4:8, 2].any()
    assert skipped[9, 5:11].all() and skipped[10:12, 0:2].all()


def test_suspect_steps_are_marked_where_the_path_is_drawn_solid():
    """On a slice a path's steps away from it are faint; a suspect step
    among them is not marked there (it showed on every slice)."""
    from matplotlib.figure import Figure

    from cdpm.plotting._overlays import draw_path

    ax = Figure().add_subplot()
    draw_path(
        ax,
        [0.0, 1.0, 2.0, 3.0],
        [0.0, 0.0, 1.0, 1.0],
        near=[True, True, True, False],
        suspect=(0, 2),
    )
    (marks,) = [c for c in ax.collections if c.get_gid() == "suspect steps"]
    np.testing.assert_allclose(marks.get_segments()[0], [[0.0, 0.0], [1.0, 0.0]])
    assert len(marks.get_segments()) == 1  # step 2 ends away from the slice


@pytest.mark.slow
def test_sampled_map_gets_regions_path_and_log_margin(tmp_path):
    from matplotlib.colors import LogNorm

    from cdpm.plotting import plot_map, save_map_plot
    from tests.conftest import MODELS

    spec = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
    ds = workspace_map(
        spec, {"q1": (-np.pi, np.pi), "q2": (-np.pi, np.pi)}, samples=1500, seed=4, workers=1
    )
    ds = _with_regions(ds)
    path = {"q1": [-2.5, 1.0], "q2": [0.5, 2.4]}
    fig = plot_map(ds, path=path)
    verdict, margin, output = fig.axes
    assert verdict.get_xlabel() == "q1 [rad]" and verdict.get_ylabel() == "q2 [rad]"
    assert "1" in _region_numbers(verdict) and _gids(verdict, "region outlines") is not None
    assert [ln for ln in verdict.get_lines() if ln.get_gid() == "path"]
    points = _gids(margin, "margin")
    assert isinstance(points.norm, LogNorm)
    values = ds["reach_margin"].values
    positive = values[values > 0]
    assert np.asarray(points.get_array()).size == positive.size
    # the colour scale ends at the largest margin but stragglers (here about
    # 120 m where the equilibrium needs huge tensions), which it says it clips
    above = positive[positive > points.norm.vmax]
    assert points.norm.vmax in positive and above.size <= 0.01 * positive.size
    assert np.all(above > 10 * np.quantile(positive, 0.99))
    assert above.size >= 1
    label = margin.child_axes[0].get_ylabel()
    assert f"above {points.norm.vmax:.2g} clipped" in label, label
    assert points.colorbar.extend in ("max", "both")
    # the path over the margins as well
    assert [ln for ln in margin.get_lines() if ln.get_gid() == "path"]
    colours = {
        tuple(np.round(c.get_facecolor()[0][:3], 3))
        for c in margin.collections
        if c.get_gid() == "margin categories"
    }
    assert len(colours) >= 1  # poses without an equilibrium
    _assert_legends_outside(fig)
    _check_image(save_map_plot(ds, tmp_path / "samples.png", path=path))


def test_path_across_the_seam_of_a_full_turn_goes_the_short_way(paper_map):
    """-pi and pi are one pose: a step across the seam leaves the panel at
    one edge and comes back at the other, it does not cross the map."""
    from cdpm.plotting import plot_map

    path = {"q1": [2.9, 3.1, -3.05, -2.8], "q2": [1.0, 1.0, 1.0, 1.0]}
    ax = plot_map(paper_map, path=path, margin=False, output_view=False).axes[0]
    limits = ax.get_xlim()
    (line,) = [ln for ln in ax.get_lines() if ln.get_gid() == "path"]
    x = np.asarray(line.get_xdata(), dtype=float)
    np.testing.assert_allclose(x, [2.9, 3.1, np.nan, -3.05, -2.8])
    (stubs,) = [c for c in ax.collections if c.get_gid() == "path seam"]
    (out, back) = [seg[:, 0] for seg in stubs.get_segments()]
    assert out[1] > np.pi and back[0] < -np.pi  # through the right edge, back at the left
    assert ax.get_xlim() == limits and limits[1] < 3.3  # the stubs do not widen the panel


# ------------------------------------------------------- review of the map plots


def test_margin_range_clips_a_few_stragglers_at_either_end_by_one_rule():
    from cdpm.plotting._margin import STRAGGLER_DECADES, STRAGGLER_FRACTION, margin_range

    assert (STRAGGLER_FRACTION, STRAGGLER_DECADES) == (0.01, 1.0)
    rng = np.random.default_rng(7)
    bulk = 10.0 ** rng.normal(-0.9, 0.4, 5000)  # median about 0.12 m
    # the gravity arm's stragglers: 692 m where the equilibrium needs 35 kN
    high = np.array([15.0, 20.7, 84.3, 692.7])
    low = np.array([1e-15, 3e-9])  # round-off at singular poses
    limits = margin_range(np.concatenate([bulk, high, low, [np.nan]]))
    assert (limits.below, limits.above) == (2, 4)
    assert (limits.low, limits.high) == (bulk.min(), bulk.max())
    assert limits.extend == "both"
    assert limits.clip_note == f"below {bulk.min():.2g} and above {bulk.max():.2g} clipped"
    # symmetric: the reciprocal margins clip the reciprocal stragglers
    mirrored = margin_range(1.0 / np.concatenate([bulk, high, low]))
    assert (mirrored.below, mirrored.above) == (4, 2)
    assert mirrored.low == pytest.approx(1.0 / bulk.max(), rel=1e-12)
    only_high = margin_range(np.concatenate([bulk, high]))
    assert (only_high.below, only_high.above, only_high.extend) == (0, 4, "max")
    assert only_high.clip_note == f"above {bulk.max():.2g} clipped"
    # not stragglers: 3 % of the margins far above (a feature of the map), a
    # wide but continuous spread, fewer than 100 margins
    many = np.concatenate([bulk, np.full(150, 500.0)])
    assert margin_range(many).above == 0 and margin_range(many).high == 500.0
    wide = 10.0 ** rng.uniform(-6, 0, 5000)
    assert margin_range(wide).extend == "neither" and margin_range(wide).low == wide.min()
    few = np.concatenate([bulk[:60], [692.7]])
    assert margin_range(few).above == 0
    # one value: a decade either side
    single = margin_range(np.array([0.5, 0.5]))
    assert (single.low, single.high, single.extend) == (0.05, 5.0, "neither")


def test_huge_margins_take_the_top_colour_and_the_colour_bar_says_so(vertical_map):
    """A few huge margins (the gravity arm's 692 m next to a median of 0.12 m)
    no longer stretch the colour bar over the useful range."""
    from cdpm.plotting import plot_map

    ds = vertical_map.copy(deep=True)
    values = ds["reach_margin"].values
    positive = np.flatnonzero(values.reshape(-1) > 0)
    huge = positive[[10, 200, 400, 600, 800]]
    flat = values.reshape(-1)
    flat[huge] = [9.5, 20.7, 42.0, 84.3, 692.7]
    ds["reach_margin"].values = flat.reshape(values.shape)
    margin = plot_map(ds, output_view=False).axes[1]
    mesh = _gids(margin, "margin")
    rest = np.delete(flat, huge)
    rest = rest[rest > 0]
    assert mesh.norm.vmax == rest.max() < 2.0
    assert mesh.colorbar.extend in ("max", "both")
    label = margin.child_axes[0].get_ylabel()
    assert f"above {rest.max():.2g} clipped" in label
    # the stragglers take the top colour; the bulk (1st to 99th percentile)
    # fills at least half of the colour bar (it got a third before)
    top = mesh.cmap(1.0)
    cells = mesh.to_rgba(np.ma.masked_invalid(np.asarray(mesh.get_array()).reshape(-1)))
    np.testing.assert_allclose(cells[huge], [top] * huge.size)
    p1, p99 = np.quantile(np.log10(rest), [0.01, 0.99])
    assert (p99 - p1) / np.log10(mesh.norm.vmax / mesh.norm.vmin) > 0.5


def _thin_and_wide_no(n=181):
    """A synthetic POC map: one region with diagonal NO lines met at
    isolated poses (as on the paper's arm at 181 x 181), a one-pose-wide NO
    row, a small NO spot and a wide NO block."""
    import xarray as xr

    poc = np.ones((n, n), dtype=np.int8)
    k = np.arange(20, 120, 2)
    poc[k, 30 + k // 2] = 0  # a diagonal line of isolated poses, slope 1/2 in cells
    poc[k + 40, 20 + k // 2] = 0
    poc[10:170, 150] = 0  # a row one pose wide
    poc[100, 20:23] = 0  # a small spot of 3 poses
    poc[130:160, 30:60] = 0  # a wide block: a hole to outline
    q = np.linspace(-np.pi, np.pi, n)
    region = np.where(poc == 1, 1, 0).astype(np.int32)
    attrs = {"flag_values": [1, 0, 2, -1]}
    return xr.Dataset(
        {"poc": (("q1", "q2"), poc, attrs), "poc_region": (("q1", "q2"), region)},
        coords={"q1": q, "q2": q},
    )


@pytest.mark.slow
def test_thin_no_lines_read_as_red_lines_not_as_outlined_dots(tmp_path):
    from matplotlib.colors import to_rgb

    from cdpm.plotting import VERDICT_COLORS, plot_map, save_map_plot
    from cdpm.plotting._overlays import SMALL_HOLE_POSES, _outline_segments

    ds = _thin_and_wide_no()
    poc, ids = ds["poc"].values, ds["poc_region"].values
    edges = np.arange(poc.shape[0] + 1.0)
    segments = np.array(_outline_segments(ids, edges, edges))  # (n, 2 ends, xy)
    # every outlined edge borders the wide block, whose whole boundary is drawn
    lo, hi = segments.min(axis=1), segments.max(axis=1)
    assert np.all((lo >= [130, 30]) & (hi <= [160, 60]))
    assert len(segments) == 4 * 30 and SMALL_HOLE_POSES == 4
    # in the picture the thin lines stay red at 181 x 181 and 61 x 61
    for n in (181, 61):
        ds = _thin_and_wide_no()
        if n == 61:  # every third pose: the lines stay isolated poses
            ds = ds.isel(q1=slice(0, 183, 3), q2=slice(0, 183, 3))
        fig = plot_map(ds, margin=False, output_view=False)
        ax = fig.axes[0]
        pixels = _render(fig)[..., :3].astype(float) / 255
        q = np.linspace(-np.pi, np.pi, 181)
        q1, q2 = ds["q1"].values[:, None], ds["q2"].values[None, :]
        block = (q1 > q[129]) & (q1 < q[160]) & (q2 > q[29]) & (q2 < q[60])
        no = np.argwhere((ds["poc"].values == 0) & ~block)
        xy = ax.transData.transform(
            np.column_stack([ds["q1"].values[no[:, 0]], ds["q2"].values[no[:, 1]]])
        )
        rows = (pixels.shape[0] - xy[:, 1]).astype(int)
        colours = pixels[rows, xy[:, 0].astype(int)]
        red = np.linalg.norm(colours - to_rgb(VERDICT_COLORS[0]), axis=1) < 0.25
        dark = colours.sum(axis=1) < 0.6
        assert red.mean() > 0.9 and not dark.any(), (n, red.mean(), dark.sum())
    png = save_map_plot(_thin_and_wide_no(), tmp_path / "thin.png", margin=False)
    assert png.stat().st_size > 5_000


def test_path_start_and_goal_on_the_edge_of_the_map_are_not_cut_off(paper_map):
    from cdpm.plotting import plot_map

    # start on the bottom edge, goal on the right edge of a 181 x 181 map
    # (its cells are under 2 pixels wide: the markers reach beyond the panel)
    path = {"q1": [0.5, 1.5, 2.5, np.pi], "q2": [-np.pi, -2.5, -2.5, -2.5]}
    fig = plot_map(_thin_and_wide_no(), path=path, margin=False, output_view=False)
    ax = fig.axes[0]
    pixels = _render(fig)[..., :3].astype(int)
    height, box = pixels.shape[0], ax.get_window_extent()
    x, y = ax.transData.transform((np.pi, -2.5))
    right = pixels[int(height - y) - 6 : int(height - y) + 4, int(box.x1) + 2 : int(box.x1) + 7]
    x, y = ax.transData.transform((0.5, -np.pi))
    below = pixels[int(height - box.y0) + 2 : int(height - box.y0) + 6, int(x) - 4 : int(x) + 5]

    # the path's blue (PATH_COLOR, #1f3fd6): blue well above red and green
    def blue(p):
        return (p[..., 2] > 180) & (p[..., 0] < 90) & (p[..., 1] < 110)

    assert blue(right).any()  # the star beyond the right edge
    assert blue(below).any()  # the start circle's rim below
    # on the margin panel too
    fig = plot_map(paper_map, path=path, output_view=False)
    for ax in fig.axes[:2]:
        (goal,) = [ln for ln in ax.get_lines() if ln.get_gid() == "goal"]
        (start,) = [ln for ln in ax.get_lines() if ln.get_gid() == "start"]
        assert not goal.get_clip_on() and not start.get_clip_on()


def test_every_piece_of_a_region_on_a_panel_is_numbered(vertical_map):
    """A region across the seams of the full turns shows as several pieces
    on the panel; each piece big enough gets the region's number (only the
    largest one was numbered, and the others read as unnamed regions)."""
    from scipy import ndimage

    from cdpm.plotting import plot_map
    from cdpm.plotting._overlays import MIN_NUMBERED_FRACTION

    ids = vertical_map.poc_region.transpose("q1", "q2").values
    verdict = plot_map(vertical_map, margin=False, output_view=False).axes[0]
    numbers = _region_numbers(verdict)
    pieces_of = {}
    for k in np.unique(ids[ids > 0]):
        pieces, n = ndimage.label(ids == k)
        sizes = ndimage.sum_labels(ids == k, pieces, index=np.arange(1, n + 1))
        pieces_of[str(k)] = max(1, int((sizes >= MIN_NUMBERED_FRACTION * ids.size).sum()))
    assert {k: numbers.count(k) for k in pieces_of} == pieces_of
    assert max(pieces_of.values()) >= 2  # the gravity arm's regions wrap around


@pytest.mark.slow
def test_a_path_legend_does_not_squeeze_a_one_axis_map():
    """Above the strip of a one-axis map, a path's legend entries (with
    its suspect steps) set the width of the strip's column, which shrank
    to a sixth; the legend now takes as many rows as it needs."""
    from cdpm.plotting import plot_map
    from cdpm.regions.paths import poc_path

    ds = workspace_map(PAPER_SPEC, {"q1": (-np.pi, np.pi)}, samples=500, seed=0, workers=1)
    path = poc_path(ds, {"q1": 0.0}, {"q1": 1.5})
    assert path.suspect_steps  # the arm's NO pose near q1 = pi/3

    def strip_width(fig) -> float:
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        FigureCanvasAgg(fig).draw()  # the constrained layout, as when saved
        return fig.axes[0].get_window_extent().width

    plain, with_path = strip_width(plot_map(ds)), strip_width(plot_map(ds, path=path))
    assert with_path > 0.9 * plain


@pytest.mark.slow
def test_a_pocpath_is_drawn_with_its_suspect_steps(paper_map):
    """plot_map takes a POCPath: its steps that may cross a thin NO set
    are drawn over in magenta on the verdict and margin panels, and the
    legend counts them, as `cdpm path` warns of them."""
    from cdpm.plotting import plot_map
    from cdpm.plotting._overlays import SUSPECT_COLOR
    from cdpm.regions.paths import poc_path

    path = poc_path(paper_map, [np.pi / 6, np.pi / 3], [3.0, -2.0])
    assert path.suspect_steps  # the paper arm's thin NO lines
    fig = plot_map(paper_map, path=path, output_view=False)
    for ax in fig.axes[:2]:
        (marks,) = [c for c in ax.collections if c.get_gid() == "suspect steps"]
        first = path.suspect_steps[0]
        np.testing.assert_allclose(
            marks.get_segments()[0],
            [[path.coordinates[a][first + d] for a in ("q1", "q2")] for d in (0, 1)],
        )
        assert len(marks.get_segments()) == len(path.suspect_steps)  # none across the seam
        assert tuple(marks.get_colors()[0][:3]) == pytest.approx(
            [int(SUSPECT_COLOR[k : k + 2], 16) / 255 for k in (1, 3, 5)]
        )
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert f"step that may cross a thin NO set ({len(path.suspect_steps)})" in labels
    # a plain mapping of coordinates has no steps to mark
    fig = plot_map(paper_map, path=path.coordinates, output_view=False)
    assert not [c for c in fig.axes[0].collections if c.get_gid() == "suspect steps"]


@pytest.mark.parametrize("kind", ["grid", "samples", "one axis"])
def test_region_outlines_only_over_the_poc_verdict(kind, vertical_map):
    from cdpm.plotting import plot_map

    if kind == "grid":
        ds = vertical_map
    elif kind == "samples":
        from tests.conftest import MODELS

        spec = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
        ranges = {"q1": (-np.pi, np.pi), "q2": (-np.pi, np.pi)}
        ds = _with_regions(workspace_map(spec, ranges, samples=600, seed=4, workers=1))
    else:
        ds = vertical_map.isel(q2=25)
        ds = ds.drop_vars("q2").assign_attrs(axes=["q1"])
    verdict = plot_map(ds, margin=False, output_view=False).axes[0]
    assert _region_numbers(verdict) and _gids(verdict, "region outlines") is not None
    for variable in ("wrench_closure", "static_feasible"):
        verdict = plot_map(ds, variable=variable, margin=False, output_view=False).axes[0]
        assert not _region_numbers(verdict), variable
        assert _gids(verdict, "region outlines") is None, variable
        labels = [t.get_text() for t in verdict.get_legend().get_texts()]
        assert not any("POC regions" in t for t in labels), labels
    # beside another criterion's verdicts, the margin panel says whose margin it is
    panels = plot_map(ds, variable="wrench_closure", output_view=False).axes
    assert any(ax.get_title().startswith("POC reach margin $r_T$ [m]") for ax in panels)
    panels = plot_map(ds, output_view=False).axes
    assert any(ax.get_title().startswith("reach margin $r_T$ [m]") for ax in panels)


def test_one_axis_margin_line_marks_stragglers_off_the_scale(paper_robot):
    from cdpm.plotting import plot_map

    ds = workspace_map(paper_robot, {"q1": np.linspace(-np.pi, np.pi, 181)}, workers=1)
    values = ds["reach_margin"].values.copy()
    values[40] = 692.7  # one huge margin among 181 (at most 1 % is clipped)
    ds["reach_margin"].values = values
    line = plot_map(ds, output_view=False).axes[1]
    positive = np.delete(values, 40)
    assert line.get_ylim()[1] == pytest.approx(1.5 * positive.max())
    (marks,) = [ln for ln in line.get_lines() if ln.get_gid() == "off scale"]
    assert marks.get_xdata() == pytest.approx([ds["q1"].values[40]])
    assert marks.get_marker() == "^" and not marks.get_clip_on()
    labels = [t.get_text() for t in line.get_legend().get_texts()]
    assert f"$r_T$ above {positive.max():.2g}: off the scale (1)" in labels


@pytest.mark.slow
def test_map_and_plot_of_rotation_and_cable_outputs(tmp_path, capsys):
    """``cdpm map`` stores y of rotation and cable outputs with their
    units; ``cdpm plot --outputs`` labels each axis with name, formula and
    unit, the margin with the reach margin's unit."""
    import re
    import shutil

    import matplotlib.pyplot as plt

    from cdpm.plotting import plot_map
    from tests.conftest import MODELS

    folder = MODELS / "two_link_vertical"
    shutil.copy(folder / "two_link_vertical.urdf", tmp_path)
    text = (folder / "two_link_vertical.yaml").read_text()
    outputs = (
        "outputs:\n"
        "  - {name: tip_ry, frame: tip, component: ry}\n"
        "  - {name: c1_length, cable: c1}\n"
    )
    spec = tmp_path / "turns.yaml"
    spec.write_text(re.sub(r"outputs:\n(?:  - .*\n)+", outputs, text))
    store, png = tmp_path / "turns.zarr", tmp_path / "turns.png"
    axes = ["--axis", "q1=-pi:pi:31", "--axis", "q2=-pi:pi:31", "--workers", "1"]
    assert main(["map", str(spec), *axes, "--out", str(store), "--quiet"]) == 0
    ds = open_map(store)
    assert ds["y"].attrs["output_units"] == ["rad", "m"]
    assert ds["y"].attrs["output_formulas"] == ["", "cable c1"]
    assert ds["reach_margin"].attrs["units"] == "m and rad, one to one"
    robot = cdpm.load_robot(spec)
    for i, j in ((3, 7), (20, 11), (15, 15)):
        q = np.array([ds["q1"].values[i], ds["q2"].values[j]])
        np.testing.assert_allclose(ds["y"].values[i, j], robot.output(q), rtol=1e-14)
    assert main(["plot", str(store), "-o", str(png), "--outputs", "c1_length", "tip_ry"]) == 0
    _check_image(png)
    fig = plot_map(ds)
    verdict, margin, output = fig.axes[:3]
    assert output.get_xlabel() == "output tip_ry [rad]"
    assert output.get_ylabel() == "output c1_length = cable c1 [m]"
    assert output.get_aspect() == "auto"  # radians against metres: no equal aspect
    (colorbar,) = margin.child_axes
    assert "[m and rad, one to one]" in colorbar.get_ylabel()
    assert "for cables without an upper bound" in margin.get_title()
    plt.close(fig)
    fig = plot_map(ds, outputs=["tip_ry"])
    assert fig.axes[-1].get_ylabel() == "output tip_ry [rad]"
    plt.close(fig)
