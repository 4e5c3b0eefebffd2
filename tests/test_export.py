"""The linearisation outside cdpm: npz and MAT files (``cdpm analyze --format``)
and python-control state-space systems."""

from __future__ import annotations

import json
import re
import sys

import numpy as np
import pytest
import scipy.io
import scipy.linalg

import cdpm
from cdpm.cli import main
from tests.conftest import MODELS, PAPER_SPEC

VERTICAL = MODELS / "two_link_vertical" / "two_link_vertical.yaml"


@pytest.fixture(scope="module")
def lin():
    # under gravity: one taut cable (free input), three slack (u >= 0), K != 0
    return cdpm.linearise(cdpm.load_robot(VERTICAL), "nominal")


def test_npz_holds_the_linearisation(lin, tmp_path):
    path = lin.save(tmp_path / "lin.npz")
    with np.load(path) as data:  # no pickle needed: names are unicode arrays
        for key in ("A", "B", "B_cone", "C", "q", "output", "tension"):
            np.testing.assert_array_equal(data[key], getattr(lin, key), err_msg=key)
        np.testing.assert_array_equal(data["sign_constrained"], [False, True, True, True])
        np.testing.assert_array_equal(data["input_sign"], lin.input_sign)
        assert data["sign_constrained"].dtype == bool
        assert data["cable_names"].tolist() == ["c1", "c2", "c3", "c4"]
        assert data["output_names"].tolist() == ["tip_x", "tip_z"]
        assert data["state_names"].tolist() == ["q1", "q2", "q1_dot", "q2_dot"]
        assert data["cable_names"].dtype.kind == "U"
        assert data["tension"][0] == pytest.approx(25.4927, abs=1e-4)


def test_mat_holds_the_linearisation(lin, tmp_path):
    path = lin.save(tmp_path / "lin.mat")
    data = scipy.io.loadmat(path)
    for key in ("A", "B", "B_cone", "C"):
        np.testing.assert_array_equal(data[key], getattr(lin, key), err_msg=key)
    np.testing.assert_array_equal(data["q"].ravel(), lin.q)
    np.testing.assert_array_equal(data["tension"].ravel(), lin.tension)
    np.testing.assert_array_equal(data["sign_constrained"].ravel(), [0, 1, 1, 1])
    np.testing.assert_array_equal(data["input_sign"].ravel(), lin.input_sign)
    names = [str(cell[0][0]) for cell in data["cable_names"]]  # a cell array of char
    assert names == ["c1", "c2", "c3", "c4"]
    assert [str(c[0][0]) for c in data["state_names"]] == ["q1", "q2", "q1_dot", "q2_dot"]


def test_save_refuses_other_extensions(lin, tmp_path):
    with pytest.raises(cdpm.InputError, match=r"lin\.npy: give a file ending in \.npz or \.mat"):
        lin.save(tmp_path / "lin.npy")


def test_cli_formats(tmp_path, capsys):
    spec = str(PAPER_SPEC)
    target = tmp_path / "paper.npz"
    assert (
        main(["analyze", spec, "--pose", "nominal", "--format", "npz", "--output", str(target)])
        == 0
    )
    assert f"wrote {target}" in capsys.readouterr().out
    paper = cdpm.linearise(cdpm.load_robot(PAPER_SPEC), "nominal")
    with np.load(target) as data:
        np.testing.assert_array_equal(data["B"], paper.B)
    # the format from the extension
    assert main(["analyze", spec, "--pose", "nominal", "-o", str(tmp_path / "paper.mat")]) == 0
    assert "paper.mat" in capsys.readouterr().out
    np.testing.assert_array_equal(scipy.io.loadmat(tmp_path / "paper.mat")["A"], paper.A)
    # --json is --format json
    assert main(["analyze", spec, "--pose", "nominal", "--json"]) == 0
    by_alias = json.loads(capsys.readouterr().out)
    assert main(["analyze", spec, "--pose", "nominal", "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out) == by_alias
    assert main(["analyze", spec, "--pose", "nominal", "-o", str(tmp_path / "r.json")]) == 0
    assert json.loads((tmp_path / "r.json").read_text()) == by_alias


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--format", "npz"], "--format npz writes a file: add --output FILE.npz"),
        (["--format", "mat"], "--format mat writes a file: add --output FILE.mat"),
        (["--format", "npz", "--output", "lin.mat"], "--format npz writes a .npz file"),
        (["--format", "mat", "--output", "lin.npz"], "--format mat writes a .mat file"),
        (["--format", "json", "--output", "lin.txt"], "--format json writes a .json file"),
    ],
)
def test_cli_refuses_a_missing_or_wrong_file(args, message, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["analyze", str(PAPER_SPEC), *args]) == 1
    assert message in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_cli_writes_nothing_without_an_equilibrium(tmp_path, capsys):
    target = tmp_path / "lin.npz"
    argv = ["analyze", str(VERTICAL), "--q", "0", "0", "--tension", "zero"]
    assert main([*argv, "--format", "npz", "--output", str(target)]) == 3
    out, err = capsys.readouterr()
    assert "INFEASIBLE" in out and f"{target} not written" in err
    assert not target.exists()


def test_to_control_is_the_same_system(lin):
    control = pytest.importorskip("control", reason="python-control (cdpm[control]) missing")
    sys_ = lin.to_control()
    assert isinstance(sys_, control.StateSpace)
    np.testing.assert_array_equal(sys_.A, lin.A)
    np.testing.assert_array_equal(sys_.B, lin.B)
    np.testing.assert_array_equal(sys_.C, lin.C)
    np.testing.assert_array_equal(sys_.D, np.zeros((2, 4)))
    assert sys_.input_labels == ["c1", "c2", "c3", "c4"]
    assert sys_.output_labels == ["tip_x", "tip_z"]
    np.testing.assert_array_equal(lin.to_control(cone=True).B, lin.B_cone)
    # a step of 1 N on the taut cable c1 (input 0) for 0.1 s: y = C int_0^T e^{As} ds b_1,
    # from the exponential of the augmented matrix [[A, b_1], [0, 0]]
    t = np.linspace(0.0, 0.1, 201)
    response = control.step_response(sys_, T=t, input=0)
    y = np.asarray(response.outputs)[..., -1].reshape(-1)
    augmented = np.zeros((5, 5))
    augmented[:4, :4], augmented[:4, 4] = lin.A, lin.B[:, 0]
    expected = lin.C @ scipy.linalg.expm(augmented * 0.1)[:4, 4]
    assert abs(expected[1]) > 1e-3  # the tip moves: the test can fail
    np.testing.assert_allclose(y, expected, rtol=1e-6)


def test_to_control_names_the_extra_when_missing(lin, monkeypatch):
    monkeypatch.setitem(sys.modules, "control", None)  # import control -> ImportError
    with pytest.raises(cdpm.MissingExtraError, match=r"pip install 'cdpm\[control\]'"):
        lin.to_control()


def test_linearisation_prints_rounded_to_its_scale():
    spatial = cdpm.load_robot(MODELS / "spatial_8cable")
    text = str(cdpm.linearise(spatial, "offset"))
    a_rows = text[text.index("A =\n") : text.index("B =\n")].splitlines()[1:]
    assert len(a_rows) == 12  # one line per row
    assert not re.search(r"\de-\d", text) and not re.search(r"(?<![\w.])-0\.?(?![\w.])", text)
    planar = cdpm.load_robot(PAPER_SPEC)
    text = str(cdpm.linearise(planar, [np.pi / 2, 0.0]))
    assert "C =\n[[-2. -1.  0.  0.]]" in text
