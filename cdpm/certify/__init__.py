"""Certified boxes: enclosures, over boxes of poses, of what the POC test
needs, with round-off accounted for (shared THEORY.md section 6).

Modules: :mod:`~cdpm.certify.interval` (interval arithmetic on numpy
arrays, rounded outward), :mod:`~cdpm.certify.jet` (intervals with their
derivatives, for mean-value forms), :mod:`~cdpm.certify.kinematics`
(enclosures of a robot's joint placements, cable points, L, outputs, C_q
and mass matrix over a box), :mod:`~cdpm.certify.box` (:func:`certify_box`:
a POC verdict proven on a whole box, and its certificate) and
:mod:`~cdpm.certify.map` (:func:`certify_map`: a grid of cells subdivided
until proven, and certified regions).
"""

from cdpm.certify.box import BoxCertificate, certify_box
from cdpm.certify.interval import Interval
from cdpm.certify.kinematics import BoxKinematics, box_kinematics
from cdpm.certify.map import CertifiedMap, certify_map

__all__ = [
    "Interval",
    "BoxKinematics",
    "box_kinematics",
    "BoxCertificate",
    "certify_box",
    "CertifiedMap",
    "certify_map",
]
