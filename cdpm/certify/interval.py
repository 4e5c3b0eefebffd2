"""Interval arithmetic on numpy arrays, rounded outward.

An :class:`Interval` holds two float64 arrays of one shape, ``lo`` and
``hi``: the set of arrays ``x`` with ``lo <= x <= hi`` element by element.
Every operation returns a true enclosure of its exact result over every
choice of the operands inside theirs, round-off included:

- ``+``, ``-``, ``*``, ``/`` by a point, ``sqrt`` and ``reciprocal`` are
  correctly rounded in IEEE 754 arithmetic (gradual underflow on, numpy's
  default), so one step of ``np.nextafter`` outward (towards -inf on ``lo``,
  +inf on ``hi``) after each of them is enough;
- sums over an axis (:meth:`Interval.sum`, and so :func:`matmul`) use
  numpy's summation with the bound ``|fl(sum) - sum| <= gamma_{n-1}
  sum |x_i|`` (``gamma_k = k u / (1 - k u)``, any order of summation),
  taken as ``2 n eps sum |x_i|``, then one more ``nextafter``;
- ``sin`` and ``cos`` are numpy's, widened by
  :data:`cdpm.numerics.CERTIFY_SINCOS_ERROR` (an absolute bound of their
  error), and take the extreme values +-1 whenever a maximum or minimum of
  the function may lie in the interval (tested with a margin that can only
  add an extremum, never miss one).

Arrays broadcast as numpy's do. A plain numpy array (or a float) stands for
a point: ``Interval * ndarray`` and ``ndarray @ Interval`` work, with the
fewer products that a point needs. The class holds only what cdpm's
certified boxes need (:mod:`cdpm.certify.kinematics`); it is not a
general-purpose interval library.

The per-element interval types of PyInterval and ``mpmath.iv`` would cost
one Python object per entry, far too slow for maps of many boxes.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cdpm.numerics import CERTIFY_SINCOS_ERROR

__all__ = ["Interval", "matmul", "stack", "sin", "cos", "as_interval"]

_EPS = np.finfo(float).eps
_INF = np.inf
#: a maximum or minimum of sin/cos at ``phase + 2 k pi`` counts as inside
#: [a, b] when k is within this relative margin of [t_a, t_b]
#: (``t = (x - phase) / (2 pi)``); far above the round-off of t, and so small
#: that taking an extremum in too early costs nothing visible
_EXTREMUM_MARGIN = 1e-10


#: what an Interval's operators take as a point operand
_POINTS = (np.ndarray, float, int, np.floating, np.integer, list, tuple)


def _down(x: np.ndarray) -> np.ndarray:
    return np.nextafter(x, -_INF)


def _up(x: np.ndarray) -> np.ndarray:
    return np.nextafter(x, _INF)


class Interval:
    """An array of closed intervals ``[lo, hi]`` (element by element).

    Attributes:
        lo: lower bounds, float64 array.
        hi: upper bounds, float64 array of the same shape.
    """

    __slots__ = ("lo", "hi")
    # numpy hands ``ndarray * Interval`` over to Interval.__rmul__
    __array_ufunc__ = None

    def __init__(self, lo: Any, hi: Any = None) -> None:
        lo = np.asarray(lo, dtype=float)
        hi = lo if hi is None else np.asarray(hi, dtype=float)
        if lo.shape != hi.shape:
            lo, hi = np.broadcast_arrays(lo, hi)
        if not np.all(lo <= hi):
            bad = np.flatnonzero(~(lo <= hi).reshape(-1))[0]
            raise ValueError(
                f"an interval needs lo <= hi (and no NaN); entry {bad} has "
                f"lo={lo.reshape(-1)[bad]!r}, hi={hi.reshape(-1)[bad]!r}"
            )
        self.lo, self.hi = lo, hi

    @classmethod
    def _raw(cls, lo: np.ndarray, hi: np.ndarray) -> Interval:
        """No checks: for results whose bounds are ordered by construction."""
        out = object.__new__(cls)
        out.lo, out.hi = lo, hi
        return out

    # ----------------------------------------------------------- array shape

    @property
    def shape(self) -> tuple[int, ...]:
        return self.lo.shape

    @property
    def ndim(self) -> int:
        return self.lo.ndim

    def __len__(self) -> int:
        return len(self.lo)

    def __getitem__(self, index: Any) -> Interval:
        return Interval._raw(self.lo[index], self.hi[index])

    def reshape(self, *shape: Any) -> Interval:
        return Interval._raw(self.lo.reshape(*shape), self.hi.reshape(*shape))

    def swapaxes(self, a: int, b: int) -> Interval:
        return Interval._raw(self.lo.swapaxes(a, b), self.hi.swapaxes(a, b))

    def moveaxis(self, source: int, destination: int) -> Interval:
        return Interval._raw(
            np.moveaxis(self.lo, source, destination), np.moveaxis(self.hi, source, destination)
        )

    def broadcast_to(self, shape: tuple[int, ...]) -> Interval:
        return Interval._raw(np.broadcast_to(self.lo, shape), np.broadcast_to(self.hi, shape))

    @property
    def mT(self) -> Interval:  # noqa: N802 (numpy's name)
        """Transpose of the last two axes."""
        return self.swapaxes(-1, -2)

    def __repr__(self) -> str:
        return f"Interval(lo={self.lo!r}, hi={self.hi!r})"

    # ------------------------------------------------------------ properties

    @property
    def width(self) -> np.ndarray:
        """``hi - lo`` (rounded up)."""
        return _up(self.hi - self.lo)

    @property
    def midpoint(self) -> np.ndarray:
        """``(lo + hi) / 2`` (a point inside the interval)."""
        mid = 0.5 * self.lo + 0.5 * self.hi
        return np.clip(mid, self.lo, self.hi)

    @property
    def magnitude(self) -> np.ndarray:
        """``max(|lo|, |hi|)``: the largest absolute value in the interval."""
        return np.maximum(np.abs(self.lo), np.abs(self.hi))

    def contains(self, x: Any) -> np.ndarray:
        """Whether each entry of the point array ``x`` lies in its interval
        (broadcasting), as a boolean array."""
        x = np.asarray(x, dtype=float)
        return (self.lo <= x) & (x <= self.hi)

    def hull(self, other: Any) -> Interval:
        """The smallest intervals holding both ``self`` and ``other``."""
        other = as_interval(other)
        return Interval._raw(np.minimum(self.lo, other.lo), np.maximum(self.hi, other.hi))

    def intersect(self, lo: Any, hi: Any) -> Interval:
        """``self`` cut to [lo, hi] (a known range of the exact values, such
        as [-1, 1] for a unit vector's components). The result is empty
        nowhere as long as the exact values lie in both."""
        return Interval._raw(np.maximum(self.lo, lo), np.minimum(self.hi, hi))

    # ------------------------------------------------------------ arithmetic

    def __neg__(self) -> Interval:
        return Interval._raw(-self.hi, -self.lo)

    def __add__(self, other: Any) -> Interval:
        if not isinstance(other, (Interval, *_POINTS)):
            return NotImplemented
        if isinstance(other, Interval):
            return Interval._raw(_down(self.lo + other.lo), _up(self.hi + other.hi))
        other = np.asarray(other, dtype=float)
        return Interval._raw(_down(self.lo + other), _up(self.hi + other))

    __radd__ = __add__

    def __sub__(self, other: Any) -> Interval:
        if not isinstance(other, (Interval, *_POINTS)):
            return NotImplemented
        if isinstance(other, Interval):
            return Interval._raw(_down(self.lo - other.hi), _up(self.hi - other.lo))
        other = np.asarray(other, dtype=float)
        return Interval._raw(_down(self.lo - other), _up(self.hi - other))

    def __rsub__(self, other: Any) -> Interval:
        if not isinstance(other, _POINTS):
            return NotImplemented
        return (-self) + other

    def __mul__(self, other: Any) -> Interval:
        if not isinstance(other, (Interval, *_POINTS)):
            return NotImplemented
        if isinstance(other, Interval):
            products = (
                self.lo * other.lo,
                self.lo * other.hi,
                self.hi * other.lo,
                self.hi * other.hi,
            )
            lo = np.minimum(np.minimum(products[0], products[1]), np.minimum(*products[2:]))
            hi = np.maximum(np.maximum(products[0], products[1]), np.maximum(*products[2:]))
        else:
            other = np.asarray(other, dtype=float)
            a, b = self.lo * other, self.hi * other
            lo, hi = np.minimum(a, b), np.maximum(a, b)
        return Interval._raw(_down(lo), _up(hi))

    __rmul__ = __mul__

    def __truediv__(self, other: Any) -> Interval:
        if not isinstance(other, (Interval, *_POINTS)):
            return NotImplemented
        if isinstance(other, Interval):
            return self * other.reciprocal()
        other = np.asarray(other, dtype=float)
        if np.any(other == 0):
            raise ZeroDivisionError("division of an interval by zero")
        a, b = self.lo / other, self.hi / other
        return Interval._raw(_down(np.minimum(a, b)), _up(np.maximum(a, b)))

    def __matmul__(self, other: Any) -> Interval:
        if not isinstance(other, (Interval, *_POINTS)):
            return NotImplemented
        return matmul(self, other)

    def __rmatmul__(self, other: Any) -> Interval:
        if not isinstance(other, _POINTS):
            return NotImplemented
        return matmul(other, self)

    def square(self) -> Interval:
        """``x**2``, tighter than ``x * x`` (0 when the interval holds 0)."""
        a, b = self.lo * self.lo, self.hi * self.hi
        hi = np.maximum(a, b)
        lo = np.where((self.lo <= 0) & (self.hi >= 0), 0.0, _down(np.minimum(a, b)))
        return Interval._raw(lo, _up(hi))

    def sqrt(self) -> Interval:
        """Square root. Negative lower bounds (round-off below an exact 0)
        are taken as 0; an interval wholly below 0 raises ValueError."""
        if np.any(self.hi < 0):
            raise ValueError("square root of an interval below 0")
        lo = np.sqrt(np.maximum(self.lo, 0.0))
        return Interval._raw(np.maximum(_down(lo), 0.0), _up(np.sqrt(self.hi)))

    def reciprocal(self) -> Interval:
        """``1 / x``.

        Raises:
            ZeroDivisionError: some interval holds 0.
        """
        if np.any((self.lo <= 0) & (self.hi >= 0)):
            raise ZeroDivisionError("reciprocal of an interval that holds 0")
        return Interval._raw(_down(1.0 / self.hi), _up(1.0 / self.lo))

    def sum(self, axis: int | None = None) -> Interval:
        """Sum over ``axis`` (all entries when None), enclosing numpy's
        summation error (``2 n eps sum |x_i|``, n the number of terms)."""
        lo, hi = self.lo, self.hi
        if axis is None:
            lo, hi, axis = lo.reshape(-1), hi.reshape(-1), 0
        n = lo.shape[axis]
        if n <= 1:
            return Interval._raw(lo.sum(axis=axis), hi.sum(axis=axis))
        gamma = 2.0 * n * _EPS
        err_lo = _up(gamma * np.abs(lo).sum(axis=axis))
        err_hi = _up(gamma * np.abs(hi).sum(axis=axis))
        return Interval._raw(_down(lo.sum(axis=axis) - err_lo), _up(hi.sum(axis=axis) + err_hi))


def as_interval(x: Any) -> Interval:
    """``x`` as an Interval (a point array becomes ``[x, x]``)."""
    return x if isinstance(x, Interval) else Interval(x)


def matmul(a: Any, b: Any) -> Interval:
    """Matrix product with numpy's ``@`` broadcasting (either operand may be
    a point array; 1-D operands are vectors). The products are rounded
    outward, the sums over the inner axis as in :meth:`Interval.sum`."""
    a_vec = np.ndim(a.lo if isinstance(a, Interval) else a) == 1
    b_vec = np.ndim(b.lo if isinstance(b, Interval) else b) == 1
    if a_vec:
        a = a[None, :] if isinstance(a, Interval) else np.asarray(a, dtype=float)[None, :]
    if b_vec:
        b = b[:, None] if isinstance(b, Interval) else np.asarray(b, dtype=float)[:, None]
    if not isinstance(a, Interval) and not isinstance(b, Interval):
        a = as_interval(a)
    if isinstance(a, Interval):
        left = a[..., :, :, None]
    else:
        left = np.asarray(a, dtype=float)[..., :, :, None]
    if isinstance(b, Interval):
        right = b[..., None, :, :]
    else:
        right = np.asarray(b, dtype=float)[..., None, :, :]
    out = (left * right if isinstance(left, Interval) else right * left).sum(axis=-2)
    if b_vec:
        out = out[..., 0]
    if a_vec:
        out = out[..., 0, :] if not b_vec else out[..., 0]
    return out


def stack(items: list[Any], axis: int = 0) -> Interval:
    """``np.stack`` of intervals (or point arrays) along a new ``axis``."""
    items = [as_interval(x) for x in items]
    return Interval._raw(
        np.stack([x.lo for x in items], axis=axis), np.stack([x.hi for x in items], axis=axis)
    )


def _may_hold(a: np.ndarray, b: np.ndarray, phase: float) -> np.ndarray:
    """Whether some ``phase + 2 k pi`` may lie in [a, b] (never False when it
    does; True also within a tiny relative margin outside)."""
    t_a = (a - phase) / (2.0 * math.pi)
    t_b = (b - phase) / (2.0 * math.pi)
    margin = _EXTREMUM_MARGIN * (1.0 + np.maximum(np.abs(t_a), np.abs(t_b)))
    return np.floor(t_b + margin) >= np.ceil(t_a - margin)


def _periodic(x: Any, fn, phase_max: float, phase_min: float) -> Interval:
    x = as_interval(x)
    a, b = x.lo, x.hi
    fa, fb = fn(a), fn(b)
    lo = np.minimum(fa, fb) - CERTIFY_SINCOS_ERROR
    hi = np.maximum(fa, fb) + CERTIFY_SINCOS_ERROR
    hi = np.where(_may_hold(a, b, phase_max), 1.0, np.minimum(_up(hi), 1.0))
    lo = np.where(_may_hold(a, b, phase_min), -1.0, np.maximum(_down(lo), -1.0))
    wide = (b - a) >= 2.0 * math.pi
    return Interval._raw(np.where(wide, -1.0, lo), np.where(wide, 1.0, hi))


def sin(x: Any) -> Interval:
    """Enclosure of sin over each interval of ``x``."""
    return _periodic(x, np.sin, 0.5 * math.pi, 1.5 * math.pi)


def cos(x: Any) -> Interval:
    """Enclosure of cos over each interval of ``x``."""
    return _periodic(x, np.cos, 0.0, math.pi)
