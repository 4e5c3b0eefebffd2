"""Interval arithmetic and jets of cdpm.certify: every enclosure holds the
exact result at every point of its operands' intervals, round-off included.

Points sampled inside random intervals go through numpy and must land in
the enclosure; exact rational arithmetic (fractions.Fraction) checks the
outward rounding where a float computation would round inward.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from cdpm.certify.interval import Interval, cos, matmul, sin, stack
from cdpm.certify.jet import Jet, jet_cos, jet_sin, mean_value, variables

RNG_SEED = 20261128
N_SAMPLES = 64


def random_interval(rng, shape, scale=3.0, positive=False):
    centre = rng.uniform(-scale, scale, shape)
    if positive:
        centre = np.abs(centre) + 0.1
    half = rng.uniform(0, 1, shape) * 10.0 ** rng.integers(-12, 1, shape)
    if positive:
        half = np.minimum(half, 0.5 * centre)
    return Interval(centre - half, centre + half)


def samples(rng, x: Interval, n=N_SAMPLES):
    """n points of x (corners included), shape (n,) + x.shape."""
    u = rng.uniform(0, 1, (n,) + x.shape)
    u[0], u[1] = 0.0, 1.0
    pts = x.lo + u * (x.hi - x.lo)
    return np.clip(pts, x.lo, x.hi)


@pytest.mark.parametrize(
    ("name", "op"),
    [
        ("add", lambda a, b: a + b),
        ("sub", lambda a, b: a - b),
        ("mul", lambda a, b: a * b),
    ],
)
def test_binary_operations_hold_every_point(name, op):
    rng = np.random.default_rng(RNG_SEED)
    a, b = random_interval(rng, (50,)), random_interval(rng, (50,))
    out = op(a, b)
    for x, y in zip(samples(rng, a), samples(rng, b), strict=True):
        assert out.contains(op(x, y)).all(), name
    # interval op point, point op interval
    p = rng.uniform(-2, 2, 50)
    assert op(a, p).contains(op(samples(rng, a), p)).all()
    assert op(p, a).contains(op(p, samples(rng, a))).all()


def test_unary_operations_hold_every_point():
    rng = np.random.default_rng(RNG_SEED + 1)
    a = random_interval(rng, (200,))
    pos = random_interval(rng, (200,), positive=True)
    xs, ps = samples(rng, a), samples(rng, pos)
    assert a.square().contains(xs**2).all()
    assert pos.sqrt().contains(np.sqrt(ps)).all()
    assert pos.reciprocal().contains(1.0 / ps).all()
    assert (-a).contains(-xs).all()
    assert (a / 3.0).contains(xs / 3.0).all()
    # a square of an interval around 0 starts at 0, not at a negative product
    assert Interval(-1.0, 2.0).square().lo == 0.0


def test_sums_and_matrix_products_hold_every_point():
    rng = np.random.default_rng(RNG_SEED + 2)
    a = random_interval(rng, (4, 3, 5))
    b = random_interval(rng, (4, 5, 2))
    m = rng.uniform(-1, 1, (3, 5))
    xs, ys = samples(rng, a, 32), samples(rng, b, 32)
    ab, mb, am = a @ b, m @ b, a @ m.T
    total = a.sum(axis=-1)
    for x, y in zip(xs, ys, strict=True):
        assert ab.contains(x @ y).all()
        assert mb.contains(m @ y).all()
        assert am.contains(x @ m.T).all()
        assert total.contains(x.sum(axis=-1)).all()
    # vectors
    v = random_interval(rng, (5,))
    assert matmul(a, v).contains(xs[0] @ v.lo).all()
    assert (m @ v).shape == (3,)


def test_sin_and_cos_hold_every_point_and_reach_their_extrema():
    rng = np.random.default_rng(RNG_SEED + 3)
    # intervals around every kind of extremum, tiny to wide
    centres = np.concatenate([np.arange(-8, 9) * math.pi / 2, rng.uniform(-10, 10, 100)])
    widths = 10.0 ** rng.uniform(-14, 1, centres.shape)
    x = Interval(centres - widths * rng.uniform(0, 1, centres.shape), centres + widths)
    xs = samples(rng, x, 400)
    s, c = sin(x), cos(x)
    assert s.contains(np.sin(xs)).all()
    assert c.contains(np.cos(xs)).all()
    # a maximum inside: the enclosure reaches 1 exactly, and -1 at a minimum
    assert sin(Interval(math.pi / 2 - 1e-3, math.pi / 2 + 1e-3)).hi == 1.0
    assert sin(Interval(-math.pi / 2 - 1e-3, -math.pi / 2 + 1e-3)).lo == -1.0
    assert cos(Interval(2 * math.pi - 1e-3, 2 * math.pi + 1e-3)).hi == 1.0
    assert cos(Interval(3 * math.pi - 1e-3, 3 * math.pi + 1e-3)).lo == -1.0
    # no extremum inside: the enclosure stays near the end values
    away = sin(Interval(0.1, 0.2))
    assert away.lo == pytest.approx(math.sin(0.1), abs=1e-14)
    assert away.hi == pytest.approx(math.sin(0.2), abs=1e-14)
    # wider than a turn: everything
    wide = cos(Interval(0.3, 0.3 + 2 * math.pi))
    assert (wide.lo, wide.hi) == (-1.0, 1.0)


def test_outward_rounding_holds_the_exact_rational_results():
    a, b = Interval(0.1), Interval(0.2)
    exact = Fraction(0.1) + Fraction(0.2)  # the doubles' exact sum
    s = a + b
    assert Fraction(s.lo) <= exact <= Fraction(s.hi)
    assert Fraction(0.1 + 0.2) != exact  # the float sum alone is not it
    p = a * b
    assert Fraction(p.lo) <= Fraction(0.1) * Fraction(0.2) <= Fraction(p.hi)
    q = Interval(3.0).reciprocal()
    assert Fraction(q.lo) <= Fraction(1, 3) <= Fraction(q.hi)
    root = Interval(2.0).sqrt()
    assert Fraction(root.lo) ** 2 <= 2 <= Fraction(root.hi) ** 2
    # a sum of many terms whose float sum loses digits
    rng = np.random.default_rng(RNG_SEED + 4)
    terms = rng.uniform(-1, 1, 1000) * 10.0 ** rng.integers(-8, 8, 1000)
    total = Interval(terms).sum()
    exact_total = sum(Fraction(t) for t in terms)
    assert Fraction(total.lo) <= exact_total <= Fraction(total.hi)
    # a matrix product, entry by entry
    m = rng.uniform(-1, 1, (3, 4))
    n = rng.uniform(-1, 1, (4, 2))
    prod = Interval(m) @ n
    for i in range(3):
        for j in range(2):
            e = sum(Fraction(m[i, k]) * Fraction(n[k, j]) for k in range(4))
            assert Fraction(prod.lo[i, j]) <= e <= Fraction(prod.hi[i, j])


def test_point_enclosures_are_round_off_wide():
    x = Interval(np.linspace(-3, 3, 7))
    for enclosure in (sin(x), cos(x), x * x + x, (x @ x[:, None]), x.square().sqrt()):
        assert np.all(enclosure.width <= 1e-14 * np.maximum(1.0, enclosure.magnitude))


def test_reciprocal_of_an_interval_holding_zero_raises():
    with pytest.raises(ZeroDivisionError, match="holds 0"):
        Interval([-1.0, 1.0], [1.0, 2.0]).reciprocal()
    with pytest.raises(ValueError, match="lo <= hi"):
        Interval(1.0, 0.0)


def test_helpers_hull_width_midpoint_stack():
    a, b = Interval(0.0, 1.0), Interval(2.0, 3.0)
    h = a.hull(b)
    assert (h.lo, h.hi) == (0.0, 3.0)
    assert h.width == np.nextafter(3.0, 4.0)  # rounded up: never below the width
    assert h.midpoint == 1.5
    assert h.contains(2.5) and not h.contains(3.5)
    st = stack([a, b, np.array(5.0)])
    assert st.shape == (3,) and st.contains([0.5, 2.5, 5.0]).all()


def _f(q0, q1, sin_fn):
    """A test function of two coordinates: sin(q0) q1^2 + q1 / (2 + q0^2)."""
    return sin_fn(q0) * q1.square() + q1 * (q0.square() + 2.0).reciprocal()


def test_jets_enclose_derivatives_and_the_mean_value_form():
    rng = np.random.default_rng(RNG_SEED + 5)
    lo = rng.uniform(-2, 2, (20, 2))
    hi = lo + 10.0 ** rng.uniform(-6, 0, (20, 2))
    q = variables(lo, hi)
    jet = _f(q[:, 0], q[:, 1], jet_sin)
    assert isinstance(jet, Jet) and jet.grad.shape == (20, 2)
    centre = 0.5 * (lo + hi)
    radius = np.maximum(centre - lo, hi - centre)
    at_centre = _f(Interval(centre[:, 0]), Interval(centre[:, 1]), sin)
    mv = mean_value(at_centre, jet, radius)
    for t in rng.uniform(0, 1, (100, 1, 2)):
        x = lo + t * (hi - lo)
        a, b = x[:, 0], x[:, 1]
        value = np.sin(a) * b**2 + b / (2 + a**2)
        d0 = np.cos(a) * b**2 - b * 2 * a / (2 + a**2) ** 2
        d1 = 2 * np.sin(a) * b + 1 / (2 + a**2)
        assert jet.val.contains(value).all() and mv.contains(value).all()
        assert jet.grad[:, 0].contains(d0).all() and jet.grad[:, 1].contains(d1).all()
    # on small boxes the mean-value form is the tighter one
    small = (hi - lo).max(axis=1) < 1e-3
    assert np.all(mv.width[small] <= jet.val.width[small])
    # cos jets: d cos / dq = -sin
    c = jet_cos(q[:, 0])
    assert c.grad[:, 0].contains(-np.sin(lo[:, 0])).all()
