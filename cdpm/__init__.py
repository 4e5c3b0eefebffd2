"""cdpm: positive output controllability of cable-driven parallel manipulators.

The public API is re-exported here. Submodules are imported on first use, so
``import cdpm`` is fast and pulls in neither Pinocchio nor SciPy.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from cdpm._version import __version__

# public name -> submodule that defines it
_EXPORTS: dict[str, str] = {
    # errors
    "CdpmError": "cdpm.errors",
    "SpecError": "cdpm.errors",
    "InputError": "cdpm.errors",
    "ModelError": "cdpm.errors",
    "UnsupportedError": "cdpm.errors",
    "MissingExtraError": "cdpm.errors",
    # spec and robot
    "CableSpec": "cdpm.model.spec",
    "load_spec": "cdpm.model.spec",
    "parse_number": "cdpm.expressions",
    "CableRobot": "cdpm.model.robot",
    "load_robot": "cdpm.model.robot",
    # equilibrium and linearisation
    "EquilibriumResult": "cdpm.dynamics.equilibrium",
    "equilibrium_tension": "cdpm.dynamics.equilibrium",
    "check_equilibrium": "cdpm.dynamics.equilibrium",
    "InfeasibleEquilibriumError": "cdpm.dynamics.equilibrium",
    "EquilibriumWarning": "cdpm.dynamics.equilibrium",
    "Linearisation": "cdpm.dynamics.linearisation",
    "linearise": "cdpm.dynamics.linearisation",
    # analysis (pure LTI, no Pinocchio)
    "Verdict": "cdpm.analysis",
    "positive_output_controllability": "cdpm.analysis",
    "positive_controllability": "cdpm.analysis",
    "output_controllability": "cdpm.analysis",
    "controllability": "cdpm.analysis",
    "positively_spans": "cdpm.analysis",
    "wrench_closure": "cdpm.analysis",
    "POCResult": "cdpm.analysis",
    "POCCertificate": "cdpm.analysis",
    "PositiveControllabilityResult": "cdpm.analysis",
    "ControllabilityResult": "cdpm.analysis",
    "OutputControllabilityResult": "cdpm.analysis",
    "SpanResult": "cdpm.analysis",
    "SpanCertificate": "cdpm.analysis",
    # the nonlinear robot: simulation, steering, verification
    "simulate": "cdpm.dynamics.simulation",
    "Trajectory": "cdpm.dynamics.simulation",
    "TensionProfile": "cdpm.dynamics.simulation",
    "steer": "cdpm.steering.shooting",
    "SteerResult": "cdpm.steering.shooting",
    "verify_pose": "cdpm.steering.verify",
    "VerifyReport": "cdpm.steering.verify",
    # pose report
    "PoseReport": "cdpm.text.report",
    "analyze_pose": "cdpm.text.report",
    # workspace maps (xarray + zarr; Dask optional)
    "workspace_map": "cdpm.maps",
    "sample_axes": "cdpm.maps",
    "SampledAxes": "cdpm.maps",
    "open_map": "cdpm.maps",
    "StoreSettingsError": "cdpm.maps",
    "evaluate_poses": "cdpm.pipeline",
    "VERDICT_CODES": "cdpm.pipeline",
    "STATUS_CODES": "cdpm.pipeline",
    "label_regions": "cdpm.maps.regions",
    "region_of": "cdpm.maps.regions",
    "poc_path": "cdpm.regions.paths",
    "POCPath": "cdpm.regions.paths",
    "NotConnectedError": "cdpm.regions.paths",
    "certified_path": "cdpm.regions.certified",
    "CertifiedPath": "cdpm.regions.certified",
    # certified boxes: POC proven on a whole box of poses
    "certify_box": "cdpm.certify.box",
    "BoxCertificate": "cdpm.certify.box",
    "certify_map": "cdpm.certify.map",
    "CertifiedMap": "cdpm.certify.map",
    "open_certified": "cdpm.certify.map",
    # margins with units and POC neighbourhoods
    "ReachSettings": "cdpm.dynamics.reach",
    "reach_settings": "cdpm.dynamics.reach",
    "poc_neighbourhood": "cdpm.regions.neighbourhood",
    "Neighbourhood": "cdpm.regions.neighbourhood",
    "certified_neighbourhood": "cdpm.regions.neighbourhood",
    "CertifiedNeighbourhood": "cdpm.regions.neighbourhood",
    # searching for poses worth analysing (cdpm find)
    "find_poses": "cdpm.regions.search",
    "search_box": "cdpm.regions.search",
    "PoseSearch": "cdpm.regions.search",
    "SearchBox": "cdpm.regions.search",
    "FoundPose": "cdpm.regions.search",
    # choosing the equilibrium tension
    "tension_range": "cdpm.dynamics.tension_choice",
    "TensionRange": "cdpm.dynamics.tension_choice",
    "best_tension": "cdpm.dynamics.tension_choice",
    "BestTension": "cdpm.dynamics.tension_choice",
    "best_tension_batch": "cdpm.dynamics.tension_choice",
    "plot_map": "cdpm.plotting",
    "save_map_plot": "cdpm.plotting",
    # viewer and pictures (extra: cdpm[viz])
    "Viewer": "cdpm.viewer",
    "PoseInspector": "cdpm.viewer",
    "PoseState": "cdpm.viewer",
    "CableState": "cdpm.viewer",
    "pose_state": "cdpm.viewer",
    "render_pose": "cdpm.plotting.picture",
    # CASPR import (extra: cdpm[caspr])
    "import_caspr": "cdpm.caspr",
    "CasprImport": "cdpm.caspr",
    "CasprWarning": "cdpm.caspr",
    "cable_sets": "cdpm.caspr",
}

__all__ = ["__version__", *_EXPORTS]


#: submodules reachable as attributes after a plain ``import cdpm``: the
#: packages, and two modules under the names they had before they moved
#: into ``cdpm.dynamics`` (``cdpm.equilibrium``, ``cdpm.reach``)
_SUBMODULES = {
    **{
        name: f"cdpm.{name}"
        for name in (
            "model",
            "dynamics",
            "analysis",
            "pipeline",
            "maps",
            "regions",
            "steering",
            "caspr",
            "text",
            "plotting",
            "viewer",
            "numerics",
            "verdicts",
            "errors",
        )
    },
    "equilibrium": "cdpm.dynamics.equilibrium",
    "reach": "cdpm.dynamics.reach",
}


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(_SUBMODULES[name])
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'cdpm' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


if TYPE_CHECKING:  # pragma: no cover - for static type checkers only
    from cdpm.analysis import (  # noqa: F401
        ControllabilityResult,
        OutputControllabilityResult,
        POCCertificate,
        POCResult,
        PositiveControllabilityResult,
        SpanCertificate,
        SpanResult,
        Verdict,
        controllability,
        output_controllability,
        positive_controllability,
        positive_output_controllability,
        positively_spans,
        wrench_closure,
    )
    from cdpm.caspr import CasprImport, CasprWarning, cable_sets, import_caspr  # noqa: F401
    from cdpm.certify.box import BoxCertificate, certify_box  # noqa: F401
    from cdpm.certify.map import CertifiedMap, certify_map, open_certified  # noqa: F401
    from cdpm.dynamics.equilibrium import (  # noqa: F401
        EquilibriumResult,
        EquilibriumWarning,
        InfeasibleEquilibriumError,
        check_equilibrium,
        equilibrium_tension,
    )
    from cdpm.dynamics.linearisation import Linearisation, linearise  # noqa: F401
    from cdpm.dynamics.reach import ReachSettings, reach_settings  # noqa: F401
    from cdpm.dynamics.simulation import TensionProfile, Trajectory, simulate  # noqa: F401
    from cdpm.dynamics.tension_choice import (  # noqa: F401
        BestTension,
        TensionRange,
        best_tension,
        best_tension_batch,
        tension_range,
    )
    from cdpm.errors import (  # noqa: F401
        CdpmError,
        InputError,
        MissingExtraError,
        ModelError,
        SpecError,
        UnsupportedError,
    )
    from cdpm.expressions import parse_number  # noqa: F401
    from cdpm.maps import (  # noqa: F401
        SampledAxes,
        StoreSettingsError,
        open_map,
        sample_axes,
        workspace_map,
    )
    from cdpm.maps.regions import label_regions, region_of  # noqa: F401
    from cdpm.model.robot import CableRobot, load_robot  # noqa: F401
    from cdpm.model.spec import CableSpec, load_spec  # noqa: F401
    from cdpm.pipeline import STATUS_CODES, VERDICT_CODES, evaluate_poses  # noqa: F401
    from cdpm.plotting import plot_map, save_map_plot  # noqa: F401
    from cdpm.plotting.picture import render_pose  # noqa: F401
    from cdpm.regions.certified import CertifiedPath, certified_path  # noqa: F401
    from cdpm.regions.neighbourhood import (  # noqa: F401
        CertifiedNeighbourhood,
        Neighbourhood,
        certified_neighbourhood,
        poc_neighbourhood,
    )
    from cdpm.regions.paths import NotConnectedError, POCPath, poc_path  # noqa: F401
    from cdpm.regions.search import (  # noqa: F401
        FoundPose,
        PoseSearch,
        SearchBox,
        find_poses,
        search_box,
    )
    from cdpm.steering.shooting import SteerResult, steer  # noqa: F401
    from cdpm.steering.verify import VerifyReport, verify_pose  # noqa: F401
    from cdpm.text.report import PoseReport, analyze_pose  # noqa: F401
    from cdpm.viewer import CableState, PoseInspector, PoseState, Viewer, pose_state  # noqa: F401
