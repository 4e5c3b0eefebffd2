"""Intervals with their first derivatives: forward-mode differentiation in
interval arithmetic, for mean-value forms.

A :class:`Jet` holds an enclosure ``val`` (an :class:`Interval` of shape S)
of a quantity f(q) over a box of q (n coordinates) and an enclosure
``grad`` (shape S + (n,)) of its partial derivatives ``df/dq_k`` over the
same box. Its operators apply the chain rule in interval arithmetic, so code
written for intervals (:mod:`cdpm.certify.kinematics`) runs unchanged on
jets and returns both enclosures. With them the mean-value form
``f(Q) in f(q_c) + sum_k df/dq_k(Q) [-h_k, h_k]`` (:func:`mean_value`)
holds for every q in the box Q = q_c + [-h, h].

Operands may be jets, intervals or point arrays (constants: no derivative).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cdpm.certify.interval import Interval, as_interval, cos, sin, stack

__all__ = ["Jet", "variables", "jet_sin", "jet_cos", "jet_stack", "jet_where", "mean_value"]


def _grad_axis(axis: int) -> int:
    """The axis of ``grad`` that is ``axis`` of ``val`` (grad has one more, last)."""
    return axis - 1 if axis < 0 else axis


class Jet:
    """An enclosure and the enclosure of its gradient.

    Attributes:
        val: enclosure of the values, Interval of shape S.
        grad: enclosure of the partial derivatives, Interval of shape S + (n,).
    """

    __slots__ = ("val", "grad")
    __array_ufunc__ = None

    def __init__(self, val: Interval, grad: Interval) -> None:
        self.val, self.grad = val, grad

    @property
    def shape(self) -> tuple[int, ...]:
        return self.val.shape

    @property
    def n(self) -> int:
        return self.grad.shape[-1]

    def _full_grad(self, shape: tuple[int, ...]) -> Interval:
        if self.grad.shape[:-1] == shape:
            return self.grad
        return self.grad.broadcast_to(shape + (self.n,))

    def __getitem__(self, index: Any) -> Jet:
        index = index if isinstance(index, tuple) else (index,)
        grad_index = index + (slice(None),) if any(i is Ellipsis for i in index) else index
        return Jet(self.val[index], self.grad[grad_index])

    def swapaxes(self, a: int, b: int) -> Jet:
        return Jet(self.val.swapaxes(a, b), self.grad.swapaxes(_grad_axis(a), _grad_axis(b)))

    @property
    def mT(self) -> Jet:  # noqa: N802 (numpy's name)
        return self.swapaxes(-1, -2)

    def intersect(self, lo: Any, hi: Any) -> Jet:
        """The value cut to [lo, hi] (the derivatives stay as they are)."""
        return Jet(self.val.intersect(lo, hi), self.grad)

    # ------------------------------------------------------------ arithmetic

    def __neg__(self) -> Jet:
        return Jet(-self.val, -self.grad)

    def __add__(self, other: Any) -> Jet:
        if isinstance(other, Jet):
            val = self.val + other.val
            return Jet(val, self._full_grad(val.shape) + other._full_grad(val.shape))
        val = self.val + other
        return Jet(val, self._full_grad(val.shape))

    __radd__ = __add__

    def __sub__(self, other: Any) -> Jet:
        return self + (-other)

    def __rsub__(self, other: Any) -> Jet:
        return (-self) + other

    def __mul__(self, other: Any) -> Jet:
        if isinstance(other, Jet):
            val = self.val * other.val
            grad = other.val[..., None] * self.grad + self.val[..., None] * other.grad
            return Jet(val, grad)
        point = other if isinstance(other, Interval) else np.asarray(other, dtype=float)
        return Jet(self.val * point, self.grad * point[..., None])

    __rmul__ = __mul__

    def __matmul__(self, other: Any) -> Jet:
        return _matmul(self, other)

    def __rmatmul__(self, other: Any) -> Jet:
        return _matmul(other, self)

    def square(self) -> Jet:
        return Jet(self.val.square(), (self.val * 2.0)[..., None] * self.grad)

    def sqrt(self) -> Jet:
        """Square root; the derivative needs a value bounded away from 0."""
        root = self.val.sqrt()
        return Jet(root, (root * 2.0).reciprocal()[..., None] * self.grad)

    def reciprocal(self) -> Jet:
        inverse = self.val.reciprocal()
        return Jet(inverse, (-inverse.square())[..., None] * self.grad)

    def sum(self, axis: int) -> Jet:
        return Jet(self.val.sum(axis=axis), self.grad.sum(axis=_grad_axis(axis)))


def _matmul(a: Any, b: Any) -> Jet:
    """``a @ b`` with the product rule; a 1-D point ``b`` is a vector."""
    if not isinstance(b, (Jet, Interval)) and np.ndim(b) == 1:
        return _matmul(a, np.asarray(b, dtype=float)[:, None])[..., 0]
    val_a = a.val if isinstance(a, Jet) else a
    val_b = b.val if isinstance(b, Jet) else b
    val = val_a @ val_b
    grads = []
    if isinstance(a, Jet):  # (dA @ B)[..., i, j, k] with the derivative axis moved aside
        grads.append((a.grad.moveaxis(-1, -3) @ _expand(val_b, -3)).moveaxis(-3, -1))
    if isinstance(b, Jet):
        grads.append((_expand(val_a, -3) @ b.grad.moveaxis(-1, -3)).moveaxis(-3, -1))
    grad = grads[0] if len(grads) == 1 else grads[0] + grads[1]
    return Jet(val, grad.broadcast_to(val.shape + (grad.shape[-1],)))


def _expand(x: Any, axis: int) -> Any:
    return x[(Ellipsis, None, slice(None), slice(None))] if axis == -3 else x


def variables(lo: np.ndarray, hi: np.ndarray) -> Jet:
    """The coordinates over boxes (B, n) as jets: ``dq_i/dq_k = delta_ik``."""
    n = lo.shape[-1]
    return Jet(Interval(lo, hi), Interval(np.broadcast_to(np.eye(n), lo.shape + (n,))))


def jet_sin(q: Jet | Interval) -> Jet | Interval:
    if isinstance(q, Interval):
        return sin(q)
    return Jet(sin(q.val), cos(q.val)[..., None] * q.grad)


def jet_cos(q: Jet | Interval) -> Jet | Interval:
    if isinstance(q, Interval):
        return cos(q)
    return Jet(cos(q.val), (-sin(q.val))[..., None] * q.grad)


def jet_stack(items: list[Any], axis: int) -> Jet | Interval:
    """:func:`cdpm.certify.interval.stack` of jets (or intervals, points)."""
    jets = [x for x in items if isinstance(x, Jet)]
    if not jets:
        return stack(items, axis=axis)
    n = jets[0].n
    vals = [x.val if isinstance(x, Jet) else as_interval(x) for x in items]
    grads = [
        x.grad if isinstance(x, Jet) else Interval(np.zeros(v.shape + (n,)))
        for x, v in zip(items, vals, strict=True)
    ]
    return Jet(stack(vals, axis=axis), stack(grads, axis=_grad_axis(axis)))


def jet_where(mask: np.ndarray, x: Any, y: Any) -> Jet | Interval:
    """``x`` where ``mask``, else ``y`` (jets, intervals or points), broadcast."""
    if not isinstance(x, Jet) and not isinstance(y, Jet):
        x, y = as_interval(x), as_interval(y)
        return Interval._raw(np.where(mask, x.lo, y.lo), np.where(mask, x.hi, y.hi))
    n = (x if isinstance(x, Jet) else y).n
    val = jet_where(mask, x.val if isinstance(x, Jet) else x, y.val if isinstance(y, Jet) else y)
    zero = np.zeros(1)
    gx = x.grad if isinstance(x, Jet) else Interval(zero)
    gy = y.grad if isinstance(y, Jet) else Interval(zero)
    grad = jet_where(np.asarray(mask)[..., None], gx, gy)
    return Jet(val, grad.broadcast_to(val.shape + (n,)))


def mean_value(centre: Interval, jet: Jet, radius: np.ndarray) -> Interval:
    """``centre + sum_k grad[..., k] [-radius_k, radius_k]``, cut to the jet's
    own enclosure: the mean-value form over the box q_c + [-radius, radius].

    Args:
        centre: enclosure of f at the box's centre, shape S.
        jet: f's jet over the box (val and grad), shape S (grad S + (n,)).
        radius: the box's half-widths, (B, n) for S = (B, ...).
    """
    r = radius.reshape(radius.shape[:1] + (1,) * (len(centre.shape) - 1) + radius.shape[1:])
    spread = (jet.grad * Interval(-r, r)).sum(axis=-1)
    mv = centre + spread
    return Interval._raw(np.maximum(mv.lo, jet.val.lo), np.minimum(mv.hi, jet.val.hi))
