"""The nonlinear robot driven by pull-only cables: steering its output to a
target (:mod:`~cdpm.steering.shooting`) and checking a verdict by steering
towards targets all around the pose's output (:mod:`~cdpm.steering.verify`).
"""

from cdpm.steering.shooting import SteerResult, steer
from cdpm.steering.verify import VerifyReport, verify_pose

__all__ = ["SteerResult", "steer", "VerifyReport", "verify_pose"]
