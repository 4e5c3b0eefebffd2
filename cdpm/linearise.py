"""Linearisation of the cable robot dynamics at an equilibrium.

Dynamics (seed paper eq 11): ``M(q) q'' + C(q, q') + G(q) + w_ext = -L(q)^T f``.
At an equilibrium (q*, q' = 0, f*) the linearisation in the state
``x = (dq, dq')`` (tangent space, nv each) is (paper eqs 21-23)::

    A = [[0, I], [K, 0]],   B = [[0], [-M^-1 L^T]],   C = [[dh/dq, 0]]

with the stiffness block ``K = dq''/dq``. At zero tension and no gravity
(the paper's case) K = 0 and A is nilpotent.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cdpm.errors import InputError, ModelError, UnsupportedError

__all__ = ["Linearisation", "linearise", "state_names"]

#: A cable whose equilibrium tension is within this of its lower bound [N]
#: (relative to the largest tension scale) is treated as sitting on it.
BOUND_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Linearisation:
    """The linear system ``dx' = A dx + B du, dy = C dx`` at an equilibrium.

    Attributes:
        A: state matrix, shape (2 nv, 2 nv); state ``(dq, dq')`` in the tangent space.
        B: input matrix, shape (2 nv, m); input = change of cable tension [N].
        C: output matrix, shape (p, 2 nv).
        tension: equilibrium cable tensions f* [N], shape (m,).
        sign_constrained: True for cables at their lower tension bound
            (their input can only increase), shape (m,).
        q: configuration vector of the equilibrium, shape (nq,).
        mass_matrix: M(q*), shape (nv, nv).
        cable_jacobian: L(q*), shape (m, nv).
        output_jacobian: dh/dq at q*, shape (p, nv).
        stiffness: K = dq''/dq at the equilibrium, shape (nv, nv) [1/s^2].
        output: y* = h(q*), shape (p,).
        cable_names, output_names, state_names: labels of inputs, outputs, states.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    tension: np.ndarray
    sign_constrained: np.ndarray
    q: np.ndarray
    mass_matrix: np.ndarray
    cable_jacobian: np.ndarray
    output_jacobian: np.ndarray
    stiffness: np.ndarray
    output: np.ndarray
    cable_names: tuple[str, ...] = ()
    output_names: tuple[str, ...] = ()
    state_names: tuple[str, ...] = field(default=())

    @property
    def nilpotent(self) -> bool:
        """True when K = 0, so that A^2 = 0 (zero tension, no gravity)."""
        return not np.any(self.stiffness)

    def as_dict(self) -> dict:
        """JSON-serialisable content."""
        return {
            "q": self.q.tolist(),
            "A": self.A.tolist(),
            "B": self.B.tolist(),
            "C": self.C.tolist(),
            "tension": self.tension.tolist(),
            "sign_constrained": self.sign_constrained.tolist(),
            "output": self.output.tolist(),
            "cable_names": list(self.cable_names),
            "output_names": list(self.output_names),
            "state_names": list(self.state_names),
        }

    def __str__(self) -> str:
        with np.printoptions(precision=4, suppress=True, linewidth=100):
            return (
                f"Linearisation at q = {self.q}\n"
                f"A =\n{self.A}\nB =\n{self.B}\nC =\n{self.C}\n"
                f"tension f* = {self.tension} N\n"
                f"sign-constrained inputs: {self.sign_constrained}"
            )


def state_names(robot) -> tuple[str, ...]:
    """Names of the 2 nv states: each coordinate, then its rate (``name_dot``)."""
    coords = list(robot.coordinate_names)
    return tuple(coords + [f"{c}_dot" for c in coords])


def _validate_tension(robot, tension: Any) -> np.ndarray:
    try:
        f = np.array(tension, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"tension must be a vector of {robot.n_cables} numbers: {exc}") from exc
    if f.shape[0] != robot.n_cables:
        raise InputError(
            f"tension has {f.shape[0]} entries, expected one per cable "
            f"({robot.n_cables}: {', '.join(robot.cable_names)})"
        )
    if not np.all(np.isfinite(f)):
        raise InputError(f"tension has non-finite entries: {f}")
    low = f < robot.tension_min - BOUND_TOLERANCE
    high = f > robot.tension_max + BOUND_TOLERANCE
    if np.any(low | high):
        bad = [
            f"{robot.cable_names[i]}={f[i]:g} not in [{robot.tension_min[i]:g}, "
            f"{robot.tension_max[i]:g}]"
            for i in np.flatnonzero(low | high)
        ]
        raise InputError(f"tension outside the cable bounds: {'; '.join(bad)}")
    return f


def linearise(robot, q: Any, tension: Any = None) -> Linearisation:
    """Linearise the robot at the equilibrium (q, q' = 0, f).

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.
        q: configuration (nq,), natural coordinates (nv,), or a pose name.
        tension: equilibrium tensions f* [N], shape (m,); ``None`` uses zero
            tension (the seed paper's case).

    Returns:
        The :class:`Linearisation` (A, B, C, input cone, the matrices used).

    Raises:
        UnsupportedError: the equilibrium needs gravity, an external wrench
            or nonzero tension, which this version does not linearise.
        ModelError: the mass matrix is singular or a cable has zero length.
        InputError: bad q or tension.
    """
    kin = robot.kinematics(q)
    q = kin.q
    nv, m = robot.nv, robot.n_cables
    f = np.zeros(m) if tension is None else _validate_tension(robot, tension)

    gravity = robot.gravity_torque(q)
    if np.any(f != 0) or np.any(np.abs(gravity) > 0) or np.any(robot.external_wrench):
        raise UnsupportedError(
            "only zero-tension equilibria without gravity or external wrench are "
            "linearised (the seed paper's case); this pose has "
            + ("nonzero tension" if np.any(f) else "gravity or an external wrench")
            + ". Set gravity: [0, 0, 0] in the spec or pass tension=None"
        )

    M = robot.mass_matrix(q)
    L = kin.jacobian
    try:
        chol = np.linalg.cholesky(M)
    except np.linalg.LinAlgError as exc:
        raise ModelError(
            f"mass matrix is singular or not positive definite at q={q.tolist()}: "
            "check the URDF inertias (every moving joint needs mass or inertia beyond it)"
        ) from exc
    Minv_LT = np.linalg.solve(chol.T, np.linalg.solve(chol, L.T))
    stiffness = np.zeros((nv, nv))

    A = np.zeros((2 * nv, 2 * nv))
    A[:nv, nv:] = np.eye(nv)
    A[nv:, :nv] = stiffness
    B = np.zeros((2 * nv, m))
    B[nv:] = -Minv_LT
    C = np.zeros((robot.n_outputs, 2 * nv))
    C[:, :nv] = kin.output_jacobian
    scale = max(1.0, float(np.max(np.abs(robot.tension_min), initial=0.0)))
    sign_constrained = f <= robot.tension_min + BOUND_TOLERANCE * scale
    return Linearisation(
        A=A,
        B=B,
        C=C,
        tension=f,
        sign_constrained=sign_constrained,
        q=q.copy(),
        mass_matrix=M,
        cable_jacobian=L.copy(),
        output_jacobian=kin.output_jacobian.copy(),
        stiffness=stiffness,
        output=kin.output.copy(),
        cable_names=robot.cable_names,
        output_names=robot.output_names,
        state_names=state_names(robot),
    )
