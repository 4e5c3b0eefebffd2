"""The result of a positive output controllability decision and its printing."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from cdpm.analysis._common import Verdict, fmt_array
from cdpm.analysis._poc_margin import margin_bracket
from cdpm.analysis.certificate import POCCertificate
from cdpm.analysis.margin import margin_horizon
from cdpm.analysis.rank import output_reachable_basis
from cdpm.printing import html_table, to_plain

__all__ = ["POCResult", "poc_margin"]


@dataclass(frozen=True)
class POCResult:
    """Verdict of positive output controllability with its proof.

    Attributes:
        verdict: YES, NO or MARGINAL (``bool(result)`` is True only for YES).
        method: the path that decided: ``"trivial"``, ``"mixed-cone"``,
            ``"nilpotent"``, ``"modal"``, ``"full-rank-brammer"``,
            ``"output-rank"``, ``"general"``, prefixed ``"mixed-cone+"`` when
            free inputs were projected out first.
        reason: one readable sentence.
        certificate: :class:`~cdpm.analysis.certificate.POCCertificate`;
            ``result.certificate.verify(A, B, C)`` re-checks it.
        horizon: the horizon of the sampled search [time] (the certificate's
            times when a path needed longer).
        margin: ``mu_T = min_{|v|=1} max_{t in [0,T], j} v^T W C e^{At} b_j s_j``
            (W = output_weight, s = input_scale; free inputs count with both
            signs) with ``T = margin_horizon``: the signed inradius about 0
            of the outputs g_j(t_k) sampled on a fixed grid of [0, T]
            (a lower bound of mu_T, exact for A^2 = 0), continuous in
            (A, B, C). Positive iff POC is seen within T; clipped to <= 0
            unless the verdict is YES. See docs/analysis.md.
        margin_bracket: (lower, upper) bounds of mu_T (the upper bound adds
            the grid spacing times a Lipschitz bound of g; for p >= 4 the
            lower one is the cross-polytope bound r1 / sqrt(p)).
        margin_horizon: T of the margin: ``horizon=`` if given, else a
            continuous function of A (:func:`cdpm.analysis.margin.margin_horizon`).
        output_rank: rank of [CB, CAB, ...]; output_controllable: == p.
        A, B, C, sign_constrained: the (validated copies of the) system.
    """

    verdict: Verdict
    method: str
    reason: str
    certificate: POCCertificate
    horizon: float
    A: np.ndarray = field(repr=False)
    B: np.ndarray = field(repr=False)
    C: np.ndarray = field(repr=False)
    sign_constrained: np.ndarray = field(repr=False)
    input_scale: np.ndarray | None = field(repr=False)
    output_weight: np.ndarray | None = field(repr=False)
    fixed_horizon: float | None = field(default=None, repr=False)

    def __bool__(self) -> bool:
        return self.verdict is Verdict.YES

    @functools.cached_property
    def output_rank(self) -> int:
        return output_reachable_basis(self.A, self.B, self.C).shape[1]

    @property
    def output_controllable(self) -> bool:
        return self.output_rank == self.C.shape[0]

    @functools.cached_property
    def margin_horizon(self) -> float:
        """Horizon of the margin [time]: the ``horizon=`` passed by the
        caller, else :func:`~cdpm.analysis.margin.margin_horizon` (a
        continuous function of the spectrum, |A|_2, CB and CAB)."""
        return self.fixed_horizon or margin_horizon(self.A, self.B, self.C)

    @functools.cached_property
    def margin_bracket(self) -> tuple[float, float]:
        return poc_margin(self)

    @property
    def margin(self) -> float:
        return self.margin_bracket[0]

    def as_dict(self) -> dict:
        return to_plain(
            {
                "verdict": self.verdict,
                "method": self.method,
                "reason": self.reason,
                "margin": self.margin,
                "margin_bracket": list(self.margin_bracket),
                "horizon": self.horizon,
                "output_rank": self.output_rank,
                "output_controllable": self.output_controllable,
                "p": self.C.shape[0],
                "sign_constrained": self.sign_constrained,
                "certificate": self.certificate.as_dict(),
            }
        )

    def _certificate_lines(self) -> list[str]:
        c = self.certificate
        if c.kind == "positive-span":
            late = ""
            if c.times.size and c.times.max() > self.margin_horizon:
                # the impulse index only sees [0, margin_horizon]: say so
                late = (
                    f" (at t up to {c.times.max():.4g}, beyond the impulse index's "
                    f"horizon [0, {self.margin_horizon:.4g}])"
                )
            lines = [
                f"  {c.times.size} output vectors g_j(t) positively span R^{self.C.shape[0]}{late}:"
            ]
            for t, j, s, w in zip(c.times, c.inputs, c.signs, c.weights, strict=True):
                sign = "-" if s < 0 else "+"
                lines.append(f"    {sign}g_{j}(t={t:.4g}) weight {w:.4g}")
            return lines
        if c.kind == "modal":
            lines = ["  modal certificate (stiffness eigenvalues kappa of K):"]
            for md in c.proof["modes"]:
                used = ", ".join(map(str, md["inputs"]))
                what = "have full rank in it"
                if md["definite"]:
                    what = "positively span its eigenspace"
                lines.append(
                    f"    kappa {md['kappa']:.4g} (x{md['multiplicity']}): inputs {used} {what}"
                )
            return lines
        if c.kind == "separator":
            return [
                f"  separating v = {fmt_array(c.separator)} "
                f"(v.g_j(t) <= 0 for all t >= 0; {c.proof.get('path')} proof)"
            ]
        return []

    def __str__(self) -> str:
        head = (
            f"positive output controllability: {self.verdict} ({self.method}; "
            f"impulse index {self.margin + 0.0:.4g} on [0, {self.margin_horizon:.4g}])"
        )
        return "\n".join([head, f"  {self.reason}", *self._certificate_lines()])

    def _repr_html_(self) -> str:
        return html_table(
            f"Positive output controllability: {self.verdict}",
            [
                ("method", self.method),
                ("reason", self.reason),
                (
                    "impulse index",
                    f"{self.margin + 0.0:.4g} (horizon {self.margin_horizon:.4g})",
                ),
                ("certificate", "\n".join(self._certificate_lines())),
            ],
        )


def poc_margin(res: POCResult) -> tuple[float, float]:
    """(lower, upper) bounds of mu_T on [0, ``res.margin_horizon``] (see
    :mod:`cdpm.analysis.margin`); clipped to <= 0 unless the verdict is YES."""
    return margin_bracket(
        res.A,
        res.B,
        res.C,
        res.sign_constrained,
        res.input_scale,
        res.output_weight,
        res.margin_horizon,
        res.verdict is Verdict.YES,
    )
