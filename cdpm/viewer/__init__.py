"""Look at a pose: a meshcat 3-D view and interactive pose inspection.

:class:`Viewer` draws a cable robot in meshcat (a WebGL viewer served on
127.0.0.1 and opened in a browser): the URDF's visual geometry (or generated
links when the URDF has none or its meshes cannot be loaded), the base
anchors and attachment points, the cables coloured by state, and the outputs
in the colour of the positive output controllability (POC) verdict at the
displayed pose: a marker on each output point, the axes of the frame of an
orientation output, a sleeve on a cable whose length is an output
(:mod:`cdpm.viewer.outputs`). :meth:`Viewer.display` moves everything to a new pose;
:meth:`Viewer.show_map` overlays a workspace map as a point cloud.

:func:`pose_state` computes what is drawn (positions, tensions, cable
states, verdict) without meshcat, so the headless picture
(:mod:`cdpm.plotting.picture`) and the text panel of :class:`PoseInspector` share it.

Cable states (:class:`CableState`), from the linearisation at the pose:

- ``taut``: the equilibrium tension is above the cable's lower bound, so the
  tension can change both ways; drawn in blue, darker with more tension.
- ``slack``: the cable sits at its lower bound (zero tension by default);
  it can only pull more (a sign-constrained input); drawn in pink.
- ``unavailable``: no equilibrium or linearisation at this pose (e.g. gravity
  without an equilibrium, a zero-length cable); drawn in grey, verdict grey.

meshcat, ipywidgets and matplotlib are optional (``pip install "cdpm[viz]"``)
and imported only when a viewer, a widget or a picture is made.

Modules, each importing only those above it:

- :mod:`cdpm.viewer.outputs`: where each output is drawn, from the spec;
- :mod:`cdpm.viewer.state`: the pose state and colours (no meshcat);
- :mod:`cdpm.viewer.coordinates`: slider ranges and units of the coordinates;
- :mod:`cdpm.viewer.server`: the meshcat server process (loopback only)
  and the host and origin checks of both web servers;
- :mod:`cdpm.viewer.overlay`: workspace-map points and their colours;
- :mod:`cdpm.viewer.output_marks`: the outputs' marks in the meshcat scene;
- :mod:`cdpm.viewer.scene`: the meshcat scene, :class:`Viewer`;
- :mod:`cdpm.viewer.inspector`: notebook sliders, :class:`PoseInspector`;
- :mod:`cdpm.viewer.panel`: every verdict at a pose, :func:`pose_panel`;
- :mod:`cdpm.viewer.page`: the inspection page of ``cdpm view``,
  :class:`InspectionPage` (the standard library's HTTP server, which also
  serves the scene on the page's origin; the page's files are in
  ``cdpm/viewer/static``).
"""

from __future__ import annotations

from cdpm.viewer.coordinates import CoordinateRange, coordinate_ranges, coordinate_sliders
from cdpm.viewer.inspector import PoseInspector
from cdpm.viewer.overlay import VERDICT_CODES, check_map_spec, map_points  # noqa: F401
from cdpm.viewer.page import InspectionPage
from cdpm.viewer.panel import PosePanel, pose_panel
from cdpm.viewer.scene import Viewer
from cdpm.viewer.server import LOOPBACK, check_port
from cdpm.viewer.state import (  # noqa: F401
    COLORS,
    CableState,
    PoseState,
    cable_colors,
    pose_state,
    tension_scale,
)

# map_points, cable_colors and tension_scale stay importable from here, as
# before the split, without joining __all__

__all__ = [
    "CableState",
    "PoseState",
    "pose_state",
    "coordinate_ranges",
    "coordinate_sliders",
    "CoordinateRange",
    "Viewer",
    "PoseInspector",
    "PosePanel",
    "pose_panel",
    "InspectionPage",
    "check_map_spec",
    "check_port",
    "LOOPBACK",
    "COLORS",
    "VERDICT_CODES",
]
