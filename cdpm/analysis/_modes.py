"""Evaluating output responses g_j(t) = C e^{At} b_j on time grids, choosing
the horizon from the spectrum, and proving v^T g_j(t) <= 0 for all t >= 0.

All functions work on a scaled system (|A|_2 = 1, unit columns of B, unit
rows of C; see :func:`cdpm.analysis._common.scaled_system`), so times are in
units of 1/|A| and the tolerances below are relative.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from cdpm.numerics import (
    DOMINANT_RATE_ATOL,
    GRID_ROUNDOFF_RTOL,
    HORIZON_MAX,
    HORIZON_RATE_MIN,
    MODAL_COND_MAX,
    MODE_COEFF_RTOL,
    RATE_FLOOR,
    REAL_EIG_ATOL,
    TAYLOR_ZERO_RTOL,
)

#: ln of the largest float64 (~709.78): sinh(x) / w < e^x / (2 w) stays
#: finite for x below this plus min(0, ln w)
_LOG_FLOAT_MAX = math.log(np.finfo(float).max)

# MODAL_COND_MAX: the eigenvector matrix of A above which the modal
# (eigen-decomposition) evaluation is not trusted; HORIZON_MAX: the longest
# default horizon, in units of 1/|A|


class Evaluator:
    """g(t) = C e^{At} B on arrays of times, shape (N, p, m).

    Uses the eigen-decomposition when A is diagonalisable with a
    well-conditioned eigenvector matrix (exact modal sums, also used by the
    proofs), else batched :func:`scipy.linalg.expm`.
    """

    def __init__(self, A: np.ndarray, B: np.ndarray, C: np.ndarray):
        self.A, self.B, self.C = A, B, C
        self.lam = None
        self.eigvals = np.zeros(0, dtype=complex)
        n = A.shape[0]
        if n == 0:
            return
        lam, V = np.linalg.eig(A)
        try:
            Vinv = np.linalg.inv(V)
        except np.linalg.LinAlgError:
            Vinv = None
        # |V|_F |V^-1|_F >= cond_2(V): a conservative bound without an SVD
        cond = np.inf if Vinv is None else float(np.linalg.norm(V) * np.linalg.norm(Vinv))
        if np.isfinite(cond) and cond <= MODAL_COND_MAX:
            self.lam = lam
            self.CV = C @ V
            self.WB = Vinv @ B
        self.eigvals = lam

    @property
    def modal(self) -> bool:
        return self.lam is not None

    def __call__(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        if self.A.shape[0] == 0:
            return np.zeros((t.size, self.C.shape[0], self.B.shape[1]))
        if self.modal:
            E = np.exp(np.outer(t, self.lam))
            return np.einsum("pi,ti,ij->tpj", self.CV, E, self.WB).real
        return np.einsum("pi,tij->tpj", self.C, expm(t[:, None, None] * self.A) @ self.B)

    def with_scale(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(g(t) (N, p, m), scale (N, m)): ``scale[k, j]`` is the size of the
        terms summed into g_j(t_k) (root of the sum of squares of the modal
        terms, or |C| |e^{At}| |b_j|); |g_j(t_k)| far below it is round-off."""
        t = np.asarray(t, dtype=float)
        n, m = self.A.shape[0], self.B.shape[1]
        if n == 0:
            return np.zeros((t.size, self.C.shape[0], m)), np.zeros((t.size, m))
        if self.modal:
            E = np.exp(np.outer(t, self.lam))
            G = np.einsum("pi,ti,ij->tpj", self.CV, E, self.WB).real
            cv2 = np.einsum("pi,pi->i", self.CV, self.CV.conj()).real
            E2 = (E * E.conj()).real
            scale = np.sqrt((E2 * cv2) @ (self.WB * self.WB.conj()).real)
            return G, scale
        X = expm(t[:, None, None] * self.A)
        G = np.einsum("pi,tij->tpj", self.C, X @ self.B)
        scale = (
            np.linalg.norm(self.C)
            * np.linalg.norm(X, axis=(1, 2))[:, None]
            * np.linalg.norm(self.B, axis=0)
        )
        return G, scale

    def coefficients(self, v: np.ndarray, j: int) -> np.ndarray:
        """kappa_i with v^T g_j(t) = Re sum_i kappa_i exp(lam_i t) (modal only)."""
        return (v @ self.CV) * self.WB[:, j]


class ModalEvaluator:
    """g(t) = Cq U diag(s_k(t)) U^-1 Bv for A = [[0, I], [K, 0]], B = [0; Bv],
    C = [Cq, 0] with K = U diag(kappa) U^-1 real: s_k(t) = sin(w t)/w
    (kappa = -w^2 < 0), t (kappa = 0) or sinh(w t)/w (kappa = w^2 > 0)."""

    modal = False  # no complex modal sums: the NO proofs use the exact modal test

    def __init__(self, kappa: np.ndarray, CqU: np.ndarray, beta: np.ndarray, zero: float):
        self.kappa, self.CqU, self.beta = kappa, CqU, beta
        self.w = np.sqrt(np.abs(kappa))
        self.osc = kappa < -zero
        self.grow = kappa > zero
        self.eigvals = np.concatenate([1j * self.w, -1j * self.w])
        self._cq2 = np.einsum("pi,pi->i", CqU, CqU)
        w_grow = self.w[self.grow]
        #: the latest time at which every modal response s_k(t) is a finite
        #: float64 (same time unit as 1/w; sinh(w t) / w of a growing mode
        #: overflows beyond)
        self.t_finite = (
            float(np.min((_LOG_FLOAT_MAX + np.minimum(np.log(w_grow), 0.0)) / w_grow))
            if w_grow.size
            else math.inf
        )

    def __call__(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return np.einsum("pi,ti,ij->tpj", self.CqU, self._s(t), self.beta)

    def _s(self, t: np.ndarray) -> np.ndarray:
        """Modal responses s_k(t), shape (N, h), for times t in
        [0, ``t_finite``] (the unit of 1/w).

        Each response is evaluated on its own modes only: sinh of an
        oscillatory mode's w t (discarded anyway) overflows at late times of
        a slow oscillation although every value returned is finite. A time
        beyond ``t_finite`` would make a growing mode's sinh overflow to inf
        (and its products with zero entries NaN), so it is refused; the
        samplers stop far earlier (a growth of 1e8).
        """
        t = np.asarray(t, dtype=float)
        if t.size and float(t.max()) > self.t_finite:
            raise ValueError(
                f"modal responses sinh(w t) / w overflow float64 beyond "
                f"t = {self.t_finite:.6g}; got t = {float(t.max()):.6g}"
            )
        S = np.empty((t.size, self.w.size))
        flat = ~(self.osc | self.grow)
        S[:, flat] = t[:, None]
        for modes, fn in ((self.osc, np.sin), (self.grow, np.sinh)):
            if modes.any():
                w = self.w[modes]
                S[:, modes] = fn(np.outer(t, w)) / w
        return S

    def columns(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(G (p, N*m), scale (N*m,)): column k*m + j is g_j(t_k), with its
        round-off scale as in :meth:`Evaluator.with_scale`."""
        S = self._s(np.asarray(t, dtype=float))  # (N, h)
        Z = (S.T[:, :, None] * self.beta[:, None, :]).reshape(S.shape[1], -1)  # (h, N*m)
        scale = np.sqrt(self._cq2 @ (Z * Z))
        return self.CqU @ Z, scale

    def with_scale(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(g(t) (N, p, m), scale (N, m)) as :meth:`Evaluator.with_scale`."""
        t = np.asarray(t, dtype=float)
        S = self._s(t)
        G = np.einsum("pi,ti,ij->tpj", self.CqU, S, self.beta)
        return G, np.sqrt((S * S * self._cq2) @ (self.beta * self.beta))


def default_horizon(eigvals: np.ndarray) -> float:
    """A horizon (units 1/|A|) that sees the slow dynamics: three periods of
    the slowest oscillation and five time constants of the slowest real
    rate, at least 10, at most ``HORIZON_MAX``."""
    T = 10.0
    if eigvals is None or eigvals.size == 0:
        return T
    im = np.abs(eigvals.imag)
    re = np.abs(eigvals.real)
    osc = im[im > HORIZON_RATE_MIN]
    if osc.size:
        T = max(T, 3 * 2 * math.pi / osc.min())
    rates = re[re > HORIZON_RATE_MIN]
    if rates.size:
        T = max(T, 5.0 / rates.min())
    growth = eigvals.real.max()
    if growth > HORIZON_RATE_MIN:
        # responses grow like e^{growth t}: stop before they dwarf everything
        T = min(T, max(10.0, 30.0 / growth))
    return min(T, HORIZON_MAX)


#: the coarse grid on [0, 1]: uniform plus logarithmic near 0 (sorted, unique)
_COARSE = np.unique(np.concatenate([np.linspace(0.0, 1.0, 25), np.geomspace(1e-3, 1 / 24, 8)]))


def coarse_times(T: float) -> np.ndarray:
    """A small mixed grid on [0, T]: uniform plus logarithmic near 0."""
    return T * _COARSE


def fine_times(T: float, eigvals) -> np.ndarray:
    """A finer grid resolving the fastest mode, plus tail points beyond T."""
    fast = 1.0 if eigvals is None or eigvals.size == 0 else max(np.abs(eigvals).max(), RATE_FLOOR)
    n = int(min(4000, max(200, math.ceil(T * fast / 0.25))))
    return np.unique(
        np.concatenate(
            [
                np.linspace(0.0, T, n + 1),
                np.geomspace(T * 1e-4, T / n, 12),
                T * 2.0 ** np.arange(1, 9),
            ]
        )
    )


# --------------------------------------------------------------------------
# the NO proof: v^T g_j(t) <= 0 for every t >= 0


def prove_nonpositive(ev: Evaluator, v: np.ndarray, j: int, T: float):
    """Try to prove f(t) = v^T C e^{At} b_j <= 0 for all t >= 0.

    Three pieces (docs/analysis.md): a Taylor bound on (0, t1], a sampled
    bound with a second-derivative bound on [t1, T'] and a dominant-mode
    bound on [T', inf). Needs the modal evaluator.

    Returns:
        (ok, data, violations): ``data`` the proof numbers (plain floats);
        ``violations`` times where f > 0 was found (for the exchange step).
    """
    A, b, C = ev.A, ev.B[:, j], ev.C
    n = A.shape[0]
    w = v @ C
    scale = float(np.linalg.norm(w) * np.linalg.norm(b)) + 1e-300
    # --- Taylor at 0 (|A|_2 = 1 so |A^k| <= 1)
    K = n + 8
    coeff = np.empty(K + 1)
    x = b.copy()
    for k in range(K + 1):
        coeff[k] = w @ x
        x = A @ x
    small = TAYLOR_ZERO_RTOL * scale
    lead = np.flatnonzero(np.abs(coeff[:n]) > small)
    if lead.size == 0:
        return True, {"input": j, "identically_zero": True}, []
    k0 = int(lead[0])
    fac = np.array([math.factorial(k) for k in range(K + 2)], dtype=float)
    t1 = None
    for i in range(0, 60):
        t = min(1.0, T) * 2.0**-i
        ks = np.arange(k0 + 1, K + 1)
        rem = np.sum(np.abs(coeff[ks]) * t ** (ks - k0) / fac[ks])
        rem += scale * t ** (K + 1 - k0) / fac[K + 1] * math.exp(t)
        if rem < abs(coeff[k0]) / fac[k0]:
            t1 = t
            break
    if t1 is None:
        return False, {"input": j, "reason": "no Taylor interval"}, []
    if coeff[k0] > 0:
        # f > 0 on (0, t1]: hand those times to the exchange step
        return False, {"input": j, "reason": "positive near t = 0"}, [t1, t1 / 2]
    data = {"input": j, "taylor_order": k0, "taylor_coefficient": float(coeff[k0]), "t1": t1}
    if not ev.modal:
        return False, {**data, "reason": "A is defective or ill-conditioned: no tail bound"}, []
    kap = ev.coefficients(v, j)
    lam = ev.lam
    mag = np.abs(kap)
    sig = mag > MODE_COEFF_RTOL * max(mag.sum(), 1e-300)
    if not sig.any():
        return True, {**data, "identically_zero": True}, []
    # --- tail: f(t) <= e^{alpha t} (c0 + amp + sum_rest |kap| e^{(re - alpha) t})
    re = lam.real
    alpha = re[sig].max()
    dom = sig & (re >= alpha - DOMINANT_RATE_ATOL)
    is_real = np.abs(lam.imag) <= REAL_EIG_ATOL
    c0 = float(np.sum(kap[dom & is_real].real))
    amp = float(np.sum(mag[dom & ~is_real]))
    rest = sig & ~dom
    lead_bound = c0 + amp
    if lead_bound >= 0:
        # the dominant mode is not negative (a complex dominant mode: v fails)
        tt = T * np.linspace(1.0, 8.0, 400)
        if alpha > 0:
            tt = tt[tt * alpha < 300]
        with np.errstate(over="ignore", invalid="ignore"):
            f = ev(tt)[:, :, j] @ v
        viol = list(tt[f > 0][:5])
        return False, {**data, "reason": "dominant mode not negative"}, viol
    Tp = T
    for _ in range(60):
        tail = lead_bound + float(np.sum(mag[rest] * np.exp((re[rest] - alpha) * Tp)))
        if tail < 0:
            break
        Tp *= 1.5
    else:
        return False, {**data, "reason": "tail bound does not close"}, []
    # --- [t1, Tp]: max over an interval <= max(endpoints) + h^2/8 max|f''|
    ok, viol, nint = _grid_bound(ev, v, j, kap, lam, t1, Tp)
    data.update(
        {"grid_end": Tp, "intervals": nint, "tail_alpha": float(alpha), "tail_bound": float(tail)}
    )
    if not ok:
        return False, {**data, "reason": "sampled bound does not close on [t1, T]"}, viol
    return True, data, []


def _grid_bound(ev, v, j, kap, lam, t0, t1, depth=0, n=None):
    if n is None:
        fast = max(np.abs(lam).max(), RATE_FLOOR)
        n = int(min(20000, max(64, math.ceil((t1 - t0) * fast / 0.2))))
    t = np.linspace(t0, t1, n + 1)
    with np.errstate(over="ignore", invalid="ignore"):
        f = np.real(np.exp(np.outer(t, lam)) @ kap)
    if not np.all(np.isfinite(f)):
        return False, [], n
    if np.any(f > 0):
        return False, list(t[f > 0][:5]), n
    h = t[1] - t[0]
    mag2 = np.abs(kap) * np.abs(lam) ** 2
    ends = np.maximum(np.outer(t[:-1], lam.real), np.outer(t[1:], lam.real))
    curv = np.exp(ends) @ mag2
    err = GRID_ROUNDOFF_RTOL * (np.exp(ends) @ np.abs(kap))
    bound = np.maximum(f[:-1], f[1:]) + h * h / 8 * curv + err
    bad = np.flatnonzero(bound > 0)
    if bad.size == 0:
        return True, [], n
    if depth >= 3 or bad.size > 200:
        return False, [], n
    total = n
    for i in bad:
        ok, viol, m = _grid_bound(ev, v, j, kap, lam, t[i], t[i + 1], depth + 1, 16)
        total += m
        if not ok:
            return False, viol, total
    return True, [], total
