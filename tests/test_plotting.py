"""Map pictures and the map / plot commands (in-process via cdpm.cli.main)."""

from __future__ import annotations

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


def test_grid_map_plot(paper_robot, tmp_path):
    from cdpm.plotting import plot_map, save_map_plot

    ds = workspace_map(
        paper_robot, {"q1": np.linspace(-3, 3, 61), "q2": np.linspace(-3, 3, 61)}, workers=1
    )
    fig = plot_map(ds)
    labels = [ax.get_xlabel() for ax in fig.axes]
    assert "q2 [rad]" in labels and "tip x [m]" in labels
    assert any(ax.get_legend() is not None for ax in fig.axes)
    _check_image(save_map_plot(ds, tmp_path / "map.png"))


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


def test_plot_rejects_unknown_variable(paper_robot):
    from cdpm.errors import InputError
    from cdpm.plotting import plot_map

    ds = workspace_map(paper_robot, {"q1": [0.1, 0.2]}, workers=1)
    with pytest.raises(InputError, match="not a verdict of this map"):
        plot_map(ds, variable="tension_max")
    # status has flag meanings too, but its codes are not verdicts
    with pytest.raises(InputError, match="'status' is not a verdict of this map"):
        plot_map(ds, variable="status")


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
    assert ds.sizes == {"q1": 41, "q2": 31, "output": 1, "xyz": 3}
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
    assert main(["map", str(PAPER_SPEC), "--axis", "q9=0:1:3", "--quiet"]) == 1
    assert "'q9' is not a coordinate of the robot" in capsys.readouterr().err
    assert main(["map", str(PAPER_SPEC), "--axis", "q1=0:1", "--quiet"]) == 1
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
                "--quiet",
                "--workers",
                "1",
            ]
        )
        == 0
    )
    assert "3 poses" in capsys.readouterr().out
    assert main(["plot", str(tmp_path / "missing.zarr"), "-o", str(tmp_path / "x.png")]) == 1
    assert "missing.zarr not found" in capsys.readouterr().err


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
    assert np.isnan(fast["poc_margin"].values).all()
    assert np.isfinite(full["poc_margin"].values[full["status"].values == 0]).all()


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


@pytest.mark.parametrize("dpi", ["0", "-3", "nan", "ten"])
def test_plot_and_picture_reject_a_dpi_that_is_not_positive(dpi, tmp_path, capsys):
    from cdpm.picture import render_pose
    from cdpm.plotting import save_map_plot

    for command in (["plot", str(tmp_path / "m.zarr")], ["picture", str(PAPER_SPEC)]):
        with pytest.raises(SystemExit) as info:
            main([*command, "-o", str(tmp_path / "x.png"), "--dpi", dpi])
        assert info.value.code == 2
        err = capsys.readouterr().err
        assert f"argument --dpi: dpi={dpi} must be a positive number of dots per inch" in err
    if dpi != "ten":
        with pytest.raises(cdpm.InputError, match="must be a positive number of dots per inch"):
            save_map_plot(tmp_path / "m.zarr", tmp_path / "x.png", dpi=float(dpi))
        with pytest.raises(cdpm.InputError, match="must be a positive number of dots per inch"):
            render_pose(cdpm.load_robot(PAPER_SPEC), "nominal", dpi=float(dpi))


# ---------------------------------------------------------------- one axis


@pytest.mark.parametrize("sample", [False, True])
def test_one_axis_map_is_a_strip_and_a_margin_line(paper_robot, tmp_path, sample):
    from matplotlib.collections import PathCollection, QuadMesh

    from cdpm.plotting import VERDICT_COLORS, plot_map, save_map_plot

    if sample:
        ds = workspace_map(paper_robot, {"q1": (-3, 3)}, samples=80, seed=1, workers=1)
    else:
        ds = workspace_map(paper_robot, {"q1": np.linspace(-3, 3, 61)}, workers=1)
    order = np.argsort(ds["q1"].values)
    fig = plot_map(ds)
    strip, line, output = fig.axes[:3]
    # the verdict: one coloured band along q1, cell k in the verdict colour of pose k
    (mesh,) = [c for c in strip.collections if isinstance(c, QuadMesh)]
    colors = mesh.to_rgba(np.asarray(mesh.get_array()).reshape(-1))[:, :3]
    assert colors.shape == (ds.sizes[ds["poc"].dims[0]], 3)
    expected = [VERDICT_COLORS[int(c)] for c in ds["poc"].values[order]]
    from matplotlib.colors import to_rgb

    np.testing.assert_allclose(colors, [to_rgb(c) for c in expected], atol=1e-6)
    assert not [c for c in strip.collections if isinstance(c, PathCollection)]  # no dots
    assert strip.get_yticks().size == 0 and strip.get_legend() is not None
    assert strip.get_title(loc="left") == "poc along q1"
    # the margin: a line over q1, on the same x axis
    (margin,) = [ln for ln in line.get_lines() if ln.get_label() == "POC margin"]
    np.testing.assert_allclose(margin.get_xdata(), ds["q1"].values[order])
    np.testing.assert_allclose(margin.get_ydata(), ds["poc_margin"].values[order])
    assert line.get_xlabel() == "q1 [rad]" and line.get_ylabel() == "POC margin"
    assert strip.get_shared_x_axes().joined(strip, line)
    assert output.get_xlabel() == "tip x [m]"
    _check_image(save_map_plot(ds, tmp_path / "line.png"))
    # without the margin panel the band carries the axis label itself
    fig = plot_map(ds, margin=False, output_view=False)
    assert len(fig.axes) == 1 and fig.axes[0].get_xlabel() == "q1 [rad]"
