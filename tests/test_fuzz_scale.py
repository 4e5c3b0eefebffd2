"""Scale: a shipped model with every mass times 10**k and every length times
10**j (inertias times 10**(k + 2j), tension bounds [0, inf), no pretension)
has the POC verdicts of the unit model at every pose, or is refused with
cdpm's error when its masses or lengths leave the range cdpm analyses
(tests/fuzzing.py; ``python tools/fuzz_specs.py --class scale`` runs more)."""

from __future__ import annotations

import numpy as np
import pytest

import cdpm
from tests.fuzzing import (
    ROOT,
    SCALE_LENGTH_EXPONENTS,
    SCALE_MASS_EXPONENTS,
    SCALE_MODELS,
    make_scale_case,
    run_scale_case,
    write_scaled_model,
)


def _model(name: str):
    return ROOT / "models" / name / f"{name}.yaml"


@pytest.mark.parametrize(
    ("name", "mass_exp", "length_exp"),
    [
        ("two_link_vertical", 3, 0),
        ("two_link_vertical", -3, 1),
        ("two_link_planar", 6, -2),
        ("spatial_8cable", -3, -1),
        ("spatial_8cable", 2, 2),
        ("multilink_arm", 4, 1),
        ("multilink_arm", -4, -1),
    ],
)
def test_scaled_model_has_the_unit_models_verdicts(tmp_path, name, mass_exp, length_exp):
    case = make_scale_case(_model(name), seed=17, mass_exp=mass_exp, length_exp=length_exp)
    outcome = run_scale_case(case, tmp_path)
    assert outcome.kind == "same verdicts", outcome
    assert "yes" in outcome.detail  # the poses compared include POC ones


def test_model_scaled_past_cdpms_range_is_refused_as_such(tmp_path):
    # 25 kg x 1e9: a platform of 2.5e10 kg, beyond the 1e9 kg cdpm analyses
    case = make_scale_case(_model("spatial_8cable"), seed=3, mass_exp=9, length_exp=0)
    outcome = run_scale_case(case, tmp_path)
    assert outcome.kind == "refused (out of range)"
    assert "mass 2.5e+10 kg" in outcome.detail


def test_scaled_copy_scales_mass_inertia_and_lengths(tmp_path):
    """The generator itself: total mass x 1e3, size x 1e-2, and at the same
    pose the mass matrix x 1e3 x (1e-2)^2 (revolute joints: M ~ m L^2)."""
    unit = cdpm.load_robot(write_scaled_model(_model("two_link_vertical"), tmp_path / "a", 0, 0))
    scaled = cdpm.load_robot(write_scaled_model(_model("two_link_vertical"), tmp_path / "b", 3, -2))
    assert scaled.mass == pytest.approx(1e3 * unit.mass, rel=1e-12)
    assert scaled.size == pytest.approx(1e-2 * unit.size, rel=1e-12)
    q = np.array([0.4, -0.7])
    np.testing.assert_allclose(
        scaled.mass_matrix(q), 1e3 * 1e-4 * unit.mass_matrix(q), rtol=1e-10, atol=0
    )
    np.testing.assert_allclose(scaled.output(q), 1e-2 * unit.output(q), rtol=1e-12)
    assert np.isinf(scaled.tension_max).all() and (scaled.tension_min == 0).all()


def test_a_scaled_model_that_differs_is_caught(tmp_path, monkeypatch):
    """The comparison can fail: scaling the URDF's lengths but not the
    spec's attachment points changes the robot, and the verdicts differ."""
    import tests.scaled_models as scaled_models

    unscaled_points = scaled_models.scaled_spec

    def points_left_alone(data, mass, length, equilibrium, unbounded):
        return unscaled_points(data, mass, 1.0, equilibrium, unbounded)

    monkeypatch.setattr(scaled_models, "scaled_spec", points_left_alone)
    case = make_scale_case(_model("two_link_vertical"), seed=5, mass_exp=0, length_exp=1)
    with pytest.raises(AssertionError, match="verdicts differ|outputs|not equal"):
        run_scale_case(case, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("model", SCALE_MODELS, ids=lambda p: p.stem)
def test_every_scale_keeps_the_verdicts(tmp_path, model):
    """The wide sweep: every mass exponent -9..9 with every length exponent
    -3..3."""
    failures = []
    for mass_exp in SCALE_MASS_EXPONENTS:
        for length_exp in SCALE_LENGTH_EXPONENTS:
            case = make_scale_case(model, seed=11, mass_exp=mass_exp, length_exp=length_exp)
            try:
                run_scale_case(case, tmp_path / f"{mass_exp}_{length_exp}")
            except AssertionError as exc:
                failures.append(str(exc)[:400])
    assert not failures, f"{len(failures)} scales fail:\n" + "\n".join(failures)
