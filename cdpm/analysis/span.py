"""Positive spanning of a finite set of vectors (and wrench closure).

A finite set S = {s_1, ..., s_k} of R^p positively spans R^p iff its conic
hull is R^p, iff rank S = p and some strictly positive w has S w = 0, iff no
nonzero v has v^T s_i <= 0 for all i (a separating vector).

Decision paths (reported in ``SpanResult.method``):

- ``"sign"`` (p = 1): a positive and a negative entry;
- ``"angular"`` (p = 2): the largest angular gap between consecutive
  directions is below pi; the certificate is three directions whose cross
  products are the weights (those through the first direction, else the
  three that pass the re-check by the widest margin);
- ``"nnls"`` (p >= 3): rank p and ``-S 1`` in cone(S), one non-negative
  least-squares solve (``-S 1 = S mu``, mu >= 0 gives w = 1 + mu > 0; the
  NNLS residual otherwise gives a separating vector);
- ``"lp"``: a HiGHS LP, only when the NNLS answer does not re-check (YES
  weights it leaves at 0 are completed by one NNLS);
- ``"rank"``: rank < p (a vector orthogonal to all of S separates).

Every certificate is re-checked as :meth:`SpanCertificate.verify` checks
it. When the LP's does not re-check, the same decision on the columns
mapped to orthonormal rows (an invertible map, under which positive
spanning and its certificates are invariant) supplies one; when none
does, :func:`span_result` reports MARGINAL: the set is within the
solvers' tolerances of the boundary.

Columns are normalised before deciding, and columns shorter than 1e-11 times
the longest are treated as zero, so the verdict is invariant to positive
scaling of each vector and ``tol`` is an angle-like tolerance.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog, nnls

from cdpm.analysis._common import (
    Verdict,
    as_matrix,
    eigh,
    fmt_array,
    in_norm_range,
    numerical_rank,
    qr_pivots,
    svdvals,
)
from cdpm.analysis._span_hull import min_norm_separator, span_margin_bracket
from cdpm.errors import InputError, check_tol
from cdpm.numerics import (
    COMBINATION_SHARE_MARGIN,
    COMBINATION_SV_MIN,
    NNLS_RES_RTOL,
    RECHECK_TOL,
    ROUNDOFF_SHARE_RTOL,
    SPAN_RANK_RTOL,
    SPAN_TOL,
    ZERO_RTOL,
)
from cdpm.printing import html_table, to_plain

__all__ = ["SpanCertificate", "SpanResult", "positively_spans", "wrench_closure"]


@dataclass(frozen=True)
class SpanCertificate:
    """Re-checkable proof of a positive-span decision.

    Attributes:
        kind: ``"positive-span"`` (YES) or ``"separator"`` (NO).
        indices: for YES, the columns used, shape (q,).
        weights: for YES, strictly positive weights w with
            ``vectors[:, indices] @ w = 0``, the largest 1, shape (q,).
        separator: for NO, a unit vector v with ``v @ s_i <= 0`` for every
            column not shorter than ``ZERO_RTOL`` times the longest (shorter
            ones count as zero, as in the decision), (p,).
    """

    kind: str
    indices: np.ndarray | None = None
    weights: np.ndarray | None = None
    separator: np.ndarray | None = None

    def verify(self, vectors, tol: float = RECHECK_TOL) -> bool:
        """Re-check against ``vectors`` (p, k) by direct linear algebra.

        Raises:
            InputError: ``vectors`` is not a real matrix, or has fewer
                columns than the certificate uses or another number of rows
                than its separator has entries.
        """
        S = as_matrix("vectors", vectors, check_finite=False)
        tol = check_tol(tol, RECHECK_TOL, "a relative tolerance", "")
        if not np.all(np.isfinite(S)):
            return False
        p, k = S.shape
        used = self.indices if self.kind == "positive-span" else []
        if (len(used) and int(np.max(used)) >= k) or (
            self.kind == "separator" and np.size(self.separator) != p
        ):
            what = f"columns {fmt_array(used)}" if len(used) else f"{np.size(self.separator)} rows"
            raise InputError(
                f"vectors of shape {S.shape} do not fit this certificate (it uses {what}); "
                "re-check it against the vectors it was made for"
            )
        if self.kind == "positive-span":
            if p == 0:
                return True
            sub = S[:, self.indices]
            return check_positive_combination(sub, self.weights, tol)
        if self.kind == "separator":
            S = in_norm_range(S)[0]  # norms that neither under- nor overflow
            v = np.asarray(self.separator, dtype=float)
            nv = np.linalg.norm(v)
            if nv == 0:
                return False
            norms = np.linalg.norm(S, axis=0)
            if norms.size == 0:
                return True
            counted = _counted(norms)
            return bool(np.all((v @ S <= tol * nv * norms + 1e-300)[counted]))
        return False

    def as_dict(self) -> dict:
        return to_plain(
            {
                "kind": self.kind,
                "indices": self.indices,
                "weights": self.weights,
                "separator": self.separator,
            }
        )


def _counted(norms: np.ndarray) -> np.ndarray:
    """Mask of the columns whose ``norms`` (k,) exceed ZERO_RTOL times the
    largest: the others count as zero (as :func:`span_core` decides)."""
    return norms > ZERO_RTOL * norms.max() if norms.size else np.zeros(0, bool)


def check_positive_combination(S: np.ndarray, w: np.ndarray, tol: float) -> bool:
    """True when w > 0, S w = 0 (relative to tol) and rank S = rows of S,
    with the smallest singular value of the normalised S above the residual,
    and every column's share w_i |s_i| / sum w |s| above
    COMBINATION_SHARE_MARGIN times the residual over that singular value: an
    exact combination with positive weights is then within the residual's
    correction, so S positively spans the space."""
    p = S.shape[0]
    w = np.asarray(w, dtype=float)
    if w.ndim != 1 or w.size != S.shape[1] or np.any(~(w > 0)):
        return False
    # both scale out of every test: brought into range where squares would
    # under- or overflow
    S, w = in_norm_range(S)[0], in_norm_range(w)[0]
    norms = np.linalg.norm(S, axis=0)
    if np.any(norms == 0):
        return False
    scale = float(np.sum(w * norms))
    residual = float(np.linalg.norm(S @ w)) / scale
    if residual > tol:
        return False
    s = np.linalg.svd(S / norms, compute_uv=False)
    if s.size < p or not s[p - 1] > max(10 * residual, COMBINATION_SV_MIN):
        return False
    shares = w * norms / scale
    return bool(shares.min() > COMBINATION_SHARE_MARGIN * residual / s[p - 1])


@dataclass(frozen=True)
class SpanResult:
    """Whether the columns of ``vectors`` positively span R^p.

    Attributes:
        verdict: ``Verdict.YES`` or ``Verdict.NO`` (for p = 2, boundary
            cases within ``tol`` are NO: the conic hull is then a closed
            half-plane or less); ``Verdict.MARGINAL`` when the decision's certificate does
            not re-check (vectors within the solvers' own tolerances of the
            boundary: nothing is proven, and ``certificate`` holds the
            candidate that failed).
        p: dimension of the space.
        rank: numerical rank of the (normalised) vectors.
        method: which path decided (see module docstring).
        certificate: :class:`SpanCertificate`.
        vectors: copy of the input, shape (p, k).
        tol: tolerance used.
        margin: a polynomial-time index of ``mu = min_{|v|=1} max_i v^T s_i``
            (the inradius about 0 of conv(S) when YES, minus the distance
            from 0 to conv(S) when NO): for NO exactly ``-dist(0, conv S)``
            (min-norm point); for YES and p <= 3 exactly mu (the facets of a
            planar or spatial convex hull); for YES and p >= 4 ``r1 / sqrt(p)``
            where ``r1`` is the largest r with the cross-polytope
            ``{|y|_1 <= r}`` inside conv(S) (2p small LPs), a lower bound of
            mu. Continuous in S, polynomial in p and k; computed on first access.
        margin_bracket: ``(lower, upper)`` bounds of mu; lower is ``margin``.
    """

    verdict: Verdict
    p: int
    rank: int
    method: str
    certificate: SpanCertificate
    vectors: np.ndarray = field(repr=False)
    tol: float = SPAN_TOL

    def __bool__(self) -> bool:
        return self.verdict is Verdict.YES

    @functools.cached_property
    def margin_bracket(self) -> tuple[float, float]:
        return span_margin_bracket(self.vectors, self.verdict is Verdict.YES)

    @property
    def margin(self) -> float:
        return self.margin_bracket[0]

    @property
    def reason(self) -> str:
        if self.verdict is Verdict.MARGINAL:
            leaning = "YES" if self.certificate.kind == "positive-span" else "NO"
            return (
                f"the decision leant {leaning}, but no certificate re-checks: the vectors all "
                "lie within the solvers' tolerances of one closed half-space (one direction "
                "is barely reachable); read it as not proven either way"
            )
        if self.verdict is Verdict.YES:
            return (
                f"{len(self.certificate.indices)} of the {self.vectors.shape[1]} vectors "
                f"combine to 0 with strictly positive weights and have rank {self.p}"
            )
        k = self.vectors.shape[1]
        zero = k - int(_counted(np.linalg.norm(in_norm_range(self.vectors)[0], axis=0)).sum())
        if zero == k:
            return f"the {k} vectors are all zero" if k else "there are no vectors"
        verb = "is" if zero == 1 else "are"
        counted = (
            f"; {zero} of the {k} vectors {verb} not longer than {ZERO_RTOL:g} times the "
            "longest and counted as zero"
            if zero
            else ""
        )
        if self.rank < self.p:
            return f"the vectors have numerical rank {self.rank} < {self.p}{counted}"
        return (
            "a separating unit vector v has v.s <= tol |s| for every vector s (they all lie "
            f"in a half-space, to within tol = {self.tol:g}){counted}"
        )

    def verify(self, vectors=None) -> bool:
        """Re-check the certificate (against ``vectors`` if given)."""
        return self.certificate.verify(self.vectors if vectors is None else vectors)

    def as_dict(self) -> dict:
        return to_plain(
            {
                "verdict": self.verdict,
                "dimension": self.p,
                "rank": self.rank,
                "method": self.method,
                "margin": self.margin,
                "reason": self.reason,
                "certificate": self.certificate.as_dict(),
            }
        )

    def __str__(self) -> str:
        return self.describe()

    def describe(self, names=None, noun: str = "columns") -> str:
        """The result as text; ``names``: one per vector (column of
        ``vectors``), e.g. the cables' names, shown after ``noun`` instead
        of the column indices in the certificate."""
        return (
            f"positively spans R^{self.p}: {self.verdict} ({self.method}; "
            f"rank {self.rank}; margin {self.margin + 0.0:.4g})\n  {self.reason}\n  "
            f"{self._certificate_text(names, noun)}"
        )

    def _certificate_text(self, names=None, noun: str = "columns") -> str:
        c = self.certificate
        if c.kind == "positive-span":
            # each weight to 4 significant digits (1e-9 beside 1 stays legible)
            w = np.asarray(c.weights, dtype=float)
            shown = ", ".join(f"{x + 0.0:.4g}" for x in w)
            which = (
                f"{noun} {fmt_array(c.indices)}"
                if names is None
                else f"{noun} [{', '.join(str(names[i]) for i in c.indices)}]"
            )
            cert = f"{which} with weights (largest 1) [{shown}]"
        else:
            cert = f"separator v = {fmt_array(c.separator)}"
        if self.verdict is Verdict.MARGINAL:
            cert = f"candidate that does not re-check: {cert}"
        return cert

    def _repr_html_(self) -> str:
        return html_table(
            f"Positive span of R^{self.p}: {self.verdict}",
            [
                ("method", self.method),
                ("margin", f"{self.margin + 0.0:.4g}"),
                ("reason", self.reason),
                ("certificate", self._certificate_text()),
            ],
        )


# --------------------------------------------------------------------------
# decision core (no validation; used by the POC code on many sample sets)


def span_core(S: np.ndarray, tol: float = SPAN_TOL, zero_rtol: float = ZERO_RTOL):
    """Decide positive spanning of the columns of S (p, k).

    Columns not longer than ``zero_rtol`` times the longest are zero; pass
    ``zero_rtol=0`` for columns already cleaned against their own
    round-off scale (only exact zeros are then dropped).

    Returns:
        (yes, method, rank, indices, weights, separator): for YES ``indices``
        and strictly positive ``weights`` on the normalised columns
        (``S[:, indices] / |s_i|``) combining them to 0, which pass
        :func:`check_positive_combination` whenever a certificate of the set
        can (:func:`_proven`); for NO a unit ``separator`` v with
        ``v @ S <= tol * |s_i|``.
    """
    p, k = S.shape
    if p == 0:
        return True, "trivial", 0, np.zeros(0, int), np.zeros(0), None
    S = in_norm_range(S)[0]
    norms = np.linalg.norm(S, axis=0) if p > 1 else np.abs(S[0])
    big = norms.max() if k else 0.0
    nz = np.flatnonzero(norms > zero_rtol * big) if big > 0 else np.zeros(0, int)
    if nz.size == 0:
        v = np.zeros(p)
        v[0] = 1.0
        return False, "rank", 0, None, None, v
    if p == 1:
        return _span_sign(S[0], nz, tol)
    U = S[:, nz] / norms[nz]
    out = _span_angular(U, nz, tol) if p == 2 else _span_general(U, nz, tol)
    if not out[0]:
        # only the LP's separators are not checked where they are found
        if out[1] != "lp" or np.max(out[5] @ U) <= RECHECK_TOL:
            return out
        v = _whitened(U, nz, tol, False)
        return out if v is None else (*out[:5], v)
    found = _proven(S, norms, out[3], out[4], tol)
    if found is None and p == 2:
        deep = _deepest_triple(U, nz)
        same = deep is not None and np.array_equal(deep[3], out[3])
        found = None if deep is None or same else _proven(S, norms, deep[3], deep[4], tol)
        if found is not None:
            out = deep
    lp = out
    if found is None and out[1] != "lp":
        lp = _span_lp(U, nz, tol, out[2])
        found = _proven(S, norms, lp[3], lp[4], tol) if lp[0] else None
    if found is None and lp[0] and lp[1] == "lp":
        cert = _completed(U, nz, lp[4])
        found = None if cert is None else _proven(S, norms, *cert, tol)
    if found is None and out[2] == p:
        cert = _whitened(U, nz, tol, True)
        found = None if cert is None else _proven(S, norms, *cert, tol)
    if found is None:  # no certificate re-checks (span_result reads it as MARGINAL)
        return out
    return (*out[:3], *found, None)


def _completed(U: np.ndarray, nz: np.ndarray, w: np.ndarray):
    """The LP's YES weights ``w`` on every unit column of U (p, k) (as
    :func:`_span_lp` returns them, for the columns ``nz``), with the columns
    they leave at round-off given weight one and the weights mu >= 0 that
    cancel those (one NNLS, ``U mu = -sum of them``) added to all:
    (nz, weights), or None.

    At its absolute tolerance the LP can leave a whole part of the set at
    weight 0: in R^3 the pair +-z beside x-y vectors that need a weight of
    1e-8, whose least weight the LP cannot raise above its tolerance. The
    pair cancels itself (mu = 0), and the weights become (..., 1, 1)."""
    full = np.asarray(w, dtype=float)
    small = full <= ROUNDOFF_SHARE_RTOL * full.max()
    if not small.any() or small.all():
        return None
    b = -U[:, small].sum(axis=1)
    mu = nnls(U, b, maxiter=50 * U.shape[1] + 100)[0]
    if np.linalg.norm(U @ mu - b) > NNLS_RES_RTOL * max(1.0, float(np.linalg.norm(b))):
        return None
    return nz, np.where(small, 1.0, full) + mu


def _whitened(U: np.ndarray, nz: np.ndarray, tol: float, yes: bool):
    """A certificate of the answer ``yes`` for the unit columns U (p, k),
    found on the whitened columns T U (T = S^-1 W^T from the SVD
    U = W S Z^T: rows orthonormal), or None.

    Positive spanning is invariant under an invertible linear map, and
    so are its certificates: weights w with T U w = 0 have U w = 0, and
    v' with v' . T u_i <= 0 gives v = T^T v' with v . u_i <= 0. A set
    flat in one direction (a component of 1e-6 in every column) has rows
    of very different size, which the LP's absolute tolerances do not
    resolve; whitened, its rows are alike. Returns, for YES, (indices,
    weights on the unit columns ``U[:, indices]``), for NO a unit v with
    ``v @ U <= RECHECK_TOL`` (what the certificate's re-check allows)."""
    W, sv, _ = np.linalg.svd(U, full_matrices=False)
    if sv.size < U.shape[0] or not sv[-1] > 0:
        return None
    T = W.T / sv[:, None]
    V = T @ U
    size = np.linalg.norm(V, axis=0)
    got = _span_general(V / size, np.arange(U.shape[1]), tol)
    if got[0] != yes:
        return None
    if yes:
        # sum w_i T u_i / |T u_i| = 0
        return nz[got[3]], got[4] / size[got[3]]
    v = T.T @ got[5]
    v = v / np.linalg.norm(v)
    return v if np.max(v @ U) <= RECHECK_TOL else None


def _proven(S, norms, idx, w, tol):
    """The YES certificate (indices, weights on the normalised columns)
    made to pass :func:`check_positive_combination`, or None.

    As found, when it passes and no column takes part at round-off (a
    weight at most ROUNDOFF_SHARE_RTOL of the largest: NNLS leaves some near
    1e-16, whose check passes or fails with the rounding of the residual).
    Otherwise such columns are dropped and the others' weights corrected by
    the least-norm change that cancels the residual; that passes when every
    corrected weight stays clearly positive."""
    idx = np.asarray(idx)
    w = np.asarray(w, dtype=float)
    V = S[:, idx] / norms[idx]
    keep = w > ROUNDOFF_SHARE_RTOL * w.max()
    if keep.all() and _certifies(S, idx, V, w, tol):
        return idx, w
    idx, V, w = idx[keep], V[:, keep], w[keep]
    w = w - np.linalg.lstsq(V, V @ w, rcond=None)[0]
    if _certifies(S, idx, V, w, tol):
        return idx, w
    return None


def _certifies(S, idx, V, w, tol) -> bool:
    """Weights ``w`` on the unit columns ``V = S[:, idx] / norms[idx]``
    pass :func:`check_positive_combination` there (at ``tol``) and as the
    certificate of :func:`span_result` holds them, on the raw columns (at
    RECHECK_TOL, as :meth:`SpanCertificate.verify` checks): the two differ
    by rounding, which decides a combination at the edge of the check."""
    return check_positive_combination(V, w, tol) and check_positive_combination(
        S[:, idx], _raw_weights(S, idx, w), RECHECK_TOL
    )


def _span_sign(s: np.ndarray, nz: np.ndarray, tol: float):
    x = s[nz]
    i_pos, i_neg = int(np.argmax(x)), int(np.argmin(x))
    if x[i_pos] > 0 and x[i_neg] < 0:
        idx = np.array([nz[i_pos], nz[i_neg]])
        # w_+ * s_+ + w_- * s_- = 0
        # on normalised columns (+1 and -1) unit weights combine to 0
        return True, "sign", 1, idx, np.ones(2), None
    v = np.array([1.0]) if x[i_pos] <= 0 else np.array([-1.0])
    return False, "sign", 1, None, None, v


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _span_angular(U: np.ndarray, nz: np.ndarray, tol: float):
    theta = np.arctan2(U[1], U[0])
    order = np.argsort(theta)
    th = theta[order]
    gaps = np.diff(np.append(th, th[0] + 2 * np.pi))
    g = int(np.argmax(gaps))
    rank = 1 if gaps.size == 1 or np.all(np.abs(np.sin(theta - theta[0])) <= tol) else 2
    if gaps[g] >= np.pi - tol:
        mid = th[g] + 0.5 * gaps[g]
        v = np.array([np.cos(mid), np.sin(mid)])
        return False, "angular", rank, None, None, v
    # three directions positively spanning: the first, the last one less than
    # pi counter-clockwise from it and the next one (consecutive => gaps < pi)
    rel = np.mod(th - th[0], 2 * np.pi)
    a = 0
    b = int(np.flatnonzero(rel < np.pi - tol)[-1])
    c = b + 1
    while c < rel.size and rel[c] <= np.pi + tol:
        # (almost) opposite directions: step past them all (the triple would
        # hold two opposite columns, and the third a weight at round-off)
        c += 1
    if c >= rel.size or not (rel[c] - rel[b] < np.pi and 2 * np.pi - rel[c] < np.pi):
        return _deepest_triple(U, nz) or _span_general(U, nz, tol)
    i, j, m = order[a], order[b], order[c]
    sa, sb, sc = U[:, i], U[:, j], U[:, m]
    w = np.array([_cross(sb, sc), _cross(sc, sa), _cross(sa, sb)])
    if np.any(w <= 0):
        return _deepest_triple(U, nz) or _span_general(U, nz, tol)
    idx = nz[[i, j, m]]
    # weights refer to the raw columns: divide by their norms
    return True, "angular", 2, idx, w, None


def _deepest_triple(U: np.ndarray, nz: np.ndarray):
    """The YES certificate of planar unit columns U (2, k) whose every
    largest angular gap is below pi, from the three columns that pass
    :func:`check_positive_combination` by the widest margin (the smallest
    share times the smallest singular value), or None when no three have
    positive weights.

    For each column a: b the furthest counter-clockwise from it by less
    than pi, c the nearest by more than pi; consecutive around the circle
    apart from columns opposite a, so c - b is one gap below pi and the
    cross products b x c, c x a, a x b are positive weights. The first
    column's triple can hold weights of about the tolerance, all of them
    (directions within the tolerance of a half-plane, a second pair within
    it of opposite), which round-off then decides; another column's triple
    has weights of order one but for that of the near-opposite pair.
    O(k^2); only when the first triple proves nothing."""
    theta = np.arctan2(U[1], U[0])
    rel = np.mod(theta[None, :] - theta[:, None], 2 * np.pi)  # [a, j]: j from a
    b = np.where((rel > 0) & (rel < np.pi), rel, -np.inf).argmax(axis=1)
    c = np.where(rel > np.pi, rel, np.inf).argmin(axis=1)
    a = np.arange(theta.size)
    sa, sb, sc = U[:, a], U[:, b], U[:, c]
    w = np.stack([_cross(sb, sc), _cross(sc, sa), _cross(sa, sb)])  # (3, k)
    # det of the Gram matrix of three planar columns: the sum of the squared
    # cross products (Cauchy-Binet), exact where the smaller eigenvalue
    # computed directly cancels; its trace is 3
    det = (w * w).sum(axis=0)
    big = 0.5 * (3.0 + np.sqrt(np.maximum(9.0 - 4.0 * det, 0.0)))
    positive = w.min(axis=0) > 0
    depth = np.where(positive, w.min(axis=0) / np.where(positive, w.sum(axis=0), 1.0), -1.0)
    depth = depth * np.sqrt(det / big)
    best = int(np.argmax(depth))
    if not depth[best] > 0:
        return None
    idx = nz[[a[best], b[best], c[best]]]
    return True, "angular", 2, idx, w[:, best], None


def _span_general(U: np.ndarray, nz: np.ndarray, tol: float):
    """NNLS decision on normalised columns U (p, k); LP only as a fallback."""
    p, k = U.shape
    # rank p and a well-conditioned basis from one pivoted QR (no SVD); the
    # Gram eigen-decomposition (rank and separator) only if QR sees a defect
    piv, rdiag = qr_pivots(U)
    rank = p
    if rdiag.size < p or not rdiag[p - 1] > SPAN_RANK_RTOL * rdiag[0]:
        # the singular values of U itself: the square roots of the Gram
        # matrix's eigenvalues resolve only about 1e-8 of the largest, which
        # is coarser than SPAN_RANK_RTOL
        rank = numerical_rank(svdvals(U), SPAN_RANK_RTOL)
        if rank < p:
            v = eigh(U @ U.T)[1][:, 0]  # the least left singular vector
            return False, "rank", rank, None, None, v
    # one NNLS decides: with a basis b_1..b_p of columns, the cone is R^p
    # iff -sum b_i is in it; then the basis (weights >= 1) and the NNLS
    # support (at most p columns) combine to 0 with positive weights. Any b
    # not in the cone proves NO, so the basis only matters for YES: the
    # first p pivots of the QR (independent by construction), all columns
    # when there are few
    basis = np.arange(k) if k <= 2 * p else piv[:p]
    b = -U[:, basis].sum(axis=1)
    mu = nnls(U, b, maxiter=50 * k + 100)[0]
    # the residual as computed here, not NNLS's own figure: with exactly
    # dependent columns in its working set NNLS can return huge weights and
    # report a residual of 0 that U mu - b does not have
    res = float(np.linalg.norm(U @ mu - b))
    if res <= NNLS_RES_RTOL * max(1.0, float(np.linalg.norm(b))):
        w = mu.copy()
        w[basis] += 1.0
        idx = np.flatnonzero(w > 0)
        # rank p: the basis is in it; span_core re-checks the certificate
        # (rank included) and falls back to the LP when it does not hold
        return True, "nnls", p, nz[idx], w[idx], None
    # KKT: U^T (U mu - b) >= 0, so v = -(U mu - b) separates
    r = U @ mu - b
    v = -r / np.linalg.norm(r)
    if np.max(v @ U) <= tol:
        return False, "nnls", p, None, None, v
    return _span_lp(U, nz, tol, rank)


def independent_columns(U: np.ndarray, r: int) -> np.ndarray:
    """Indices of r columns of U (p, k) spanning its r-dimensional range:
    the first r pivots of a column-pivoted (rank-revealing) QR."""
    return qr_pivots(U)[0][:r]


def _span_lp(U: np.ndarray, nz: np.ndarray, tol: float, rank: int):
    """LP: maximise t s.t. U w = 0, w >= t, sum w = k (HiGHS).

    t* > 0 iff U positively spans (given full rank); the dual gives v."""
    p, k = U.shape
    c = np.zeros(k + 1)
    c[-1] = -1.0
    A_eq = np.zeros((p + 1, k + 1))
    A_eq[:p, :k] = U
    A_eq[p, :k] = 1.0
    b_eq = np.zeros(p + 1)
    b_eq[p] = k
    A_ub = np.hstack([-np.eye(k), np.ones((k, 1))])
    res = linprog(
        c,
        A_ub=A_ub,
        b_ub=np.zeros(k),
        A_eq=A_eq,
        b_eq=b_eq,
        bounds=[(0, None)] * k + [(None, 1.0)],
        method="highs",
    )
    if res.status == 0 and -res.fun > tol:
        return True, "lp", rank, nz, res.x[:k], None
    # separator: the min-norm point of conv(U) (LDP via NNLS); when 0 is in
    # the hull (the cone holds a line without being R^p) the LP's duals y
    # of U w = 0 at t* = 0 have U^T y <= 0: every column in a closed half-space
    found = min_norm_separator(U)
    v = None if found is None else found[0]
    if v is None and res.status == 0:
        y = -np.asarray(res.eqlin.marginals[:p], dtype=float)
        for cand in (y, -y):
            size = float(np.linalg.norm(cand))
            if size > 0 and np.max(cand @ U) <= tol * size:
                v = cand / size
                break
    if v is None:
        v = np.zeros(p)
        v[0] = 1.0
    return False, "lp", rank, None, None, v


# --------------------------------------------------------------------------
# public API


def positively_spans(vectors, *, tol: float = SPAN_TOL) -> SpanResult:
    """Decide whether the columns of ``vectors`` positively span R^p.

    Args:
        vectors: shape (p, k), one vector per column.
        tol: angle-like tolerance in (0, 1) [rad] (module docstring: for
            p = 2 sets within ``tol`` of the boundary, a closed half-plane,
            are NO).

    Returns:
        :class:`SpanResult`: YES or NO with a certificate that
        ``verify()`` re-checks, or MARGINAL when no certificate re-checks
        (the vectors are within the solvers' tolerances of the boundary;
        read it as "not proven either way").
    """
    S = as_matrix("vectors", vectors)
    return span_result(S, check_tol(tol))


def span_result(S: np.ndarray, tol: float = SPAN_TOL) -> SpanResult:
    """:func:`positively_spans` without validation (S already a float array)."""
    yes, method, rank, idx, w, v = span_core(S, tol)
    if yes:
        cert = SpanCertificate(
            "positive-span", indices=np.asarray(idx), weights=_raw_weights(S, idx, w)
        )
    else:
        cert = SpanCertificate("separator", separator=v)
    verdict = Verdict.YES if yes else Verdict.NO
    if not cert.verify(S):
        verdict = Verdict.MARGINAL
    return SpanResult(verdict, S.shape[0], rank, method, cert, S, tol)


def _raw_weights(S, idx, w):
    """Weights found on normalised columns, converted to the raw columns
    and scaled to a largest of 1 (any positive multiple is the same
    certificate; w_i / |s_i| itself overflows for vectors of 1e-310)."""
    if S.shape[0] == 0:
        return np.zeros(0)
    raw = np.asarray(w, dtype=float) / np.linalg.norm(in_norm_range(S[:, idx])[0], axis=0)
    return raw / raw.max() if raw.size else raw


def wrench_closure(L, *, tol: float = SPAN_TOL) -> SpanResult:
    """Wrench closure at a pose: the columns of ``-L^T`` positively span R^nv.

    Args:
        L: cable Jacobian, shape (m, nv); ``l' = L q'``. A tension f >= 0
            produces the generalised force ``-L^T f`` (paper eq 11).
        tol: as :func:`positively_spans`.

    Returns:
        :class:`SpanResult` over the m columns of ``-L^T`` (shape (nv, m)).
    """
    L = as_matrix("L", L)
    return span_result(-L.T, check_tol(tol))
