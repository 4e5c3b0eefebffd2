"""Map evaluation under load: gravity, external wrenches, pretension, damping.

The general counterpart of the nilpotent path of :mod:`cdpm.maps._evaluate`,
with everything but the POC decision batched over the chunk:

1. kinematics, M and G from :meth:`cdpm.robot.CableRobot.kinematics_batch`
   (one Pinocchio pass per pose);
2. equilibrium tensions by the spec's (or the map's) method for all poses
   at once (:func:`cdpm.maps._batch.min_norm_tensions`; the few poses it
   leaves undecided go through :func:`cdpm.equilibrium.equilibrium_tension`);
3. the linearisation of :func:`cdpm.linearise` assembled for all poses:
   ``A = [[0, I], [K, K_v]]``, ``B = [0; -M^-1 L^T]`` (as ``B_cone``),
   ``C = [C_q, 0]`` with ``K = -M^-1 (dG/dq + sum_i f_i Hess l_i)`` from
   Pinocchio's gravity derivatives and the robot's
   :meth:`~cdpm.robot.CableRobot.cable_stiffness_batch`, ``K_v = -M^-1 D``;
4. output controllability from the batched output Krylov matrix, positive
   controllability where the free (taut) inputs alone make the system
   controllable (poses near rank deficiency, and the others, are left to
   the analyser);
5. POC where the free (taut) inputs alone reach every output direction
   (the analyser's mixed-cone exit, from the batched Krylov rank of the
   free inputs) and the margins of those poses
   (:func:`cdpm.analysis.poc.poc_margins`: horizons and curve samples for
   all of them at once);
6. per pose, the analyser's POC decision and margin for the others (and
   Brammer's test where step 4 did not settle it).
"""

from __future__ import annotations

import numpy as np

from cdpm.errors import CdpmError
from cdpm.maps import _evaluate as ev

__all__ = ["evaluate_general"]

#: output Krylov matrices whose singular-value ratio exceeds this have full
#: row rank beyond doubt; the others are decided by the analyser
_RANK_RATIO = 1e-6


def _spectral_norms(LT: np.ndarray) -> np.ndarray:
    """Largest singular value of each (nv, m) matrix of LT (k, nv, m)."""
    if LT.shape[0] == 0 or 0 in LT.shape[1:]:
        return np.zeros(LT.shape[0])
    return np.linalg.svd(LT, compute_uv=False)[:, 0]


def _statics_tolerance(LT, load, f) -> np.ndarray:
    """The statics tolerance of :mod:`cdpm.equilibrium`, per pose."""
    from cdpm.equilibrium import STATICS_RTOL

    scale = np.maximum(1.0, np.linalg.norm(load, axis=1))
    scale = np.maximum(scale, _spectral_norms(LT) * np.linalg.norm(f, axis=1))
    return STATICS_RTOL * scale


def _holds(LT, load, f) -> np.ndarray:
    """Do tensions f (k, m) hold the poses (statics within tolerance)?"""
    residual = np.linalg.norm((LT @ f[..., None])[..., 0] - load, axis=1)
    return residual <= _statics_tolerance(LT, load, f)


def equilibria(robot, qs, LT, load, setting):
    """Equilibrium tensions of poses qs (k, nq) with L^T (k, nv, m) and load
    -G - w_ext (k, nv) for a tension setting (method name or tensions).

    Returns:
        (f (k, m), feasible (k,)); equal to
        :func:`cdpm.equilibrium.equilibrium_tension` (or, for given
        tensions, :func:`cdpm.equilibrium.check_equilibrium`) pose by pose.
    """
    from cdpm.equilibrium import equilibrium_tension
    from cdpm.maps._batch import min_norm_tensions

    k, m = LT.shape[0], LT.shape[2]
    fmin, fmax = robot.tension_min, robot.tension_max
    if not isinstance(setting, str):  # given tensions (within the bounds)
        f = np.tile(np.asarray(setting, dtype=float), (k, 1))
        return f, _holds(LT, load, f)
    if setting == "zero":
        f = np.zeros((k, m))
        return f, _holds(LT, load, f) & bool(np.all(fmin <= 0))
    if setting == "min_norm":
        lower = fmin.copy()
    else:
        pretension = float(getattr(robot.spec, "pretension", 0.0) or 0.0)
        lower = np.maximum(fmin, pretension)
    if np.any(lower > fmax):
        return np.tile(np.minimum(lower, fmax), (k, 1)), np.zeros(k, dtype=bool)
    f = np.tile(lower, (k, 1))
    feasible = _holds(LT, load, f)  # the box's least-norm point holds the pose
    rest = np.flatnonzero(~feasible)
    if rest.size:
        f_rest, solved, infeasible = min_norm_tensions(LT[rest], load[rest], lower, fmax)
        f[rest] = f_rest
        feasible[rest] = solved & _holds(LT[rest], load[rest], f_rest)
        for i in rest[~solved & ~infeasible]:
            eq = equilibrium_tension(robot, qs[i], method=setting)
            f[i], feasible[i] = eq.tension, eq.feasible
    return f, feasible


_STIFFNESS_KEYS = ("point_jacobians", "segment_units", "segment_lengths", "spatial_jacobian")


def _linear_systems(robot, qs, kin, idx, f, Minv):
    """Pose-first (A, B_cone, C, mask) of the linearisations at poses idx."""
    import pinocchio as pin

    from cdpm.equilibrium import STATICS_RTOL

    nv, m, p, k = robot.nv, robot.n_cables, robot.n_outputs, idx.size
    L = kin["jacobian"][idx]  # (k, m, nv)
    Minv = np.moveaxis(Minv, -1, 0)  # (k, nv, nv)
    X = Minv @ np.swapaxes(L, 1, 2)  # M^-1 L^T, (k, nv, m)
    # d(G + L^T f)/dq at fixed f: Pinocchio's gravity derivatives and the
    # cables' stiffness sum_i f_i Hess l_i
    load_stiffness = np.zeros((k, nv, nv))
    if np.any(robot.gravity):
        model = robot.model
        data = model.createData()
        derivative = pin.computeGeneralizedGravityDerivatives
        for j, i in enumerate(idx):
            load_stiffness[j] = derivative(model, data, qs[i])
    if np.any(f):
        sub = {key: kin[key][idx] for key in _STIFFNESS_KEYS}
        load_stiffness += robot.cable_stiffness_batch(sub, f)
    A = np.zeros((k, 2 * nv, 2 * nv))
    A[:, :nv, nv:] = np.eye(nv)
    A[:, nv:, :nv] = -(Minv @ load_stiffness)
    damping = robot.joint_damping
    if np.any(damping):
        A[:, nv:, nv:] = -(Minv * damping[None, None, :])
    # input cone: cables on a bound are sign-constrained (u >= 0 at the
    # lower bound, u <= 0 at the upper one: B_cone negates those columns;
    # pinned cables, f_min = f_max, have no input)
    fmin, fmax = robot.tension_min, robot.tension_max
    tol = STATICS_RTOL * np.maximum(1.0, np.abs(f))
    at_lower = f <= fmin + tol
    at_upper = np.isfinite(fmax) & (f >= fmax - tol) & ~at_lower
    scale = np.where(at_upper, -1.0, 1.0) * np.where(fmin == fmax, 0.0, 1.0)
    B = np.zeros((k, 2 * nv, m))
    B[:, nv:] = -X * scale[:, None, :]
    C = np.zeros((k, p, 2 * nv))
    C[:, :, :nv] = kin["output_jacobian"][idx]
    return A, B, C, at_lower | at_upper


def _full_rank(S: np.ndarray) -> np.ndarray:
    """Rows of each (r, c) matrix of S (k, r, c) independent beyond doubt:
    columns scaled to unit length (negligible ones dropped), singular-value
    ratio above _RANK_RATIO."""
    norms = np.linalg.norm(S, axis=1)
    keep = norms > 1e-12 * norms.max(axis=1, keepdims=True)
    S = np.where(keep[:, None, :], S / np.where(keep, norms, 1.0)[:, None, :], 0.0)
    sv = np.linalg.svd(S, compute_uv=False)
    return sv[:, -1] > _RANK_RATIO * sv[:, 0]


def _free_controllable(A, B, mask):
    """YES where the free (taut) inputs alone make (A, B) controllable beyond
    doubt, else NOT_ANALYSED. Then no real left eigenvector v of A has
    v^T B_free = 0, so Brammer's obstruction cannot exist: (A, B) is
    positively controllable whatever the sign-constrained inputs do."""
    k, n, _ = A.shape
    codes = np.full(k, ev.NOT_ANALYSED, dtype=np.int8)
    if k == 0:
        return codes
    blocks, W = [], B * ~mask[:, None, :]
    for _ in range(n):
        blocks.append(W)
        W = A @ W
    codes[_full_rank(np.concatenate(blocks, axis=2))] = ev.YES
    return codes


def _output_controllable(A, B, C):
    """YES where rank [CB, CAB, ..., CA^{n-1}B] = p beyond doubt (unit
    columns, singular-value ratio above _RANK_RATIO), else NOT_ANALYSED.
    With B restricted to the free inputs this is the analyser's mixed-cone
    exit: those inputs alone reach every output direction, so POC holds."""
    k, p, n = C.shape
    codes = np.full(k, ev.NOT_ANALYSED, dtype=np.int8)
    if p == 0 or k == 0:
        codes[:] = ev.YES
        return codes
    blocks, W = [], B
    for _ in range(n):
        blocks.append(C @ W)
        W = A @ W
    codes[_full_rank(np.concatenate(blocks, axis=2))] = ev.YES  # (k, p, n m)
    return codes


def evaluate_general(robot, qs: np.ndarray, kin: dict, setting, margin: bool = True) -> dict:
    """Every map quantity at poses qs (N, nq) whose batch kinematics (with
    dynamics) are ``kin``, under the tension setting ``setting``; without
    ``margin`` the POC margin stays NaN. Poses whose free (taut) inputs
    reach every output direction are decided YES without the per-pose
    analyser (their margins computed together)."""
    from cdpm.analysis.brammer import _positive_controllability
    from cdpm.analysis.poc import _poc, poc_margins

    out, ok = ev.prelude(robot, kin, qs.shape[0])
    LT = np.swapaxes(kin["jacobian"][ok], 1, 2)  # (k, nv, m)
    load = -kin["gravity"][ok] - robot.external_wrench
    f, feasible = equilibria(robot, qs[ok], LT, load, setting)
    if setting == "min_norm":
        static = feasible
    else:
        static = equilibria(robot, qs[ok], LT, load, "min_norm")[1]
    out["static_feasible"][ok] = np.where(static, ev.YES, ev.NO)
    Minv, regular = ev._spd_inverse(np.moveaxis(kin["mass_matrix"][ok], 0, -1))
    out["status"][ok[~regular]] = ev.STATUS_CODES["singular_mass_matrix"]
    out["status"][ok[regular & ~feasible]] = ev.STATUS_CODES["no_equilibrium"]
    use = regular & feasible
    idx, f = ok[use], f[use]
    if idx.size == 0:
        return out
    out["tension_min"][idx] = f.min(axis=1) if f.shape[1] else 0.0
    out["tension_max"][idx] = f.max(axis=1) if f.shape[1] else 0.0
    A, B, C, mask = _linear_systems(robot, qs, kin, idx, f, Minv[..., use])
    pc = _free_controllable(A, B, mask)
    # the analyser's mixed-cone exit, batched: the free (taut) inputs alone
    # reach every output direction, so POC holds (and output controllability)
    mixed_yes = _output_controllable(A, B * ~mask[:, None, :], C) == ev.YES
    out["poc"][idx[mixed_yes]] = ev.YES
    oc = np.full(idx.size, ev.YES, dtype=np.int8)
    rest = ~mixed_yes
    oc[rest] = _output_controllable(A[rest], B[rest], C[rest])
    if margin and C.shape[1]:
        out["poc_margin"][idx[mixed_yes]] = poc_margins(
            A[mixed_yes], B[mixed_yes], C[mixed_yes], mask[mixed_yes], True
        )
    status = out["status"]
    for j, i in enumerate(idx):
        try:
            if not mixed_yes[j]:
                res = _poc(A[j], B[j], C[j], mask[j])
                out["poc"][i] = ev._code(res.verdict)
                if margin:
                    out["poc_margin"][i] = float(res.margin)
                if oc[j] == ev.NOT_ANALYSED:
                    oc[j] = ev.YES if res.output_controllable else ev.NO
            if pc[j] == ev.NOT_ANALYSED:
                pc[j] = ev._code(_positive_controllability(A[j], B[j], mask[j]).verdict)
            out["positive_controllable"][i] = pc[j]
        except (CdpmError, np.linalg.LinAlgError):
            status[i] = ev.STATUS_CODES["analysis_failed"]
            out["poc"][i] = out["positive_controllable"][i] = ev.NOT_ANALYSED
            out["poc_margin"][i] = np.nan
    failed = status[idx] == ev.STATUS_CODES["analysis_failed"]
    out["output_controllable"][idx] = np.where(failed, ev.NOT_ANALYSED, oc)
    return out
