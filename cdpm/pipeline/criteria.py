"""Per-pose criteria: every quantity a map stores, registered once.

A :class:`Criterion` names a map variable, its dtype and fill value, its
meaning (a flag table for verdict codes, or units), the batched function
that computes it from a :class:`PoseBatch` and hints for plots. The map
store's schema, :func:`cdpm.evaluate_poses`, :func:`cdpm.analyze_pose`'s
report, ``cdpm plot``'s variable choices and the viewer's map overlay all
read :data:`CRITERIA`.

Adding a criterion: write its function (``PoseBatch -> (N, ...) array``),
add its entry with :func:`register` (here or in your own module) and a
test. Nothing else changes: stores, reports, plots and help pick it up.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.reach import reach_margins_at, reach_unit
from cdpm.errors import InputError
from cdpm.verdicts import NO, NOT_ANALYSED, STATUS_CODES, VERDICT_CODES

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.analysis.batch import SystemVerdicts
    from cdpm.dynamics.equilibrium.methods import EquilibriumBatch
    from cdpm.dynamics.linearisation import LinearisationBatch
    from cdpm.dynamics.reach import ReachSettings
    from cdpm.model.kinematics import BatchKinematics
    from cdpm.model.robot import CableRobot

__all__ = [
    "Criterion",
    "PoseBatch",
    "CRITERIA",
    "CRITERION_DIMS",
    "register",
    "extra_size",
    "bytes_per_pose",
    "verdict_criteria",
    "missing_criteria_error",
]


@dataclass
class PoseBatch:
    """Everything the pipeline computed for N poses, for criteria to read.

    Attributes:
        robot: the robot.
        kin: batch kinematics with dynamics at the N poses.
        status: pose status codes (:data:`cdpm.verdicts.STATUS_CODES`), (N,).
        wrench_closure: verdict codes of wrench closure at the poses with
            well-defined cables (else NOT_ANALYSED), (N,).
        static_feasible: verdict codes of static feasibility, (N,).
        analysed: indices of the poses that were linearised and analysed, (k,).
        equilibrium: equilibria of the ``analysed`` poses (k of them), or None.
        linearisation: their linearisations, or None.
        verdicts: their analysis, or None.
        reach: horizon and tension budget of the reach margin, or None to
            skip it (its criteria are then NaN).
        tension_search: ``(TensionSearch, ReachSettings, tol)`` of the
            search over the feasible equilibrium tensions
            (:mod:`cdpm.pipeline.tension_criteria`), or None to skip it (its
            criteria are then NOT_ANALYSED / NaN).
    """

    robot: CableRobot
    kin: BatchKinematics
    status: np.ndarray
    wrench_closure: np.ndarray
    static_feasible: np.ndarray
    analysed: np.ndarray
    equilibrium: EquilibriumBatch | None = None
    linearisation: LinearisationBatch | None = None
    verdicts: SystemVerdicts | None = None
    reach: ReachSettings | None = None
    reach_cache: Any = field(default=None, repr=False)
    tension_search: Any = None
    tension_search_cache: Any = field(default=None, repr=False)

    def __len__(self) -> int:
        return int(self.status.shape[0])

    def scatter(self, values: np.ndarray, fill, dtype=None) -> np.ndarray:
        """An (N, ...) array with ``values`` (k, ...) at the analysed poses
        and ``fill`` elsewhere."""
        values = np.asarray(values)
        out = np.full((len(self),) + values.shape[1:], fill, dtype=dtype or values.dtype)
        out[self.analysed] = values
        return out


@dataclass(frozen=True)
class Criterion:
    """One per-pose quantity of a map.

    Attributes:
        name: the map variable's name.
        dtype: numpy dtype of the stored values (``int8`` codes, ``float64``...).
        fill: the value of poses not yet computed or not analysed.
        long_name: one line on what it is.
        compute: ``PoseBatch -> array`` of shape (N, *extra dims).
        flags: code name -> code for categorical values (verdicts, status),
            or None.
        units: units of a quantity (``"N"``, ``"m"``, ``"1"``), or None.
        dims: names of extra dimensions after the pose dimensions
            (``"output"``: one per output, ``"xyz"``: 3, ``"cable"``: one
            per cable).
        description: longer explanation for the store's attributes.
        plot: ``"verdict"`` (categorical verdict colours), ``"diverging"``
            (centred at 0), ``"sequential"``, or None (not offered by plots).
        robot_attrs: ``robot -> dict`` of store attributes that depend on
            the robot (e.g. a frame name), or None.
        on_request: computed only when asked for (e.g. the tension search),
            else left at ``fill``; reports list it only when computed.
    """

    name: str
    dtype: str
    fill: float | int
    long_name: str
    compute: Callable[[PoseBatch], np.ndarray]
    flags: dict[str, int] | None = None
    units: str | None = None
    dims: tuple[str, ...] = ()
    description: str = ""
    plot: str | None = None
    robot_attrs: Callable[[CableRobot], dict] | None = None
    on_request: bool = False

    @property
    def is_verdict(self) -> bool:
        """Values are verdict codes (:data:`cdpm.verdicts.VERDICT_CODES`)."""
        return self.flags is VERDICT_CODES

    def attrs(self, robot: CableRobot | None = None) -> dict:
        """The store attributes of its variable (for ``robot``)."""
        out: dict = {"long_name": self.long_name}
        if self.flags is not None:
            out["flag_values"] = [int(v) for v in self.flags.values()]
            out["flag_meanings"] = " ".join(self.flags)
        if self.units is not None:
            out["units"] = self.units
        if self.description:
            out["description"] = self.description
        if self.robot_attrs is not None and robot is not None:
            out.update(self.robot_attrs(robot))
        return out

    def itemsize(self, robot: CableRobot) -> int:
        """Bytes per pose."""
        size = np.dtype(self.dtype).itemsize
        for dim in self.dims:
            size *= extra_size(robot, dim)
        return size


def extra_size(robot: CableRobot, dim: str) -> int:
    """Length of a criterion's extra dimension ``dim`` (CRITERION_DIMS)
    for ``robot``: its outputs, its cables, or 3 (``xyz``)."""
    return {"output": robot.n_outputs, "cable": robot.n_cables}.get(dim, 3)


def bytes_per_pose(robot: CableRobot) -> int:
    """Bytes a map of ``robot`` holds per pose: every registered criterion's."""
    return sum(c.itemsize(robot) for c in CRITERIA.values())


#: name -> criterion, in store order
CRITERIA: dict[str, Criterion] = {}


#: extra dimensions a criterion may have, and their sizes' meaning
CRITERION_DIMS = ("output", "xyz", "cable")

#: names a criterion cannot take (the map's coordinates)
_RESERVED = ("sample", "output", "xyz", "cable")


def register(criterion: Criterion, *, replace: bool = False) -> Criterion:
    """Add a criterion to :data:`CRITERIA`.

    Register criteria at the top level of a module (not under
    ``if __name__ == "__main__":``): maps with several workers compute
    chunks in other processes, which import modules but do not run a
    script's main block.

    Args:
        criterion: the criterion.
        replace: replace a criterion of the same name (e.g. when a notebook
            cell runs twice) instead of refusing it.

    Raises:
        ValueError: the name is taken (without ``replace``) or not an
            identifier, the dtype is not a numpy dtype, or an extra
            dimension is not one of CRITERION_DIMS.
    """
    name = criterion.name
    if not (isinstance(name, str) and name.isidentifier()) or name in _RESERVED:
        raise ValueError(f"criterion name {name!r} must be an identifier other than {_RESERVED}")
    if name in CRITERIA and not replace:
        raise ValueError(
            f"criterion {name!r} is already registered; pass replace=True to replace it"
        )
    try:
        np.dtype(criterion.dtype)
    except TypeError as exc:
        raise ValueError(
            f"criterion {name!r}: dtype {criterion.dtype!r} is not a numpy dtype"
        ) from exc
    bad = [d for d in criterion.dims if d not in CRITERION_DIMS]
    if bad:
        raise ValueError(
            f"criterion {name!r}: extra dimensions {bad} are not supported; use "
            f"{CRITERION_DIMS} (one value per output, x, y, z, or one per cable)"
        )
    CRITERIA[name] = criterion
    return criterion


def missing_criteria_error(names) -> Exception | None:
    """The error for map variables not registered in this process (a
    worker that did not run the registration), or None."""
    missing = [n for n in names if n not in CRITERIA]
    if not missing:
        return None

    return InputError(
        f"criteria {', '.join(map(repr, missing))} are not registered in this worker process: "
        'workers import modules but do not run a script\'s `if __name__ == "__main__":` '
        "block. Register criteria at the top level of a module your script imports (or of "
        "the script, above the guard), or map with workers=1"
    )


def verdict_criteria() -> list[str]:
    """Names of the criteria whose values are verdict codes."""
    return [c.name for c in CRITERIA.values() if c.is_verdict]


# --------------------------------------------------------------------------
# the built-in criteria


def _verdict(field: str) -> Callable[[PoseBatch], np.ndarray]:
    def compute(batch: PoseBatch) -> np.ndarray:
        if batch.verdicts is None:
            return np.full(len(batch), NOT_ANALYSED, dtype=np.int8)
        return batch.scatter(getattr(batch.verdicts, field), NOT_ANALYSED, np.int8)

    return compute


def _reach(batch: PoseBatch):
    """The reach margins of the analysed poses (computed once per batch),
    or None when the batch skips them."""
    if batch.reach is None or batch.linearisation is None:
        return None
    cached = batch.reach_cache
    if cached is None:
        no = batch.verdicts.poc == NO
        cached = reach_margins_at(batch.robot, batch.linearisation, batch.reach, no)
        batch.reach_cache = cached
    return cached


def _reach_margin(batch: PoseBatch) -> np.ndarray:
    r = _reach(batch)
    return np.full(len(batch), np.nan) if r is None else batch.scatter(r.value, np.nan, float)


def _reach_margin_error(batch: PoseBatch) -> np.ndarray:
    r = _reach(batch)
    return np.full(len(batch), np.nan) if r is None else batch.scatter(r.error, np.nan, float)


def _tension_extreme(reduce) -> Callable[[PoseBatch], np.ndarray]:
    def compute(batch: PoseBatch) -> np.ndarray:
        if batch.equilibrium is None:
            return np.full(len(batch), np.nan)
        f = batch.equilibrium.tension
        values = reduce(f, axis=1) if f.shape[1] else np.zeros(f.shape[0])
        return batch.scatter(values, np.nan, float)

    return compute


def _marker_output(robot: CableRobot) -> int | None:
    """Index of the first output drawn at a point of a frame (its first
    position or rotation term), or None when every output is a joint or a
    cable length."""
    drawn = np.flatnonzero(np.asarray(robot.output_points) >= 0)
    return int(drawn[0]) if drawn.size else None


def _output_frame_position(batch: PoseBatch) -> np.ndarray:
    robot = batch.robot
    k = _marker_output(robot)
    if k is None:
        return np.full((len(batch), 3), np.nan)
    return np.array(batch.kin.point_positions[:, int(robot.output_points[k])])


def _frame_attrs(robot: CableRobot) -> dict:
    k = _marker_output(robot)
    if k is None:
        return {
            "long_name": "world position of the first output's frame (none: every output is "
            "a joint coordinate or a cable length)",
            "frame": "",
            "note": "NaN: no output is a position or rotation of a frame",
        }
    out = robot.spec.outputs[k]
    term = out.marker_term
    point = f" point {list(term.point_in_frame)} of" if any(term.point_in_frame) else ""
    return {
        "long_name": f"world position of{point} frame {out.frame!r} (output {out.name!r})",
        "frame": out.frame,
        "output": out.name,
    }


def _output_attrs(robot: CableRobot) -> dict:
    """``y``'s attributes: each output's unit (``output_units``), their
    common one (``units``) and each output's formula (``output_formulas``,
    "" for a single frame component)."""

    units = list(robot.output_units)
    common = units[0] if units and len(set(units)) == 1 else "see output_units"
    return {
        "units": common,
        "output_units": units,
        "output_formulas": [_formula(out) for out in robot.spec.outputs],
        "description": "each output in its unit (output_units): world coordinates [m], world "
        "rotation vector components log3(R) [rad], joint coordinates [rad or m], cable "
        f"lengths [m] or weighted sums of these (docs/outputs.md); r_T is in "
        f"{reach_unit(units)}",
    }


def _formula(out) -> str:
    """An output's formula (``joint elbow``, ``0.5 link1.x + 0.5 tip.x``),
    or "" for one component of a frame (its name and unit say it)."""
    plain = len(out.terms) == 1 and out.terms[0].weight == 1.0 and out.component
    return "" if plain else out.describe()


def _reach_attrs(robot: CableRobot) -> dict:
    """The reach margin's unit: the outputs' common unit, or ``"m and rad,
    one to one"`` for mixed outputs (:func:`cdpm.dynamics.reach.reach_unit`)."""

    return {"units": reach_unit(robot.output_units)}


def _n_taut(batch: PoseBatch) -> np.ndarray:
    if batch.equilibrium is None:
        return np.full(len(batch), -1, dtype=np.int16)
    return batch.scatter(np.count_nonzero(batch.equilibrium.taut, axis=1), -1, np.int16)


for _name, _long, _field in (
    ("poc", "positive output controllability of the linearisation (seed paper Theorem 1)", "poc"),
    ("output_controllable", "output controllability: rank [CB CAB ...] = p", "output_controllable"),
    (
        "positive_controllable",
        "positive (state) controllability, Brammer's test",
        "positive_controllable",
    ),
):
    register(
        Criterion(
            _name, "int8", NOT_ANALYSED, _long, _verdict(_field), VERDICT_CODES, plot="verdict"
        )
    )
register(
    Criterion(
        "wrench_closure",
        "int8",
        NOT_ANALYSED,
        "wrench closure: the columns of -L^T positively span R^nv",
        lambda b: b.wrench_closure,
        VERDICT_CODES,
        plot="verdict",
    )
)
register(
    Criterion(
        "static_feasible",
        "int8",
        NOT_ANALYSED,
        "static feasibility: a tension within the bounds holds the pose",
        lambda b: b.static_feasible,
        VERDICT_CODES,
        plot="verdict",
    )
)
register(
    Criterion(
        "reach_margin",
        "float64",
        np.nan,
        "reach margin r_T: within T the cables move the outputs at least this far in "
        "every direction",
        _reach_margin,
        units="m",
        description="radius of the largest ball about y0 that the linearisation reaches at "
        "time T from rest, with tension changes within the cables' bounds (+- the tension "
        "budget where a cable has no upper bound); T and the budget are the map's "
        "reach_horizon and tension_budget attributes (docs/analysis.md). In the outputs' "
        "unit; outputs in metres and radians count one metre as one radian "
        "(docs/outputs.md)",
        plot="sequential",
        robot_attrs=_reach_attrs,
    )
)
register(
    Criterion(
        "reach_margin_error",
        "float64",
        np.nan,
        "error bound of reach_margin: the true r_T lies in [reach_margin, reach_margin + this]",
        _reach_margin_error,
        units="m",
        description="bound of the gap between the piecewise-constant-input zonotope's "
        "inradius and r_T, from the kinks of the support function's integrand; 0 where r_T "
        "is exact (A^2 = 0)",
        robot_attrs=_reach_attrs,
    )
)
register(
    Criterion(
        "tension_min",
        "float64",
        np.nan,
        "smallest equilibrium cable tension",
        _tension_extreme(np.min),
        units="N",
        plot="sequential",
    )
)
register(
    Criterion(
        "tension_max",
        "float64",
        np.nan,
        "largest equilibrium cable tension",
        _tension_extreme(np.max),
        units="N",
        plot="sequential",
    )
)
register(
    Criterion(
        "n_taut",
        "int16",
        -1,
        "number of taut cables (equilibrium tension > 0)",
        _n_taut,
        units="1",
        description="-1 where the pose was not analysed",
        plot="sequential",
    )
)
register(
    Criterion(
        "y",
        "float64",
        np.nan,
        "outputs y = h(q)",
        lambda b: np.array(b.kin.output),
        units="m",
        dims=("output",),
        robot_attrs=_output_attrs,
    )
)
register(
    Criterion(
        "output_frame_position",
        "float64",
        np.nan,
        "world position of the first output's point (the first output with a frame "
        "term; NaN when every output is a joint or a cable length)",
        _output_frame_position,
        units="m",
        dims=("xyz",),
        robot_attrs=_frame_attrs,
    )
)
register(
    Criterion(
        "status", "int8", STATUS_CODES["pending"], "pose status", lambda b: b.status, STATUS_CODES
    )
)
