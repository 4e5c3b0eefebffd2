"""The robot model: a cable spec (YAML or parsed), its URDF, outputs and
coordinates, and the :class:`CableRobot` that evaluates kinematics, cable
Jacobians and Pinocchio's dynamics terms for batches of poses.

Modules: :mod:`~cdpm.model.spec` (the YAML cable spec, validated),
:mod:`~cdpm.model.outputs` (output definitions), :mod:`~cdpm.model.coordinates`
(coordinate names, kinds, units, ranges; natural and configuration values),
:mod:`~cdpm.model.poses` (batches of natural poses as configurations),
:mod:`~cdpm.model.robot` (the robot), :mod:`~cdpm.model.kinematics` (batched
kinematics), :mod:`~cdpm.model.tension_methods` (the equilibrium methods a
spec may name).
"""

from cdpm.model.robot import CableRobot, load_robot
from cdpm.model.spec import CableSpec, load_spec

__all__ = ["CableSpec", "load_spec", "CableRobot", "load_robot"]
