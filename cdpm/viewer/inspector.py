"""Interactive pose inspection: sliders over the natural coordinates.

:class:`PoseInspector` drives a :class:`cdpm.viewer.Viewer` (or only a text
panel) from one slider per natural coordinate in a notebook;
:func:`coordinate_ranges` (:mod:`cdpm.viewer.coordinates`) gives the slider
ranges. ipywidgets is imported when the widget is made.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

from cdpm.errors import InputError, MissingExtraError
from cdpm.viewer.coordinates import coordinate_ranges
from cdpm.viewer.state import PoseState, default_pose, pose_state

if TYPE_CHECKING:  # pragma: no cover - for static type checkers only
    from cdpm.model.robot import CableRobot
    from cdpm.viewer.scene import Viewer

__all__ = ["PoseInspector", "coordinate_ranges"]


class PoseInspector:
    """Sliders over the natural coordinates driving a viewer and a text panel.

    The update logic lives here (not in a notebook) so that it is testable
    and timed: :meth:`set_coordinate` is what a slider change calls.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: first pose; default the spec's first pose, else neutral.
        viewer: a :class:`Viewer` to update, or None for the text panel only.

    Attributes:
        natural: current natural coordinates (nv,).
        ranges: slider range of each coordinate (:func:`coordinate_ranges`).
        state: the current :class:`PoseState`.
        update_seconds: wall time of each update since creation [s].
    """

    def __init__(self, robot: CableRobot, q: Any = None, *, viewer: Viewer | None = None) -> None:
        self.robot = robot
        self.viewer = viewer
        q0 = robot.as_q(default_pose(robot) if q is None else q)
        self.natural = robot.to_natural(q0)
        self.ranges = coordinate_ranges(robot, self.natural)
        self.update_seconds: list[float] = []
        self.sliders: dict[str, Any] = {}
        self.panel = None
        self.state = self._update()

    def _update(self) -> PoseState:
        t0 = time.perf_counter()
        if self.viewer is not None:
            state = self.viewer.display(self.natural)
        else:
            state = pose_state(self.robot, self.natural)
        self.state = state
        if self.panel is not None:
            self.panel.value = state._repr_html_()
        self.update_seconds.append(time.perf_counter() - t0)
        return state

    @property
    def text(self) -> str:
        """The text panel: verdict, margin, pose, tensions, slack cables."""
        return str(self.state)

    def set_coordinate(self, name: str, value: float) -> PoseState:
        """Set one natural coordinate [rad or m] and update the view and panel."""
        names = list(self.robot.coordinate_names)
        if name not in names:
            raise InputError(f"no coordinate {name!r}; coordinates: {', '.join(names)}")
        value = float(value)
        if not math.isfinite(value):
            raise InputError(f"{name} = {value!r} is not a finite number")
        natural = self.natural.copy()
        natural[names.index(name)] = value
        self.natural = natural
        return self._update()

    def set_natural(self, natural: Any) -> PoseState:
        """Set all natural coordinates (nv,) and update the view and panel."""
        q = self.robot.as_q(natural)
        self.natural = self.robot.to_natural(q)
        for name, v in zip(self.robot.coordinate_names, self.natural, strict=True):
            slider = self.sliders.get(name)
            if slider is not None:
                with slider.hold_trait_notifications():
                    slider.unobserve(self._on_slider, names="value")
                    slider.value = float(v)
                    slider.observe(self._on_slider, names="value")
        return self._update()

    def _on_slider(self, change) -> None:
        self.set_coordinate(change["owner"].description, change["new"])

    def widget(self, steps: int = 200):
        """ipywidgets box: one slider per coordinate, then the text panel.

        Args:
            steps: number of slider steps across each range.

        Raises:
            MissingExtraError: ipywidgets is not installed.
        """
        try:
            # optional: cdpm[viz]
            import ipywidgets as widgets
        except ImportError as exc:
            raise MissingExtraError(
                f'the sliders need ipywidgets ({exc}); install it with: pip install "cdpm[viz]"'
            ) from exc
        self.sliders = {}
        for name, (lo, hi) in self.ranges.items():
            value = float(self.natural[list(self.robot.coordinate_names).index(name)])
            slider = widgets.FloatSlider(
                value=value,
                min=lo,
                max=hi,
                step=(hi - lo) / steps,
                description=name,
                continuous_update=True,
                readout_format=".3f",
                layout=widgets.Layout(width="480px"),
            )
            slider.observe(self._on_slider, names="value")
            self.sliders[name] = slider
        self.panel = widgets.HTML(self.state._repr_html_())
        return widgets.VBox([*self.sliders.values(), self.panel])
