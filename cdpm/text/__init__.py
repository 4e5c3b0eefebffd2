"""Reports for people and programs: the pose report (:mod:`~cdpm.text.report`)
and its text (:mod:`~cdpm.text.format`: numbers rounded to their scale,
outputs with units, the criteria and the cable table). The vocabulary every
layer writes with (lists of named values, strict JSON, notebook cells) is
:mod:`cdpm.printing`.
"""

from cdpm.text.report import PoseReport, analyze_pose

__all__ = ["PoseReport", "analyze_pose"]
