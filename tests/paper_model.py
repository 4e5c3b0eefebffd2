"""The seed paper's 2-link arm in closed form (eqs 14-17, Table I), written
independently of Pinocchio and of cdpm's cable layer, for tests to compare
against."""

from __future__ import annotations

import numpy as np

#: base anchors A_i of cables c1..c4 in the arm's plane [m]
ANCHORS = np.array([[0.0, 0.5], [0.0, 1.5], [0.0, -0.5], [0.0, -1.5]])
#: (link, point in the link frame [m]): Table I's offsets from each link's
#: centre of mass (0.5 m along the link)
ATTACH = [(1, (0.8, 0.1)), (2, (0.8, 0.1)), (1, (0.8, -0.1)), (2, (0.8, -0.1))]


def _rot(a):
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def _drot(a):
    return np.array([[-np.sin(a), -np.cos(a)], [np.cos(a), -np.sin(a)]])


def paper_L(q):
    """Cable Jacobian (4, 2): l_i = |B_i(q) - A_i|, row i = u_i^T dB_i/dq (eq 16)."""
    L = np.zeros((4, 2))
    for i, (link, p) in enumerate(ATTACH):
        p = np.array(p)
        if link == 1:
            B = _rot(q[0]) @ p
            dB = np.stack([_drot(q[0]) @ p, np.zeros(2)], axis=1)
        else:
            a = q[0] + q[1]
            B = _rot(q[0]) @ [1.0, 0.0] + _rot(a) @ p
            d1 = _drot(q[0]) @ [1.0, 0.0] + _drot(a) @ p
            dB = np.stack([d1, _drot(a) @ p], axis=1)
        u = (B - ANCHORS[i]) / np.linalg.norm(B - ANCHORS[i])
        L[i] = u @ dB
    return L


def paper_M(q):
    """Mass matrix (2, 2) [kg m^2] (eq 14: unit point masses at the link centres)."""
    c = np.cos(q[1])
    return np.array([[1.5 + c, 0.25 + 0.5 * c], [0.25 + 0.5 * c, 0.25]])


def paper_tip_x_gradient(q):
    """d/dq of the output tip x = cos q1 + cos(q1 + q2) (eq 17), shape (2,)."""
    s1, s12 = np.sin(q[0]), np.sin(q[0] + q[1])
    return np.array([-s1 - s12, -s12])
