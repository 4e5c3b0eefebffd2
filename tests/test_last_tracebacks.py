"""Inputs that used to end in a raw traceback or a wrong result, now refused
with a one-line cdpm error (or read as the user wrote them)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.errors import SpecError
from cdpm.model.yaml_loading import MAX_YAML_DEPTH, load_yaml
from tests.conftest import paper_spec_copy, paper_spec_text
from tests.processes import lock_held_elsewhere

MODEL = Path(__file__).parent.parent / "models" / "two_link_planar"


@pytest.mark.parametrize(("literal", "digits"), [("1" * 5000, "5,000"), ("0x" + "f" * 300, "300")])
def test_huge_integer_is_a_spec_error(tmp_path, literal, digits):
    text = paper_spec_text().replace("gravity: [0, 0, 0]", f"gravity: [0, 0, {literal}]", 1)
    with pytest.raises(
        SpecError, match=f"line 7: an integer of {digits} digits is too large for a number"
    ):
        cdpm.load_robot(paper_spec_copy(tmp_path, text))


def test_long_but_sane_integer_still_loads():
    data, problems = load_yaml("a: 123_456_789_012_345_678_901\n")
    assert data == {"a": 123456789012345678901}
    assert problems == []


# 2. a chain of aliases used as a mapping key


def test_alias_chain_as_mapping_key_is_refused(tmp_path):
    n = 300
    chain = "a0: &a0 [1]\n" + "".join(f"a{i}: &a{i} [*a{i - 1}]\n" for i in range(1, n))
    text = chain + f"? *a{n - 1}\n: 1\n" + paper_spec_text()
    with pytest.raises(
        SpecError, match=f"nest more than {MAX_YAML_DEPTH} deep once its aliases .* are expanded"
    ):
        cdpm.load_robot(paper_spec_copy(tmp_path, text))


def test_short_alias_chain_still_loads():
    data, problems = load_yaml("a: &a [1]\nb: &b [*a]\nc: [*b, *b]\n")
    assert data["c"] == [[[1]], [[1]]]
    assert problems == []


# 3. YAML 1.1 sexagesimal numbers are read as written


def test_sexagesimal_is_read_as_written():
    data, problems = load_yaml("a: 190:20:30\nb: -1:30.5\nc: 19020\nd: 1.5\n")
    assert data == {"a": "190:20:30", "b": "-1:30.5", "c": 19020, "d": 1.5}
    assert problems == []


def test_sexagesimal_coordinate_is_refused_as_written(tmp_path):
    text = paper_spec_text().replace("poses:\n", "poses:\n  weird: [190:20:30, 1]\n", 1)
    with pytest.raises(SpecError, match=r"poses\.weird: \[0\]: '190:20:30' is not a number"):
        cdpm.load_robot(paper_spec_copy(tmp_path, text))


# 4. CASPR joint limits with q_min > q_max


@pytest.mark.parametrize(
    ("overrides", "drop", "match"),
    [
        (
            {2: {"qmin": "-1 2", "qmax": "1 1"}},
            None,
            r"L2.*: q_min\[1\] = 2 > q_max\[1\] = 1: each lower joint limit must be at most",
        ),
        (
            {1: {"qmin": "4", "qmax": "9"}},
            ' q_max="9"',
            r"L1.*: q_min\[0\] = 4 > q_max\[0\] = 3.14159 \(q_max not given: CASPR's default\)",
        ),
    ],
)
def test_caspr_crossed_joint_limits_are_refused(tmp_path, overrides, drop, match):
    from tests.test_caspr import _import_quietly, _write_model

    bodies, cables = _write_model(tmp_path, ["R_X", "P_XY"], overrides=overrides)
    if drop is not None:
        bodies.write_text(bodies.read_text().replace(drop, "", 1))
    with pytest.raises(cdpm.InputError, match=match):
        _import_quietly(bodies, cables, tmp_path / "out")


# 5. cdpm picture with a tiny --dpi or a huge --title


@pytest.mark.parametrize(
    ("option", "value", "match"),
    [
        ("--dpi", "0.01", "dpi=0.01 is too low for a picture.* give 20 to 1200 dots per inch"),
        ("--dpi", "5", "dpi=5 is too low for a picture"),
        ("--title", "x" * 10_000, "the title has 10,000 characters, more than the 1,000"),
        ("--title", "word " * 2_000, "the title has 9,999 characters, more than the 1,000"),
    ],
)
def test_picture_bad_dpi_or_title_is_a_usage_error(tmp_path, capsys, option, value, match):
    pytest.importorskip("matplotlib")
    from cdpm.cli import main

    out = tmp_path / "p.png"
    with pytest.raises(SystemExit) as info:
        main(["picture", str(MODEL), "--pose", "nominal", "-o", str(out), option, value])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert re.search(match, err), err
    assert "Traceback" not in err and not out.exists()


def test_picture_title_of_one_long_word_does_not_crash(paper_robot):
    pytest.importorskip("matplotlib")
    from cdpm.plotting.picture import render_pose

    # one 1,000-character word in a small figure: the wrap width used to fall to 0
    fig = render_pose(paper_robot, "nominal", title="x" * 1000, figsize=(2.0, 2.0))
    assert fig.axes[0].get_title().replace("\n", "") == "x" * 1000


# 6. an indefinite link inertia in the URDF


def _urdf_variant(tmp_path: Path, inertia: str) -> Path:
    shutil.copy(MODEL / "two_link_planar.yaml", tmp_path)
    text = (MODEL / "two_link_planar.urdf").read_text()
    zero = '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>'
    assert zero in text
    (tmp_path / "two_link_planar.urdf").write_text(text.replace(zero, inertia, 1))
    return tmp_path / "two_link_planar.yaml"


def test_indefinite_inertia_is_a_model_error(tmp_path):
    # principal moments -1, 1, 3 kg m^2: positive diagonal, indefinite matrix
    spec = _urdf_variant(tmp_path, '<inertia ixx="1" ixy="2" ixz="0" iyy="1" iyz="0" izz="1"/>')
    with pytest.raises(
        cdpm.ModelError, match=r"'q1' has an inertia matrix with a negative principal moment"
    ):
        cdpm.load_robot(spec)


def test_semi_definite_inertia_still_loads(tmp_path):
    # principal moments 0, 2, 1 kg m^2: a thin rod's inertia is singular, not indefinite
    spec = _urdf_variant(tmp_path, '<inertia ixx="1" ixy="1" ixz="0" iyy="1" iyz="0" izz="1"/>')
    robot = cdpm.load_robot(spec)
    moments = np.linalg.eigvalsh(np.array(robot.model.inertias[1].inertia))
    np.testing.assert_allclose(moments, [0.0, 1.0, 2.0], atol=1e-12)


def test_caspr_indefinite_inertia_is_refused_at_import(tmp_path):
    from tests.test_caspr import _import_quietly, _write_model

    # about the joint, mass 2 kg at com (0.1, 0.2, 0.3): the inertia about the
    # COM (less 2 kg x the parallel-axis term) has a moment of -0.076 kg m^2
    overrides = {1: {"ref": "joint", "mass": 2.0, "com": "0.1 0.2 0.3"}}
    bodies, cables = _write_model(tmp_path, ["R_X", "R_Y"], overrides=overrides)
    with pytest.raises(
        cdpm.InputError, match=r"L1.*: its inertia about the COM .* has a negative principal"
    ):
        _import_quietly(bodies, cables, tmp_path / "out")


# 7. the store lock through a symbolic link to the store


@pytest.mark.parametrize("linked", ["store", "folder"])
def test_store_lock_holds_through_a_symlink(tmp_path, linked):
    from cdpm.maps._lock import lock_path, store_lock

    (tmp_path / "real").mkdir()
    store = tmp_path / "real" / "m.zarr"
    store.mkdir()
    if linked == "store":
        alias = tmp_path / "alias.zarr"
        alias.symlink_to(store)
    else:
        (tmp_path / "link").symlink_to(tmp_path / "real")
        alias = tmp_path / "link" / "m.zarr"
    with store_lock(store):
        assert lock_held_elsewhere(alias)
    with store_lock(alias):
        assert lock_held_elsewhere(store)
    assert lock_path(alias) == lock_path(store)
    assert not lock_path(store).exists()


def test_store_lock_refuses_a_symlink_loop(tmp_path):
    from cdpm.maps._lock import store_lock

    (tmp_path / "a.zarr").symlink_to(tmp_path / "b.zarr")
    (tmp_path / "b.zarr").symlink_to(tmp_path / "a.zarr")
    with pytest.raises(cdpm.InputError, match="choose another path"):
        with store_lock(tmp_path / "a.zarr"):
            pass
