"""The one batch pipeline: poses -> kinematics -> equilibria -> linearisations
-> analysis -> one array per map criterion.

:func:`evaluate_poses` runs it on poses given by the caller (a map's chunk,
a neighbourhood's samples, one pose of :func:`cdpm.analyze_pose`);
:mod:`~cdpm.pipeline.criteria` is the registry of what every map stores;
:mod:`~cdpm.pipeline.compiled` loads the compiled kernels ahead of use.
"""

from cdpm.pipeline.criteria import CRITERIA, Criterion, PoseBatch, register
from cdpm.pipeline.evaluate import (
    STATUS_CODES,
    VERDICT_CODES,
    MapJob,
    evaluate_batch,
    evaluate_poses,
    resolve_tension,
)

__all__ = [
    "CRITERIA",
    "Criterion",
    "PoseBatch",
    "register",
    "STATUS_CODES",
    "VERDICT_CODES",
    "MapJob",
    "evaluate_batch",
    "evaluate_poses",
    "resolve_tension",
]
