"""Certified boxes: enclosures, over boxes of poses, of what the POC test
needs, with round-off accounted for (docs/analysis.md, "Certified boxes").

Modules: :mod:`~cdpm.certify.interval` (interval arithmetic on numpy
arrays, rounded outward), :mod:`~cdpm.certify.jet` (intervals with their
derivatives, for mean-value forms), :mod:`~cdpm.certify.kinematics`
(enclosures of a robot's joint placements, cable points, L, outputs, C_q
and mass matrix over a box), :mod:`~cdpm.certify.box` (:func:`certify_box`:
a POC verdict proven on a whole box, and its certificate) and
:mod:`~cdpm.certify.subdivide` (cells bisected level by level until
proven), :mod:`~cdpm.certify.map` (:func:`certify_map`: a grid of cells
certified in chunks, on local workers or Dask, and certified regions) and
:mod:`~cdpm.certify.store` (the zarr store of a certified map).
"""

from cdpm.certify.box import BoxCertificate, CertifiedBoxes, certify_box, certify_boxes
from cdpm.certify.interval import Interval
from cdpm.certify.kinematics import BoxKinematics, box_kinematics
from cdpm.certify.map import CertifiedMap, certify_map, open_certified

__all__ = [
    "Interval",
    "BoxKinematics",
    "box_kinematics",
    "BoxCertificate",
    "certify_box",
    "CertifiedBoxes",
    "certify_boxes",
    "CertifiedMap",
    "certify_map",
    "open_certified",
]
