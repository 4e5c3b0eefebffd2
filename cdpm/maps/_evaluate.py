"""Evaluate every map quantity at a batch of poses.

:func:`evaluate_poses` is what one map chunk runs. Both paths start from
the robot's batched Pinocchio pass (:meth:`cdpm.robot.CableRobot.kinematics_batch`:
L, outputs, M and G of the whole chunk) and give the same verdicts as the
per-pose public API (:func:`cdpm.linearise`, then
:func:`cdpm.analysis.positive_output_controllability` and friends):

- ``nilpotent`` (zero tension, no gravity, no external wrench: the seed
  paper's case, A^2 = 0): the exact tests vectorised across poses. With
  ``C = [Cq, 0]`` and ``B = [0; -M^-1 L^T]``, ``CB = 0`` and
  ``C e^{At} B = t CAB`` with ``CAB = -Cq M^-1 L^T``, so POC is a sign test
  (p = 1) or an angular-gap test (p = 2) on the columns of CAB (THEORY.md
  section 3), the same decisions and tolerances as the analyser's
  nilpotent path. Positive (Brammer) controllability reduces to the
  columns of ``-M^-1 L^T`` positively spanning R^nv, wrench closure to
  those of ``-L^T``. Poses whose numbers fall within a small band of a
  decision threshold, and every decision the vectorised code does not
  cover (p >= 3, nv >= 3), are handed to the public analyser, so the map
  never disagrees with it because of a different rounding.
- ``general`` (gravity, loads, pretension, damping):
  :mod:`cdpm.maps._general`, batched equilibria and linearisations, then
  the analyser's decision per pose.

Degenerate poses never raise: they get a ``status`` code and the verdicts
``NOT_ANALYSED``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = [
    "VERDICT_CODES",
    "STATUS_CODES",
    "evaluate_poses",
    "resolve_tension",
]

#: verdict codes stored in maps (int8) and their meanings
VERDICT_CODES = {"yes": 1, "no": 0, "marginal": 2, "not_analysed": -1}
#: status codes stored in maps (int8) and their meanings
STATUS_CODES = {
    "pending": -1,
    "ok": 0,
    "zero_length_cable": 1,
    "singular_mass_matrix": 2,
    "no_equilibrium": 3,
    "analysis_failed": 4,
}
YES, NO, MARGINAL, NOT_ANALYSED = 1, 0, 2, -1

#: a segment shorter than this [m] has no direction (as in cdpm.robot)
MIN_SEGMENT_LENGTH = 1e-9
#: mass matrices with condition number above this are flagged singular
MASS_COND_MAX = 1e12
#: the analyser's angle-like span tolerance and zero-column threshold
_SPAN_TOL = 1e-9
_ZERO_RTOL = 1e-11

FLOAT_FIELDS = ("poc_margin", "tension_min", "tension_max")
CODE_FIELDS = (
    "poc",
    "output_controllable",
    "positive_controllable",
    "wrench_closure",
    "static_feasible",
)


def resolve_tension(robot, tension: Any) -> str | list[float]:
    """The equilibrium tension setting as plain data for provenance.

    ``None`` takes the spec's default method; a string names a method; a
    vector gives the tensions [N] (one per cable).
    """
    from cdpm.errors import InputError

    if tension is None:
        return str(robot.spec.equilibrium_method)
    if isinstance(tension, str):
        return tension
    f = np.asarray(tension, dtype=float).reshape(-1)
    if f.shape != (robot.n_cables,) or not np.all(np.isfinite(f)):
        raise InputError(
            f"tension must be a method name or {robot.n_cables} finite tensions [N] "
            f"(cables {', '.join(robot.cable_names)}), got {tension!r}"
        )
    outside = (f < robot.tension_min) | (f > robot.tension_max)
    if outside.any():
        bad = [
            f"{robot.cable_names[i]}={f[i]:g} not in [{robot.tension_min[i]:g}, "
            f"{robot.tension_max[i]:g}]"
            for i in np.flatnonzero(outside)
        ]
        raise InputError(
            f"tension outside the cable bounds: {'; '.join(bad)}; give tensions within the "
            "spec's tension_min/tension_max or a method name (zero, min_norm, pretension)"
        )
    return [float(x) for x in f]


def _zero_equilibrium(robot, setting) -> bool:
    """True when the equilibrium is f* = 0 at every pose with A^2 = 0: no
    gravity, external load or joint damping, every cable allowed to be
    slack (f_min = 0) and a method (or given tension) that then picks 0."""
    if np.any(robot.gravity) or np.any(robot.external_wrench):
        return False
    if np.any(getattr(robot, "joint_damping", 0.0)):
        return False
    if np.any(robot.tension_min != 0) or np.any(robot.tension_max <= 0):
        return False
    if isinstance(setting, str):
        return setting in ("zero", "min_norm")
    return not any(setting)


def _empty(n: int, p: int) -> dict[str, np.ndarray]:
    out = {name: np.full(n, NOT_ANALYSED, dtype=np.int8) for name in CODE_FIELDS}
    for name in FLOAT_FIELDS:
        out[name] = np.full(n, np.nan)
    out["y"] = np.full((n, p), np.nan)
    out["output_frame_position"] = np.full((n, 3), np.nan)
    out["status"] = np.full(n, STATUS_CODES["ok"], dtype=np.int8)
    return out


def _code(verdict) -> int:
    return {"yes": YES, "no": NO, "marginal": MARGINAL}[verdict.value]


def evaluate_poses(robot, natural: np.ndarray, tension: Any = None, *, margin: bool = True) -> dict:
    """Every map quantity at the poses ``natural`` (N, nv natural coordinates).

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.
        natural: poses, shape (N, nv).
        tension: equilibrium tension setting (see :func:`resolve_tension`).
        margin: compute ``poc_margin`` (else NaN; see
            :func:`cdpm.workspace_map`).

    Returns:
        dict of arrays with leading dimension N: the ``CODE_FIELDS`` (int8),
        the ``FLOAT_FIELDS``, ``y`` (N, p), ``output_frame_position`` (N, 3)
        and ``status`` (int8).
    """
    from cdpm.maps._batch import configurations

    natural = np.asarray(natural, dtype=float).reshape(-1, robot.nv)
    setting = resolve_tension(robot, tension)
    qs = configurations(robot, natural)
    kin = robot.kinematics_batch(qs, dynamics=True)
    if _zero_equilibrium(robot, setting):
        out = _evaluate_nilpotent(robot, kin, natural.shape[0])
        if not margin:
            out["poc_margin"][:] = np.nan
        return out
    from cdpm.maps._general import evaluate_general

    return evaluate_general(robot, qs, kin, setting, margin=margin)


def _pose_last(a: np.ndarray) -> np.ndarray:
    """A batch-first array of :meth:`~cdpm.robot.CableRobot.kinematics_batch`
    with the batch axis moved last (a view, contiguous for its arrays)."""
    return np.moveaxis(a, 0, -1)


# --------------------------------------------------------------------------
# nilpotent path


def prelude(robot, kin: dict, n: int) -> tuple[dict, np.ndarray]:
    """The output arrays with what every path fills alike: outputs, the
    zero-length cable flag and wrench closure. Returns (arrays, indices of
    the poses whose cables are all well defined)."""
    out = _empty(n, robot.n_outputs)
    out["y"][:] = kin["output"]
    _frame_positions(robot, kin, out)
    status = out["status"]
    seg_min = kin["segment_lengths"].min(axis=1, initial=np.inf)
    status[seg_min < MIN_SEGMENT_LENGTH] = STATUS_CODES["zero_length_cable"]
    ok = np.flatnonzero(status == 0)
    # wrench closure: the analyser tests the same vectors (round-off only)
    L = _pose_last(kin["jacobian"])[..., ok]  # (m, nv, k)
    wc, todo_wc = _span_codes(-np.swapaxes(L, 0, 1), _WRENCH_DEFER)
    for i in np.flatnonzero(todo_wc):
        wc[i] = _public_wrench(L[..., i])
    out["wrench_closure"][ok] = wc
    return out, ok


def _evaluate_nilpotent(robot, kin: dict, n: int) -> dict:
    # arrays keep the pose axis last from here
    out, ok = prelude(robot, kin, n)
    # without any load f* = 0 holds every pose, within the bounds (f_min = 0)
    out["tension_min"][ok] = 0.0
    out["tension_max"][ok] = 0.0
    out["static_feasible"][ok] = YES
    status = out["status"]
    M = _pose_last(kin["mass_matrix"])[..., ok]
    Minv, regular = _spd_inverse(M)
    status[ok[~regular]] = STATUS_CODES["singular_mass_matrix"]
    ok, M, Minv = ok[regular], M[..., regular], Minv[..., regular]
    if ok.size == 0:
        return out
    L = _pose_last(kin["jacobian"])[..., ok]  # (m, nv, k)
    Cq = _pose_last(kin["output_jacobian"])[..., ok]  # (p, nv, k)
    X = _times_transpose(Minv, L)  # M^-1 L^T, (nv, m, k)
    CAB = -_times(Cq, X)  # (p, m, k)

    poc, margin, todo = _nilpotent_poc(CAB)
    oc, todo_oc = _output_rank_full(CAB, Cq, X)
    todo |= todo_oc
    # Brammer's test sees a linear image of -M^-1 L^T
    pc, todo_pc = _span_codes(-X, _BRAMMER_DEFER)
    todo |= todo_pc
    for i in np.flatnonzero(todo):
        res = _public_nilpotent(M[..., i], L[..., i], Cq[..., i])
        poc[i], margin[i], oc[i], pc[i] = res
    out["poc"][ok] = poc
    out["poc_margin"][ok] = margin
    out["output_controllable"][ok] = oc
    out["positive_controllable"][ok] = pc
    return out


def _times(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched product a b of (r, s, k) and (s, t, k) arrays, pose axis last."""
    out = a[:, 0, None] * b[0]
    for j in range(1, a.shape[1]):
        out += a[:, j, None] * b[j]
    return out


def _times_transpose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched product a b^T of (r, s, k) and (t, s, k) arrays, pose axis last."""
    return _times(a, np.swapaxes(b, 0, 1))


def _frame_positions(robot, kin: dict, out: dict) -> None:
    """World position of the first output's frame (its tracked point)."""
    if robot.n_outputs:  # tracked points: every route point, then the outputs
        first = robot.route_point_slices[-1].stop if robot.route_point_slices else 0
        out["output_frame_position"][:] = kin["point_positions"][:, first]


def _spd_inverse(M: np.ndarray):
    """Inverses of symmetric positive semi-definite matrices M (d, d, k) and
    a mask of the regular ones (condition number below MASS_COND_MAX);
    closed forms for d <= 2."""
    d, _, k = M.shape
    if d == 1:
        regular = M[0, 0] > 0
        with np.errstate(divide="ignore"):
            return 1.0 / M, regular
    if d == 2:
        a, b, c = M[0, 0], M[0, 1], M[1, 1]
        half = 0.5 * (a + c)
        det = a * c - b * b
        root = np.sqrt(np.maximum(half * half - det, 0.0))
        lo, hi = half - root, half + root
        regular = lo > hi / MASS_COND_MAX
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = np.array([[c, -b], [-b, a]]) / det
        return inv, regular
    Mt = np.moveaxis(M, -1, 0)
    eig = np.linalg.eigvalsh(Mt)
    regular = eig[:, 0] > eig[:, -1] / MASS_COND_MAX
    inv = np.full_like(Mt, np.nan)
    if regular.any():
        inv[regular] = np.linalg.inv(Mt[regular])
    return np.moveaxis(inv, 0, -1), regular


def _nilpotent_poc(CAB: np.ndarray):
    """POC codes, margins and a 'defer' mask from CAB (p, m, k) (CB = 0),
    mirroring the analyser's nilpotent path and margin."""
    p, m, k = CAB.shape
    codes = np.full(k, NO, dtype=np.int8)
    margin = np.zeros(k)
    todo = np.zeros(k, dtype=bool)
    if p == 1:
        x = CAB[0]  # (m, k)
        big = np.abs(x).max(axis=0)
        thr = 1e-11 * big
        yes = np.any(x > thr, axis=0) & np.any(x < -thr, axis=0) & (big > 0)
        codes[yes] = YES
        margin[yes] = np.minimum(x.max(axis=0), -x.min(axis=0))[yes]
        # round-off differs from the analyser's by ~1e-16 |x|: only values
        # close to its threshold 1e-11 |x| could be decided differently
        todo |= np.any(np.abs(np.abs(x) - thr) <= 0.5 * thr, axis=0) & (big > 0)
        return codes, margin, todo
    if p == 2:
        gap, near = _max_angular_gap(CAB)
        yes = gap < math.pi - _SPAN_TOL
        codes[yes] = YES
        todo |= near | (np.abs(gap - (math.pi - _SPAN_TOL)) <= 1e-11)
        margin[yes] = _inradius_2d(CAB[..., yes])
        return codes, margin, todo
    todo[:] = True
    return codes, margin, todo


def _max_angular_gap(S: np.ndarray):
    """Largest angular gap between the nonzero columns of S (2, m, k), as the
    analyser's angular test computes it (sorted angles), and a mask of poses
    with a column near its zero threshold.

    The gap after each direction is the smallest positive angle to another
    one (2 pi for itself or an exact duplicate); their maximum equals the
    largest gap between sorted angles, without sorting m angles per pose.
    """
    norms = np.sqrt(S[0] ** 2 + S[1] ** 2)  # (m, k)
    m = norms.shape[0]
    big = norms.max(axis=0)
    zero = _ZERO_RTOL * big
    keep = norms > zero
    near = np.any(np.abs(norms - zero) <= 0.5 * zero, axis=0)
    theta = np.arctan2(S[1], S[0])
    two_pi = 2 * math.pi
    gap = np.full(norms.shape[1], -np.inf)
    for i in range(m):
        after = np.full(norms.shape[1], two_pi)
        for j in range(m):
            if j != i:
                d = np.mod(theta[j] - theta[i], two_pi)
                d = np.where(keep[j] & (d > 0), d, two_pi)
                np.minimum(after, d, out=after)
        gap = np.where(keep[i], np.maximum(gap, after), gap)
    gap[~keep.any(axis=0)] = two_pi
    return gap, near


def _inradius_2d(S: np.ndarray) -> np.ndarray:
    """min_{|v|=1} max_j v.s_j for S (2, m, k) whose columns positively span
    R^2: the minimum of the support function sits at a normal of a pair of
    columns, so evaluating it at every pair's normals is exact."""
    _, m, k = S.shape
    if k == 0:
        return np.zeros(0)
    i, j = np.triu_indices(m, 1)
    d = S[:, j] - S[:, i]  # (2, pairs, k)
    length = np.sqrt(d[0] ** 2 + d[1] ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = np.array([d[1], -d[0]]) / length
    cand = np.concatenate([normal, -normal], axis=1)  # (2, candidates, k)
    support = (cand[0][:, None] * S[0][None] + cand[1][:, None] * S[1][None]).max(axis=1)
    support = np.where(np.isfinite(support), support, np.inf)
    return np.maximum(support.min(axis=0), 0.0)


def _output_rank_full(CAB: np.ndarray, Cq: np.ndarray, X: np.ndarray):
    """Output controllability codes (rank CAB = p, as CB = 0) and a defer
    mask for nearly rank-deficient poses (the analyser decides at 1e-10 in
    its own scaling)."""
    p, m, k = CAB.shape
    rows = np.sqrt((CAB**2).sum(axis=1))  # (p, k)
    scale = np.sqrt((Cq**2).sum(axis=1)) * np.sqrt((X**2).sum(axis=(0, 1)))
    rel = rows / np.where(scale > 0, scale, 1.0)
    if p == 1:
        ratio = rel[0]
    elif p == 2:
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = CAB / rows[:, None, :]
        cos = np.abs((unit[0] * unit[1]).sum(axis=0))
        ratio = np.sqrt(np.maximum(1.0 - cos, 0.0) / (1.0 + cos))
        ratio = np.where(np.isfinite(ratio), np.minimum(ratio, rel.min(axis=0)), 0.0)
    else:
        s = np.linalg.svd(
            np.moveaxis(CAB / np.maximum(rows, 1e-300)[:, None], -1, 0), compute_uv=False
        )
        ratio = np.minimum(s[:, -1] / np.maximum(s[:, 0], 1e-300), rel.min(axis=0))
    full = ratio > 1e-6
    defer = ~full & (ratio > 1e-14)
    return np.where(full, YES, NO).astype(np.int8), defer


def _span_codes(S: np.ndarray, defer: tuple[float, float]):
    """Do the columns of S (d, m, k) positively span R^d (the analyser's
    angular test, tolerance 1e-9)? Returns codes and a mask of poses to
    defer to the analyser: those whose angular deficit ``pi - gap`` (d = 2),
    or smallest nonzero relative entry (d = 1), lies in ``defer = (lo, hi)``.
    d >= 3 always defers."""
    d, m, k = S.shape
    codes = np.full(k, NO, dtype=np.int8)
    todo = np.zeros(k, dtype=bool)
    lo, hi = defer
    if d == 1:
        x = S[0]  # (m, k)
        scale = np.abs(x).max(axis=0)
        yes = np.any(x > _SPAN_TOL * scale, axis=0) & np.any(x < -_SPAN_TOL * scale, axis=0)
        codes[yes] = YES
        rel = np.abs(x) / np.where(scale > 0, scale, 1.0)
        todo |= np.any((rel > 0) & (rel >= lo) & (rel <= hi), axis=0)
    elif d == 2:
        gap, near = _max_angular_gap(S)
        codes[gap < math.pi - _SPAN_TOL] = YES
        deficit = math.pi - gap
        todo |= near | ((deficit >= lo) & (deficit <= hi))
    else:
        todo[:] = True
    return codes, todo


#: defer bands of :func:`_span_codes`: wrench closure tests the analyser's
#: own vectors (differences are round-off, ~1e-16), Brammer's test sees a
#: linear image of -M^-1 L^T that scales small angular deficits by up to the
#: square of its condition number (exact opposites stay exact)
_WRENCH_DEFER = (_SPAN_TOL - 1e-11, _SPAN_TOL + 1e-11)
_BRAMMER_DEFER = (1e-12, 1e-5)


def _nilpotent_system(M, L, Cq):
    """(A, B, C, mask) exactly as cdpm.linearise builds them at zero tension."""
    nv, m, p = M.shape[0], L.shape[0], Cq.shape[0]
    A = np.zeros((2 * nv, 2 * nv))
    A[:nv, nv:] = np.eye(nv)
    B = np.zeros((2 * nv, m))
    chol = np.linalg.cholesky(M)
    B[nv:] = -np.linalg.solve(chol.T, np.linalg.solve(chol, L.T))
    C = np.zeros((p, 2 * nv))
    C[:, :nv] = Cq
    return A, B, C, np.ones(m, dtype=bool)


def _public_nilpotent(M, L, Cq):
    """(poc code, margin, output-controllable code, Brammer code) of one pose
    from the public analyser."""
    return _analyse(*_nilpotent_system(M, L, Cq))


def _analyse(A, B, C, mask):
    from cdpm.analysis.brammer import _positive_controllability
    from cdpm.analysis.poc import _poc

    res = _poc(A, B, C, mask)
    brammer = _positive_controllability(A, B, mask)
    return (
        _code(res.verdict),
        float(res.margin),
        YES if res.output_controllable else NO,
        _code(brammer.verdict),
    )


def _public_wrench(L) -> int:
    from cdpm.analysis import wrench_closure

    return _code(wrench_closure(L).verdict)
