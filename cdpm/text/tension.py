"""Text and JSON of the choice of tension: the feasible equilibrium
tensions of a pose (:class:`~cdpm.dynamics.tension_choice.range.TensionRange`)
and the tension search (:class:`~cdpm.dynamics.tension_choice.best.BestTension`,
``cdpm analyze --tension best``)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from cdpm.dynamics.tension_choice.best import EXACT_AND_SAMPLED
from cdpm.printing import strict
from cdpm.text.format import tension_texts
from cdpm.verdicts import NOT_ANALYSED, VERDICT_LABELS, YES

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.dynamics.tension_choice.best import BestTension
    from cdpm.dynamics.tension_choice.range import TensionRange


# -------------------------------------------------------------- the range


def tension_range_lines(r: TensionRange) -> list[str]:
    """The feasible tensions as a table, one line each: per cable its
    bounds, least, greatest and interior-point tension [N] and its state."""
    if not r.feasible:
        return [
            "Feasible equilibrium tensions: none (no tension within the cable bounds holds "
            "the pose)"
        ]
    d = r.null_space.shape[1]
    head = [
        f"Feasible equilibrium tensions (LPs, exact): rank L^T = {r.rank}, {d} "
        f"internal-force direction{'s' if d != 1 else ''} (null space of L^T)",
        f"  {'name':<12} {'bounds [N]':>18} {'least [N]':>11} {'greatest [N]':>13} "
        f"{'interior [N]':>13}  state",
    ]
    states = r.cable_states()
    for i, name in enumerate(r.cable_names):
        bounds = f"[{r.tension_min[i]:g}, {r.tension_max[i]:g}]"
        head.append(
            f"  {name:<12} {bounds:>18} {_num(r.least[i]):>11} "
            f"{_num(r.greatest[i]):>13} {_num(r.interior[i]):>13}  "
            f"{states[i]}"
        )
    if np.any(~np.isfinite(r.tension_max)):
        head.append(
            f"  interior point: smallest distance {r.interior_slack:.4g} N of the cables "
            f"that can move to their bounds; cables without an upper bound capped at "
            f"{r.tension_cap:.4g} N"
        )
    else:
        head.append(
            f"  interior point: smallest distance {r.interior_slack:.4g} N of the cables "
            "that can move to their bounds"
        )
    return head


def tension_range_text(r: TensionRange) -> str:
    """:func:`tension_range_lines` as one text."""
    return "\n".join(tension_range_lines(r))


def tension_range_json(r: TensionRange) -> dict:
    """Strict-JSON data of the feasible tensions (an infinite or undefined
    tension is null), one entry per cable in ``cables``."""
    return strict(
        {
            "feasible": r.feasible,
            "q": r.q,
            "rank": r.rank,
            "null_space_dimension": int(r.null_space.shape[1]),
            "null_space": r.null_space,
            "tension_cap": r.tension_cap,
            "interior_slack": r.interior_slack,
            "load": r.load,
            "n_lps": r.n_lps,
            "cables": [
                {
                    "name": name,
                    "tension_min": r.tension_min[i],
                    "tension_max": r.tension_max[i],
                    "least": r.least[i],
                    "greatest": r.greatest[i],
                    "can_be_slack": r.can_be_slack[i],
                    "must_be_slack": r.must_be_slack[i],
                    "can_be_taut": r.can_be_taut[i],
                    "interior": r.interior[i],
                    "state": state,
                }
                for i, (name, state) in enumerate(zip(r.cable_names, r.cable_states(), strict=True))
            ],
        }
    )


def _num(x: float) -> str:
    if not np.isfinite(x):
        return "inf" if x > 0 else "-"
    return f"{x + 0.0:.6g}"


# ------------------------------------------------------------- the search


def best_tension_lines(best: BestTension) -> list[str]:
    """The tension search in words, one line each: the verdict, the
    default and the chosen tension with their r_T, the tensions and how
    they were found (without the range: :func:`best_tension_text`)."""
    r, err = best.reach_margin
    default = VERDICT_LABELS[int(best.default_verdict)].upper()
    if int(best.default_verdict) == NOT_ANALYSED:
        default += f" (method {best.default_method!r} finds no equilibrium here)"
    else:
        default += (
            f", r_T = {_margin(best.default_margin, best.margin_unit)} ({best.default_method})"
        )
    what = {
        YES: "YES: this feasible tension makes the pose POC (certified)",
    }.get(
        int(best.poc_possible),
        f"{best.verdict.upper()}: none of the {best.n_candidates} tensions tried is POC",
    )
    exact = "exact" if err == 0 else f"at most {err:.2g} more"
    gain = r - best.default_margin
    if int(best.default_verdict) == YES and math.isfinite(gain) and 0 < gain <= err:
        exact += "; its gain over the default is within this error bound"
    return [
        f"Best tension (objective {best.objective}): {what}",
        f"  default tension: {default}",
        f"  chosen tension: {best.found_by}; r_T = {_margin(r, best.margin_unit)} "
        f"({exact}); POC "
        f"{best.poc.verdict.value.upper()} ({best.poc.method})",
        f"  tension [N]: {_tensions(best)}",
        f"  {best.n_candidates} tensions evaluated, {best.n_yes} of them POC; {best.method}",
        f"  {EXACT_AND_SAMPLED}",
    ]


def _tensions(best: BestTension) -> str:
    """``"c1 = 31.0921, c2 = 3.5e-09"``: the chosen tension [N] as the
    cable tables print it (a taut cable never as 0)."""
    at_bound = best.linearisation.sign_constrained
    texts = tension_texts(best.tension, at_bound)
    return ", ".join(f"{n} = {t}" for n, t in zip(best.cable_names, texts, strict=True))


def best_tension_text(best: BestTension) -> str:
    """The pose's feasible tensions and the search, as ``cdpm analyze
    --tension best`` prints them."""
    return "\n".join([*tension_range_lines(best.tension_range), *best_tension_lines(best)])


def best_tension_json(best: BestTension) -> dict:
    """Strict-JSON data of the search (non-finite numbers are null), the
    POC result's certificate and the pose's tension range included."""
    return strict(
        {
            "poc_possible": best.verdict,
            "objective": best.objective,
            "tension": dict(zip(best.cable_names, best.tension.tolist(), strict=True)),
            "found_by": best.found_by,
            "reach_margin": best.reach_margin[0],
            "reach_margin_error": best.reach_margin[1],
            "poc": best.poc.as_dict(),
            "sign_constrained": best.linearisation.sign_constrained,
            "default": {
                "method": best.default_method,
                "tension": dict(zip(best.cable_names, best.default_tension.tolist(), strict=True)),
                "verdict": VERDICT_LABELS[int(best.default_verdict)],
                "reach_margin": best.default_margin,
            },
            "n_candidates": best.n_candidates,
            "n_yes": best.n_yes,
            # the cap used (the default's value when none was given)
            "search": {**best.search.as_dict(), "tension_cap": best.tension_range.tension_cap},
            "reach": best.reach.as_dict(),
            "method": best.method,
            "exact_and_sampled": EXACT_AND_SAMPLED,
            "tension_range": tension_range_json(best.tension_range),
        }
    )


def _margin(r: float, unit: str) -> str:
    return f"{r + 0.0:.4g} {unit}" if math.isfinite(r) else "not resolvable"
