"""The outputs in the meshcat scene: markers, orientation triads and
emphasised cables (:mod:`cdpm.viewer.outputs` says which output gets what).

:class:`OutputMarks` sends them through the viewer's ``send`` (path,
method, arguments), so it needs meshcat's geometry module but no server of
its own. Paths under ``/meshcat/cdpm``:

- ``output/<point>``: placed on the output point, oriented as the point's
  frame; ``output/<point>/marker`` a sphere in the verdict colour;
- ``output/<point>/triad/<x|y|z>/shaft`` and ``.../head``: the frame's axes
  (arrows, x red, y green, z blue) at a point where an orientation output is
  drawn;
- ``cables/<cable>/<k>/output``: a translucent sleeve in the verdict colour
  around each segment of a cable whose length is an output.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from cdpm.viewer.outputs import OutputDrawing
from cdpm.viewer.state import AXIS_RGB

__all__ = ["OutputMarks", "MARKER_SIZE", "TRIAD_SIZE", "rgb_int", "segment_transform"]

#: Radius of an output marker, as a fraction of the scene's size.
MARKER_SIZE = 0.035
#: Length of an orientation triad's axes, as a fraction of the scene's size.
TRIAD_SIZE = 0.3


def rgb_int(rgb: tuple[float, float, float]) -> int:
    """``(r, g, b)`` in 0..1 -> meshcat's colour integer ``0xRRGGBB``."""
    r, g, b = (int(round(255 * min(max(c, 0.0), 1.0))) for c in rgb)
    return (r << 16) | (g << 8) | b


def segment_transform(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Transform taking meshcat's unit cylinder (height 1 along y, centred)
    to the segment a -> b (4, 4); the cylinder's top (+y) ends at b."""
    d = b - a
    length = float(np.linalg.norm(d))
    T = np.eye(4)
    T[:3, 3] = 0.5 * (a + b)
    if length < 1e-12:
        T[:3, :3] = np.diag([1.0, 1e-6, 1.0])
        return T
    y = d / length
    helper = np.array([1.0, 0.0, 0.0]) if abs(y[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(y, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    T[:3, 0], T[:3, 1], T[:3, 2] = x, y * length, z
    return T


class OutputMarks:
    """Output markers, triads and cable sleeves of one viewer's scene.

    Args:
        send: ``send(path, method, *args)`` on the viewer's meshcat root.
        geometry: meshcat's ``geometry`` module.
        drawing: how the robot's outputs are drawn.
        cable_names: the robot's cable names (m,).
        cable_segments: number of straight segments of each cable (m,).
        size: the scene's size [m] (markers and triads scale with it).
    """

    def __init__(
        self,
        send: Callable[..., None],
        geometry: Any,
        drawing: OutputDrawing,
        cable_names: tuple[str, ...],
        cable_segments: list[int],
        size: float,
    ) -> None:
        self._send, self._g, self._size = send, geometry, size
        self.point_names = tuple(point.name for point in drawing.points)
        self._sleeves = [
            f"cdpm/cables/{cable_names[i]}/{k}/output"
            for i in sorted(drawing.cables)
            for k in range(cable_segments[i])
        ]
        self._color: tuple[float, float, float] | None = None
        for point in drawing.points:
            if point.rotation:
                self._build_triad(f"cdpm/output/{point.name}/triad")

    def _build_triad(self, path: str) -> None:
        g, s = self._g, self._size
        length, radius = TRIAD_SIZE * s, 0.008 * s
        head = 0.22 * length
        for axis, (name, rgb) in enumerate(zip("xyz", AXIS_RGB, strict=True)):
            material = g.MeshPhongMaterial(color=rgb_int(rgb))
            direction = np.eye(3)[axis]
            tip, neck = length * direction, (length - head) * direction
            self._send(f"{path}/{name}/shaft", "set_object", g.Cylinder(1.0, radius), material)
            self._send(
                f"{path}/{name}/shaft", "set_transform", segment_transform(np.zeros(3), neck)
            )
            cone = g.Cylinder(1.0, radiusTop=0.0, radiusBottom=2.6 * radius)
            self._send(f"{path}/{name}/head", "set_object", cone, material)
            self._send(f"{path}/{name}/head", "set_transform", segment_transform(neck, tip))

    @property
    def color(self) -> tuple[float, float, float] | None:
        """Colour (r, g, b in 0..1) the markers are drawn in (None before the first)."""
        return self._color

    def set_color(self, rgb: tuple[float, float, float]) -> None:
        """Colour the markers and sleeves (the POC verdict's colour); sends
        nothing when the colour is unchanged."""
        if self._color == rgb:
            return
        g, s = self._g, self._size
        solid = g.MeshPhongMaterial(color=rgb_int(rgb))
        for name in self.point_names:
            self._send(f"cdpm/output/{name}/marker", "set_object", g.Sphere(MARKER_SIZE * s), solid)
        sleeve = g.MeshPhongMaterial(color=rgb_int(rgb), transparent=True, opacity=0.4)
        for path in self._sleeves:
            self._send(path, "set_object", g.Cylinder(1.0, 0.012 * s), sleeve)
        self._color = rgb

    def place(self, placements: list[np.ndarray]) -> None:
        """Move each output point's node to its world placement (4, 4)."""
        for name, T in zip(self.point_names, placements, strict=True):
            self._send(f"cdpm/output/{name}", "set_transform", T)
