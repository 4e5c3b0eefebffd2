"""Pure linear-systems analysis of cable-driven manipulators (numpy/scipy).

Decides, with re-checkable certificates, positive output controllability
(paper Theorem 1), positive controllability (Brammer 1972), Kalman and
output controllability ranks, positive spanning and wrench closure. Takes
matrices only: no robot, no Pinocchio. See docs/analysis.md.
"""

from __future__ import annotations

from cdpm.analysis._common import Verdict
from cdpm.analysis.brammer import PositiveControllabilityResult, positive_controllability
from cdpm.analysis.certificate import POCCertificate
from cdpm.analysis.poc import POCResult, positive_output_controllability
from cdpm.analysis.rank import (
    ControllabilityResult,
    OutputControllabilityResult,
    controllability,
    output_controllability,
)
from cdpm.analysis.span import SpanCertificate, SpanResult, positively_spans, wrench_closure

__all__ = [
    "Verdict",
    "positive_output_controllability",
    "positive_controllability",
    "output_controllability",
    "controllability",
    "positively_spans",
    "wrench_closure",
    "POCResult",
    "POCCertificate",
    "PositiveControllabilityResult",
    "ControllabilityResult",
    "OutputControllabilityResult",
    "SpanResult",
    "SpanCertificate",
]
