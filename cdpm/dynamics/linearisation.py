"""Linearisation of the cable robot dynamics at an equilibrium.

Dynamics (seed paper eq 11, with the URDF's viscous joint damping D)::

    M(q) q'' + C(q, q') + G(q) + D q' + w_ext = -L(q)^T f

At an equilibrium (q*, q' = 0, f*) the linearisation in the state
``x = (dq, dq')`` (tangent space, nv each; ``q = pin.integrate(q*, dq)``)
is (paper eqs 21-23)::

    A = [[0, I], [K, K_v]],   B = [[0], [-M^-1 L^T]],   C = [[dh/dq, 0]]

with the stiffness block ``K = dq''/dq = -M^-1 (dG/dq + d(L^T f*)/dq)``
(gravity stiffness from Pinocchio's generalised gravity derivatives, cable stiffness
``sum_i f_i Hess(l_i)`` from :meth:`cdpm.model.robot.CableRobot.cable_stiffness`,
both analytic, in Pinocchio's local tangent convention) and the rate block
``K_v = dq''/dq' = -M^-1 D`` (Coriolis terms are quadratic in q' and vanish
at rest, so K_v = 0 without damping). At zero tension and no gravity (the
paper's case) K = 0 and A is nilpotent.

The equilibrium tension comes from :func:`cdpm.dynamics.equilibrium.equilibrium_tension`
(by default the spec's method, ``min_norm`` when it names none: zero
tension for the paper's model) or is given by the caller and checked.

:func:`linearise_batch` builds the systems of many poses at once from their
batch kinematics and equilibria; :func:`linearise` is that function on one
pose, so a map and the per-pose API get the same matrices.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.equilibrium import (
    EQUILIBRIUM_METHODS,
    EquilibriumResult,
    InfeasibleEquilibriumError,
    NotAnEquilibriumError,
    check_equilibrium,
    checked_tensions,
    equilibrium_tension,
)
from cdpm.dynamics.equilibrium.statics import input_signs
from cdpm.errors import InputError, MissingExtraError, ModelError
from cdpm.model.coordinates import displacement_names, velocity_names
from cdpm.numerics import MASS_COND_MAX, OUTPUT_JACOBIAN_ZERO_RTOL
from cdpm.printing import largest_magnitude, matrix_text, round_to_scale

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.kinematics import BatchKinematics
    from cdpm.model.robot import CableRobot

__all__ = [
    "Linearisation",
    "LinearisationBatch",
    "linearise",
    "linearise_batch",
    "mass_inverse",
    "input_cone_scale",
    "state_names",
    "EXPORT_FORMATS",
]

#: file formats :meth:`Linearisation.save` writes, by extension
EXPORT_FORMATS = {".npz": "npz", ".mat": "mat"}


@dataclass(frozen=True)
class Linearisation:
    """The linear system ``dx' = A dx + B du, dy = C dx`` at an equilibrium.

    Attributes:
        A: state matrix, shape (2 nv, 2 nv); state ``(dq, dq')`` in the
            tangent space (``q = pin.integrate(q*, dq)``).
        B: input matrix, shape (2 nv, m); input = change of cable tension [N].
        C: output matrix, shape (p, 2 nv): ``[J, 0]`` with J the output
            Jacobian (``output_jacobian`` with round-off entries zeroed).
            Each output's rate is in its unit per second (``output_units``
            of the robot); rows of rotation components are the frame's
            angular velocity about the world axes, the derivative of
            ``log3(R(q* + dq) R(q*)^T)`` (docs/outputs.md).
        tension: equilibrium cable tensions f* [N], shape (m,).
        sign_constrained: True for cables whose tension change has one sign:
            at their lower bound (slack; du >= 0) or, rarely, at their upper
            bound (du <= 0; see ``input_sign``), shape (m,). Cables strictly
            inside their bounds (taut) are free inputs.
        q: configuration vector of the equilibrium, shape (nq,).
        mass_matrix: M(q*), shape (nv, nv).
        cable_jacobian: L(q*), shape (m, nv).
        output_jacobian: dh/dq at q*, shape (p, nv) (rotation rows: world
            angular velocity rows, as in C).
        stiffness: K = dq''/dq at the equilibrium, shape (nv, nv) [1/s^2].
        output: y* = h(q*), shape (p,), each in its output's unit (metres,
            radians: a rotation component is one of the frame's world
            rotation vector log3(R), docs/outputs.md).
        cable_names, output_names, state_names: labels of inputs, outputs, states.
        rate_stiffness: K_v = dq''/dq' = -M^-1 D, shape (nv, nv) [1/s];
            zero unless the URDF gives joint damping.
        input_sign: +1 for cables at their lower bound (u >= 0), -1 at their
            upper bound (u <= 0), 0 for free inputs, shape (m,).
        equilibrium: the :class:`~cdpm.dynamics.equilibrium.EquilibriumResult` used.
        gravity_stiffness: dG/dq at q* (tangent space), shape (nv, nv).
        cable_stiffness: d(L^T f*)/dq = sum_i f_i Hess(l_i), shape (nv, nv).
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
    rate_stiffness: np.ndarray | None = None
    input_sign: np.ndarray | None = None
    equilibrium: EquilibriumResult | None = None
    gravity_stiffness: np.ndarray | None = None
    cable_stiffness: np.ndarray | None = None

    @property
    def nilpotent(self) -> bool:
        """True when K = 0 and K_v = 0, so that A^2 = 0 (zero tension, no
        gravity, no damping)."""
        rate = self.rate_stiffness
        return not np.any(self.stiffness) and (rate is None or not np.any(rate))

    @property
    def B_cone(self) -> np.ndarray:
        """B with the columns of cables at their upper bound negated (and of
        pinned cables, f_min = f_max, zeroed), so that every sign-constrained
        input of ``(A, B_cone)`` is u >= 0. Pass ``(A, B_cone, C,
        sign_constrained)`` to the analysis; equal to B unless a cable sits
        at its maximum tension."""
        if self.input_sign is None:
            return self.B.copy()
        eq = self.equilibrium
        if eq is not None and eq.tension_min.shape == self.input_sign.shape:
            pinned = eq.tension_min == eq.tension_max
        else:
            pinned = np.zeros(self.input_sign.shape, dtype=bool)
        return self.B * input_cone_scale(self.input_sign, pinned)

    def as_dict(self) -> dict:
        """JSON-serialisable content."""
        out = {
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
        if self.input_sign is not None:
            out["input_sign"] = self.input_sign.tolist()
        if self.equilibrium is not None:
            out["equilibrium"] = self.equilibrium.as_dict()
        return out

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The system as named arrays, for files and other tools.

        Returns:
            ``A`` (2 nv, 2 nv), ``B`` (2 nv, m) [per N], ``B_cone`` (2 nv, m),
            ``C`` (p, 2 nv), ``q`` (nq,), ``output`` y* (p,) [m],
            ``tension`` f* (m,) [N], ``sign_constrained`` (m,) bool,
            ``input_sign`` (m,) int (+1 u >= 0, -1 u <= 0, 0 free), and the
            names ``cable_names`` (m,), ``output_names`` (p,),
            ``state_names`` (2 nv,) as string arrays. New arrays (copies).
        """
        signs = self.input_sign
        if signs is None:
            signs = self.sign_constrained.astype(int)
        return {
            "A": self.A.copy(),
            "B": self.B.copy(),
            "B_cone": self.B_cone,
            "C": self.C.copy(),
            "q": self.q.copy(),
            "output": self.output.copy(),
            "tension": self.tension.copy(),
            "sign_constrained": self.sign_constrained.astype(bool),
            "input_sign": np.asarray(signs, dtype=np.int64).copy(),
            "cable_names": np.array(self.cable_names, dtype=str),
            "output_names": np.array(self.output_names, dtype=str),
            "state_names": np.array(self.state_names, dtype=str),
        }

    def save(self, path: str | Path) -> Path:
        """Write :meth:`to_arrays` to a file, its format by the extension:
        ``.npz`` (``numpy.savez``; the names are unicode arrays, so
        ``numpy.load`` needs no pickle) or ``.mat`` (``scipy.io.savemat``,
        MATLAB 5; the names are cell arrays of char, ``sign_constrained``
        is logical).

        Returns:
            The path written.

        Raises:
            InputError: the extension is not .npz or .mat.
        """
        path = Path(path)
        fmt = EXPORT_FORMATS.get(path.suffix.lower())
        if fmt is None:
            raise InputError(
                f"cannot write a linearisation to {path.name}: give a file ending in "
                f"{' or '.join(EXPORT_FORMATS)}"
            )
        arrays = self.to_arrays()
        if fmt == "npz":
            with path.open("wb") as handle:
                np.savez(handle, **arrays)
        else:
            # scipy: loaded on first use
            from scipy.io import savemat

            for name in ("cable_names", "output_names", "state_names"):
                arrays[name] = np.array(list(arrays[name]), dtype=object).reshape(-1, 1)
            savemat(path, arrays, do_compression=True, oned_as="column")
        return path

    def to_control(self, cone: bool = False):
        """The linearisation as a python-control state-space system
        ``dx' = A dx + B du, dy = C dx`` (D = 0), with the states, inputs and
        outputs named as here (inputs: changes of cable tension [N]).

        Args:
            cone: use ``B_cone`` (every sign-constrained input u >= 0)
                instead of B.

        Returns:
            ``control.StateSpace``.

        Raises:
            MissingExtraError: python-control is not installed
                (``pip install 'cdpm[control]'``).
        """
        try:
            # optional: cdpm[control]
            import control
        except ImportError as exc:
            raise MissingExtraError(
                "Linearisation.to_control needs python-control: pip install 'cdpm[control]'"
            ) from exc
        B = self.B_cone if cone else self.B
        D = np.zeros((self.C.shape[0], B.shape[1]))
        names = {
            "inputs": list(self.cable_names) or None,
            "outputs": list(self.output_names) or None,
            "states": list(self.state_names) or None,
        }
        return control.ss(self.A, B, self.C, D, **{k: v for k, v in names.items() if v})

    def __str__(self) -> str:
        q = round_to_scale(self.q, largest_magnitude(self.q))
        tension = round_to_scale(self.tension, largest_magnitude(self.tension))
        with np.printoptions(precision=6, suppress=True, linewidth=100):
            return (
                f"Linearisation at q = {q}\n"
                f"A =\n{matrix_text(self.A)}\nB =\n{matrix_text(self.B)}\n"
                f"C =\n{matrix_text(self.C)}\n"
                f"tension f* = {tension} N\n"
                f"sign-constrained inputs: {self.sign_constrained}"
            )


@dataclass(frozen=True)
class LinearisationBatch:
    """The linear systems of N poses (pose axis first); each pose's system
    is the :class:`Linearisation` of :func:`linearise` at it.

    Attributes:
        A: state matrices, shape (N, 2 nv, 2 nv).
        B: input matrices, shape (N, 2 nv, m) [per N of tension change].
        B_cone: B with the columns of cables at their upper bound negated
            and of pinned cables zeroed (every sign-constrained input u >= 0),
            shape (N, 2 nv, m) (the array B itself when no column changes).
        C: output matrices, shape (N, p, 2 nv).
        tension: equilibrium tensions f* [N], shape (N, m).
        input_sign: +1 at the lower bound, -1 at the upper one, 0 free, (N, m).
        stiffness: K = dq''/dq [1/s^2], shape (N, nv, nv).
        rate_stiffness: K_v = -M^-1 D [1/s], shape (N, nv, nv).
        gravity_stiffness: dG/dq (tangent space), shape (N, nv, nv).
        cable_stiffness: d(L^T f*)/dq = sum_i f_i Hess(l_i), shape (N, nv, nv).
    """

    A: np.ndarray
    B: np.ndarray
    B_cone: np.ndarray
    C: np.ndarray
    tension: np.ndarray
    input_sign: np.ndarray
    stiffness: np.ndarray
    rate_stiffness: np.ndarray
    gravity_stiffness: np.ndarray
    cable_stiffness: np.ndarray

    @property
    def sign_constrained(self) -> np.ndarray:
        """Cables on a bound (one-signed input), shape (N, m)."""
        return self.input_sign != 0


def output_jacobian_rounded(robot: CableRobot, jacobian: np.ndarray) -> np.ndarray:
    """dh/dq (..., p, nv) with round-off entries set to exactly 0.

    Round-off of forward kinematics (e.g. the tip of a folded arm on its
    shoulder, where dh/dq is 1e-16 while the arm is metres long) is not an
    output direction. The analysis only judges rows against each other, so
    a single round-off row would otherwise count as full output rank.

    An entry of output row k is round-off when it is at most
    OUTPUT_JACOBIAN_ZERO_RTOL times that row's scale
    (:attr:`cdpm.model.robot.CableRobot.output_scales`): the sum over the output's terms of
    ``|weight|`` times the robot's size [m] for terms in metres (positions,
    cable lengths, prismatic joints) or times 1 for terms in radians
    (rotations, revolute joints), i.e. the row's size per radian of joint
    motion. A rotation row, whose entries are of order 1, is so not judged
    against a length."""
    floor = OUTPUT_JACOBIAN_ZERO_RTOL * robot.output_scales
    return np.where(np.abs(jacobian) <= floor[:, None], 0.0, jacobian)


def input_cone_scale(input_sign: np.ndarray, pinned: np.ndarray) -> np.ndarray:
    """Column scales turning B into B_cone: -1 for cables at their upper
    bound (so their input u <= 0 becomes u >= 0), 0 for pinned cables
    (f_min = f_max: no input), else 1; shaped like ``input_sign`` (..., m)."""
    return np.where(input_sign < 0, -1.0, 1.0) * np.where(pinned, 0.0, 1.0)


def mass_inverse(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverses of symmetric positive semi-definite mass matrices.

    Args:
        M: mass matrices, shape (N, d, d).

    Returns:
        (M^-1 (N, d, d), regular (N,)): ``regular`` is False where the
        condition number reaches MASS_COND_MAX (inverse then meaningless);
        closed forms for d <= 2.
    """
    k, d, _ = M.shape
    if d == 1:
        regular = M[:, 0, 0] > 0
        with np.errstate(divide="ignore"):
            return 1.0 / M, regular
    if d == 2:
        a, b, c = M[:, 0, 0], M[:, 0, 1], M[:, 1, 1]
        half = 0.5 * (a + c)
        det = a * c - b * b
        root = np.sqrt(np.maximum(half * half - det, 0.0))
        regular = half - root > (half + root) / MASS_COND_MAX
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = np.moveaxis(np.array([[c, -b], [-b, a]]) / det, -1, 0)
        return inv, regular
    eig = np.linalg.eigvalsh(M) if k else np.zeros((0, d))
    regular = eig[:, 0] > eig[:, -1] / MASS_COND_MAX
    inv = np.full_like(M, np.nan)
    if regular.any():
        inv[regular] = np.linalg.inv(M[regular])
    return inv, regular


def linearise_batch(
    robot: CableRobot,
    kin: BatchKinematics,
    Minv: np.ndarray,
    tension: np.ndarray,
    input_sign: np.ndarray,
) -> LinearisationBatch:
    """Linearisations at N equilibria (module docstring: A, B, C).

    Args:
        robot: the robot.
        kin: batch kinematics with dynamics at the N poses (none with a
            zero-length segment).
        Minv: inverse mass matrices, shape (N, nv, nv) (:func:`mass_inverse`).
        tension: equilibrium tensions f* [N], shape (N, m).
        input_sign: +1 (cable at its lower bound), -1 (upper), 0 (free), (N, m).

    Returns:
        :class:`LinearisationBatch`.
    """
    # pinocchio: loaded on first use
    import pinocchio as pin

    nv, m, p, k = robot.nv, robot.n_cables, robot.n_outputs, len(kin)
    X = Minv @ np.swapaxes(kin.jacobian, 1, 2)  # M^-1 L^T, (k, nv, m)
    gravity_stiffness = np.zeros((k, nv, nv))
    if np.any(robot.gravity):
        model = robot.model
        data = model.createData()
        derivative = pin.computeGeneralizedGravityDerivatives
        for j in range(k):
            gravity_stiffness[j] = derivative(model, data, kin.qs[j])
    cable_stiffness = np.zeros((k, nv, nv))
    loaded = np.flatnonzero(np.any(tension != 0, axis=1))
    if loaded.size:
        cable_stiffness[loaded] = robot.cable_stiffness_batch(kin.take(loaded), tension[loaded])
    if gravity_stiffness.any() or loaded.size:
        stiffness = -(Minv @ (gravity_stiffness + cable_stiffness))
    else:
        stiffness = np.zeros((k, nv, nv))
    damping = robot.joint_damping
    rate = -(Minv * damping[None, None, :]) if np.any(damping) else np.zeros((k, nv, nv))
    A = np.zeros((k, 2 * nv, 2 * nv))
    A[:, :nv, nv:] = np.eye(nv)
    A[:, nv:, :nv] = stiffness
    A[:, nv:, nv:] = rate
    B = np.zeros((k, 2 * nv, m))
    B[:, nv:] = -X
    # input cone: cables on a bound are sign-constrained (u >= 0 at the
    # lower bound, u <= 0 at the upper one: B_cone negates those columns;
    # pinned cables, f_min = f_max, have no input)
    pinned = robot.tension_min == robot.tension_max
    scale = input_cone_scale(input_sign, pinned)
    B_cone = B if np.all(scale == 1.0) else B * scale[:, None, :]
    C = np.zeros((k, p, 2 * nv))
    C[:, :, :nv] = output_jacobian_rounded(robot, kin.output_jacobian)
    return LinearisationBatch(
        A=A,
        B=B,
        B_cone=B_cone,
        C=C,
        tension=tension,
        input_sign=input_sign,
        stiffness=stiffness,
        rate_stiffness=rate,
        gravity_stiffness=gravity_stiffness,
        cable_stiffness=cable_stiffness,
    )


def state_names(robot: CableRobot) -> tuple[str, ...]:
    """Names of the 2 nv states: the tangent displacement's components
    (:func:`cdpm.model.coordinates.displacement_names`: a coordinate's name,
    or ``joint.d_x`` ... ``joint.th_z`` for a free-flyer's body-frame
    translation and rotation), then the velocity's
    (:func:`cdpm.model.coordinates.velocity_names`: ``name_dot``, or
    ``joint.v_x`` ... ``joint.w_z``)."""
    return tuple(displacement_names(robot.model) + velocity_names(robot.model))


def _equilibrium(robot: CableRobot, q, tension, pretension) -> EquilibriumResult:
    """The equilibrium to linearise at: solved for (None or a method name)
    or checked (an array)."""
    if tension is None or isinstance(tension, str):
        eq = equilibrium_tension(robot, q, method=tension, pretension=pretension)
        if not eq.feasible:
            raise InfeasibleEquilibriumError(eq)
        return eq
    # the one rule for given tensions: round-off beyond a bound is on it,
    # farther is an InputError (as evaluate_poses and maps)
    eq = check_equilibrium(robot, q, checked_tensions(robot, tension))
    if not eq.feasible:
        raise NotAnEquilibriumError(eq, tuple(EQUILIBRIUM_METHODS))
    return eq


def linearise(
    robot: CableRobot, q: Any, tension: Any = None, pretension: float | None = None
) -> Linearisation:
    """Linearise the robot at the equilibrium (q, q' = 0, f*).

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: configuration (nq,), natural coordinates (nv,), or a pose name.
        tension: the equilibrium tension f*: ``None`` solves for it with the
            spec's method (``min_norm`` by default, which gives f* = 0 for
            the paper's model), a method name (``zero``, ``min_norm``,
            ``pretension``) solves with that method, an array (m,) [N] is
            checked against the bounds (the rule of
            :func:`~cdpm.dynamics.equilibrium.checked_tensions`, as maps
            check it: an entry beyond its bound by round-off is put on it)
            and the statics, and used.
        pretension: least tension [N] for the ``pretension`` method; None
            uses the spec's ``equilibrium.pretension``.

    Returns:
        The :class:`Linearisation` (A, B, C, input cone, the matrices used).

    Raises:
        InfeasibleEquilibriumError: no tension in bounds holds the pose
            (``.result`` has the residual).
        InputError: bad q, a tension array of the wrong length or outside
            the bounds; :class:`~cdpm.dynamics.equilibrium.NotAnEquilibriumError` (an
            InputError) for given tensions that do not hold the pose (the
            message gives the residual, ``.result`` the equilibrium check).
        ModelError: the mass matrix is singular or a cable has zero length.
    """
    kin = robot.kinematics(q)  # raises on a zero-length segment
    q = kin.q
    eq = _equilibrium(robot, q, tension, pretension)
    batch = robot.kinematics_batch(q[None], dynamics=True)
    M = batch.mass_matrix[0]
    Minv, regular = mass_inverse(batch.mass_matrix)
    if not regular[0]:
        raise ModelError(
            f"mass matrix is singular or not positive definite at q={q.tolist()}: "
            "check the URDF inertias (every moving joint needs mass or inertia beyond it)"
        )
    input_sign = input_signs(eq.at_lower_bound, eq.at_upper_bound)
    lin = linearise_batch(robot, batch, Minv, eq.tension[None], input_sign[None])
    f = eq.tension
    L = kin.jacobian
    return Linearisation(
        A=lin.A[0],
        B=lin.B[0],
        C=lin.C[0],
        tension=f.copy(),
        sign_constrained=input_sign != 0,
        q=q.copy(),
        mass_matrix=M,
        cable_jacobian=L.copy(),
        output_jacobian=kin.output_jacobian.copy(),
        stiffness=lin.stiffness[0],
        output=kin.output.copy(),
        cable_names=robot.cable_names,
        output_names=robot.output_names,
        state_names=state_names(robot),
        rate_stiffness=lin.rate_stiffness[0],
        input_sign=input_sign.astype(int),
        equilibrium=eq,
        gravity_stiffness=lin.gravity_stiffness[0],
        cable_stiffness=lin.cable_stiffness[0],
    )
