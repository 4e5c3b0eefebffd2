"""The nonlinear robot driven by pull-only cables: steering its output to a
target (:mod:`~cdpm.steering.shooting`) and checking a verdict by steering
towards targets all around the pose's output (:mod:`~cdpm.steering.verify`);
targets no pose has are refused first (:mod:`~cdpm.steering.output_range`).
"""

from cdpm.steering.output_range import output_range
from cdpm.steering.shooting import SteerResult, TargetOutOfRangeError, steer
from cdpm.steering.verify import VerifyReport, verify_pose

__all__ = [
    "SteerResult",
    "TargetOutOfRangeError",
    "steer",
    "VerifyReport",
    "verify_pose",
    "output_range",
]
