"""Reports for people and programs: the pose report (:mod:`~cdpm.text.report`)
and its text (:mod:`~cdpm.text.format`: numbers rounded to their scale,
outputs with units, the criteria and the cable table); the text and
strict-JSON data of the other results, as functions of the result: steering
and verification (:mod:`~cdpm.text.steering`), neighbourhoods and paths
(:mod:`~cdpm.text.regions`), the choice of tension
(:mod:`~cdpm.text.tension`). The results themselves print a short summary.
The vocabulary every layer writes with (lists of named values, numbers to
their scale, strict JSON, notebook cells) is :mod:`cdpm.printing`.
"""

from cdpm.text.regions import (
    neighbourhood_json,
    neighbourhood_lines,
    neighbourhood_text,
    path_json,
    path_text,
    path_warnings,
    sampled_pose_json,
)
from cdpm.text.report import PoseReport, analyze_pose
from cdpm.text.steering import (
    direction_text,
    steer_json,
    steer_text,
    tension_profile_text,
    verify_json,
    verify_text,
)
from cdpm.text.tension import (
    best_tension_json,
    best_tension_lines,
    best_tension_text,
    tension_range_json,
    tension_range_lines,
    tension_range_text,
)

__all__ = [
    "PoseReport",
    "analyze_pose",
    "steer_text",
    "steer_json",
    "tension_profile_text",
    "verify_text",
    "verify_json",
    "direction_text",
    "neighbourhood_lines",
    "neighbourhood_text",
    "neighbourhood_json",
    "sampled_pose_json",
    "path_text",
    "path_warnings",
    "path_json",
    "tension_range_lines",
    "tension_range_text",
    "tension_range_json",
    "best_tension_lines",
    "best_tension_text",
    "best_tension_json",
]
