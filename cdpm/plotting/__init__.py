"""Pictures: workspace maps (:mod:`~cdpm.plotting.map_plot`: :func:`plot_map`,
:func:`save_map_plot`), a pose of the robot (:func:`cdpm.plotting.picture.render_pose`,
also ``cdpm.render_pose``) and motions (:mod:`~cdpm.plotting.trajectories`:
:func:`plot_trajectory`, :func:`plot_verify_report`).

matplotlib is imported on first use (:func:`cdpm.plotting._common.matplotlib_parts`,
cdpm's one import of it), with an install hint when it is missing.
"""

from cdpm.plotting.map_plot import (
    VERDICT_COLORS,
    check_dpi,
    check_image_path,
    check_output_folder,
    image_formats,
    plot_map,
    save_map_plot,
)
from cdpm.plotting.trajectories import plot_trajectory, plot_verify_report

__all__ = [
    "plot_map",
    "save_map_plot",
    "image_formats",
    "check_image_path",
    "check_output_folder",
    "check_dpi",
    "VERDICT_COLORS",
    "plot_trajectory",
    "plot_verify_report",
]
