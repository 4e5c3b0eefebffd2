"""A workspace map over the 3-D view: points coloured by a map criterion.

:func:`map_points` turns a map (``xarray.Dataset``) into positions and RGB
colours (verdict colours from :mod:`cdpm.verdicts`, the same as the plots'),
which :meth:`cdpm.viewer.Viewer.show_map` sends to meshcat;
:func:`check_map_spec` refuses a map made from another spec.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cdpm import verdicts
from cdpm.errors import InputError
from cdpm.pipeline.criteria import CRITERIA
from cdpm.verdicts import NO, NOT_ANALYSED, VERDICT_RGB, YES
from cdpm.viewer.state import COLORS

__all__ = ["map_points", "check_map_spec", "color_choices", "VERDICT_CODES"]

#: short names of ``color_by``: the POC verdict and the reach margin
_ALIASES = {"verdict": "poc", "margin": "reach_margin"}


def color_choices() -> tuple[str, ...]:
    """Values ``color_by`` accepts: ``verdict``, ``margin`` and every map
    criterion with a plot hint (:data:`cdpm.pipeline.criteria.CRITERIA`)."""

    return (*_ALIASES, *(name for name, c in CRITERIA.items() if c.plot is not None))


#: Codes of the ``poc`` variable of a workspace map (``flag_values``): code ->
#: name, the inverse of :data:`cdpm.verdicts.VERDICT_CODES` (name -> code).
VERDICT_CODES: dict[int, str] = {code: name for name, code in verdicts.VERDICT_CODES.items()}


def check_map_spec(
    dataset, robot, *, override: str | None = "check_spec=False", use: str = "view it"
) -> None:
    """Refuse a map made from another spec than ``robot``'s.

    A map records the sha256 of its spec file and URDF (attribute
    ``spec_sha256``, the hash :func:`cdpm.load_robot` computes as
    ``robot.spec.sha256``); a map without it (e.g. made by hand) is not checked.

    Args:
        dataset: the map (``xarray.Dataset``).
        robot: the robot it is to be shown with.
        override: how the caller skips this check, named in the message
            (None: it cannot be skipped).
        use: what the message offers to do with the map and its own spec.

    Raises:
        InputError: the hashes differ; the message names both spec files.
    """
    stored = getattr(dataset, "attrs", {}).get("spec_sha256")
    if not stored or stored == robot.spec.sha256:
        return
    store = getattr(dataset, "encoding", {}).get("source")
    made_from = dataset.attrs.get("spec", "another spec")
    spec, now = robot.spec.path, robot.spec.sha256
    if str(made_from) == str(spec):
        source = f"an earlier version of {spec} or its URDF (sha256 {stored[:12]}, now {now[:12]})"
    else:
        source = f"{made_from} (sha256 {stored[:12]}), not from {spec} (sha256 {now[:12]})"
    what = f"map {store}" if store else "the map"
    if str(made_from) == str(spec):  # this spec's own map, made before an edit: remake it
        rerun = f"`cdpm map {spec} ... --out {store} --overwrite`" if store else "it with this spec"
        fix = f"re-run {rerun}"
    else:  # another robot's map: keep it, make this spec's map into a new store
        new = f"`cdpm map {spec} ... --out {_new_store(store, spec)}`"
        fix = f"make a map of this spec into a new store ({new})"
    anyway = f" ({override} overlays it anyway)" if override else ""
    raise InputError(
        f"{what} was made from {source}; {fix} or {use} with the spec it was made from{anyway}"
    )


def _new_store(store, spec) -> str:
    """A store path for a map of ``spec`` that is neither ``store`` nor an
    existing path: ``SPEC_STEM.zarr`` beside ``store`` (numbered if taken)."""

    folder = Path(store).parent if store else Path(".")
    stem = Path(spec).stem
    for k in range(1, 1000):
        candidate = folder / (f"{stem}.zarr" if k == 1 else f"{stem}-{k}.zarr")
        if not candidate.exists() and (not store or candidate != Path(store)):
            return str(candidate)
    return str(folder / f"{stem}-new.zarr")


def map_points(dataset, *, color_by: str = "verdict", position: str = "output_frame_position"):
    """Positions (n, 3) [m] and RGB colours (n, 3) of a workspace map's poses.

    See :meth:`cdpm.viewer.Viewer.show_map` for the dataset contract. Poses whose
    position is not finite are left out.
    """

    choices = color_choices()
    if color_by not in choices:
        raise InputError(f"color_by={color_by!r}; use one of {', '.join(choices)}")
    needed = _ALIASES.get(color_by, color_by)
    hint = CRITERIA[needed].plot
    for var in (position, needed):
        if var not in getattr(dataset, "data_vars", {}):
            have = ", ".join(getattr(dataset, "data_vars", {})) or "none"
            raise InputError(
                f"the map has no variable {var!r} (it has: {have}); "
                "make it with the workspace-map command or pass position=/color_by="
            )
    pos = dataset[position]
    if "xyz" not in pos.dims or pos.sizes["xyz"] != 3:
        raise InputError(f"{position} must have a dimension 'xyz' of size 3, got dims {pos.dims}")
    pose_dims = [d for d in pos.dims if d != "xyz"]
    positions = pos.transpose(*pose_dims, "xyz").values.reshape(-1, 3).astype(float)
    values = dataset[needed].transpose(*pose_dims).values.reshape(-1)
    if values.shape[0] != positions.shape[0]:
        raise InputError(
            f"{needed} has dims {dataset[needed].dims}, expected the pose dims {tuple(pose_dims)}"
        )
    if hint == "verdict":
        codes = values.astype(int)
        unknown = VERDICT_RGB[NOT_ANALYSED]
        colors = np.array([VERDICT_RGB.get(int(c), unknown) for c in codes], dtype=float).reshape(
            -1, 3
        )
    elif hint == "diverging":
        colors = _margin_colors(values.astype(float))
    elif needed == "reach_margin":
        colors = _log_margin_colors(values.astype(float))
    else:
        colors = _sequential_colors(values.astype(float), fill=CRITERIA[needed].fill)
    keep = np.all(np.isfinite(positions), axis=1)
    return positions[keep], colors[keep]


def _log_margin_colors(margin: np.ndarray) -> np.ndarray:
    """Reach margins: light (small) to dark (large) blue on a log scale from
    the 1st to the 99th percentile of the positive margins (clipped beyond,
    so a few stragglers do not flatten it), zero margins red as a NO,
    non-finite grey."""
    positive = np.isfinite(margin) & (margin > 0)
    logs = np.log10(np.where(positive, margin, 1.0))
    if positive.any():
        lo, hi = np.percentile(logs[positive], [1.0, 99.0])
    else:
        lo, hi = 0.0, 1.0
    t = np.clip((logs - lo) / ((hi - lo) or 1.0), 0.0, 1.0)[:, None]
    light, dark = np.array(COLORS["taut_low"]), np.array(COLORS["taut_high"])  # cables' ramp
    out = light + t * (dark - light)
    out[np.isfinite(margin) & (margin == 0)] = VERDICT_RGB[NO]
    out[~np.isfinite(margin)] = VERDICT_RGB[NOT_ANALYSED]
    return out


def _sequential_colors(values: np.ndarray, fill) -> np.ndarray:
    """Light (smallest) to dark (largest) blue; the criterion's fill value
    (not computed) and non-finite values grey."""
    valid = np.isfinite(values) & (values != fill)
    lo = float(values[valid].min()) if valid.any() else 0.0
    hi = float(values[valid].max()) if valid.any() else 1.0
    t = np.clip((np.where(valid, values, lo) - lo) / ((hi - lo) or 1.0), 0.0, 1.0)[:, None]
    light, dark = np.array(COLORS["taut_low"]), np.array(COLORS["taut_high"])  # cables' ramp
    out = light + t * (dark - light)
    out[~valid] = VERDICT_RGB[NOT_ANALYSED]
    return out


def _margin_colors(margin: np.ndarray) -> np.ndarray:
    """Diverging colours: red (negative) - white (0) - green (positive)."""
    finite = np.isfinite(margin)
    scale = float(np.max(np.abs(margin[finite]))) if finite.any() else 1.0
    scale = scale or 1.0
    t = np.clip(np.where(finite, margin, 0.0) / scale, -1.0, 1.0)[:, None]
    white = np.ones(3)
    pos = white + t * (np.array(VERDICT_RGB[YES]) - white)
    neg = white - t * (np.array(VERDICT_RGB[NO]) - white)
    out = np.where(t >= 0, pos, neg)
    out[~finite] = VERDICT_RGB[NOT_ANALYSED]
    return out
