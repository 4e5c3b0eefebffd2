"""Late sample times of a slow oscillation: no overflow in the closed-form
modal responses, and the POC text says when its certificate lies beyond
the impulse index's horizon."""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest

from cdpm.analysis import Verdict, positive_output_controllability
from cdpm.analysis._modes import ModalEvaluator


def point_xz():
    """CASPR's Example_point_XZ at its initial pose, linearised: a 5 kg point
    in a vertical plane hanging from a taut vertical cable (49.05 N, free in
    sign) between two slack diagonal ones (0.001 N, pull only). Stiffness
    kappa = -9.81 /s^2 across the taut cable and -1e-4 /s^2 along it: a
    period of 628 s, so the modal search samples out to hundreds of
    seconds, where sinh(w t) of the fast mode overflows float64."""
    A = np.zeros((4, 4))
    A[:2, 2:] = np.eye(2)
    A[2:, :2] = np.diag([-9.8104, -1.0e-4])
    r = 1 / math.sqrt(2)
    B = np.zeros((4, 3))
    B[2:] = np.array([[-r, 0.0, r], [-r, 1.0, -r]]) / 5.0
    C = np.hstack([np.eye(2), np.zeros((2, 2))])
    return A, B, C, np.array([True, False, True])


def test_slow_oscillation_gives_no_runtime_warning():
    A, B, C, mask = point_xz()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = positive_output_controllability(A, B, C, sign_constrained=mask)
        text = str(res)
        assert res.certificate.verify(A, B, C)
        margin = res.margin
    assert res.verdict is Verdict.YES and res.method == "mixed-cone+modal"
    assert np.all(np.isfinite(res.certificate.vectors))
    assert margin > 0
    assert re.search(r"\b(nan|inf)\b", text, flags=re.IGNORECASE) is None, text


def test_text_says_certificate_time_is_beyond_the_index_horizon():
    A, B, C, mask = point_xz()
    res = positive_output_controllability(A, B, C, sign_constrained=mask)
    late = float(res.certificate.times.max())
    assert late > 10 * res.margin_horizon  # the case worth saying
    header = next(line for line in str(res).splitlines() if "output vectors g_j(t)" in line)
    assert f"at t up to {late:.4g}" in header
    assert f"beyond the impulse index's horizon [0, {res.margin_horizon:.4g}]" in header


def test_text_is_quiet_when_the_certificate_is_within_the_horizon():
    # the double integrator y'' = u1 - u2: g_j(t) = +-t, certified at t <= 1 = T
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0, 0.0], [1.0, -1.0]])
    C = np.array([[1.0, 0.0]])
    res = positive_output_controllability(A, B, C)
    assert res.verdict is Verdict.YES
    assert res.certificate.times.max() <= res.margin_horizon
    assert "beyond the impulse index's horizon" not in str(res)


def test_modal_responses_are_exact_at_late_times():
    # one oscillatory (w = 3), one flat, one growing (w = 0.5) mode
    kappa = np.array([-9.0, 0.0, 0.25])
    ev = ModalEvaluator(kappa, np.eye(3), np.eye(3), zero=1e-12)
    t = np.array([0.0, 1.0, 400.0, 1000.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        S = ev._s(t)
    np.testing.assert_allclose(S[:, 0], np.sin(3 * t) / 3, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(S[:, 1], t, rtol=0, atol=0)
    np.testing.assert_allclose(S[:, 2], np.sinh(0.5 * t) / 0.5, rtol=1e-12)


def test_growing_mode_refuses_times_that_overflow():
    # sinh(w t) / w reaches the largest float64 near w t = 709.78 + ln(w)
    w = 0.5
    ev = ModalEvaluator(np.array([-1.0, w * w]), np.eye(2), np.eye(2), zero=1e-12)
    assert ev.t_finite == pytest.approx((math.log(np.finfo(float).max) + math.log(w)) / w)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        S = ev._s(np.array([ev.t_finite]))
        assert np.all(np.isfinite(S))
        with pytest.raises(ValueError, match="overflow float64 beyond t = 1418"):
            ev._s(np.array([1.01 * ev.t_finite]))
    # with only oscillatory modes every time is finite
    assert ModalEvaluator(np.array([-4.0]), np.eye(1), np.eye(1), zero=1e-12).t_finite == math.inf
