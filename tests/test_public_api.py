"""The public API of cdpm 0.1 keeps working after the package's floor plan
changed: every name its ``cdpm.__all__`` listed, and the submodules it
reached as attributes of ``cdpm``."""

from __future__ import annotations

import pytest

import cdpm

#: ``cdpm.__all__`` of cdpm 0.1 (before the packages by concept), less __version__
NAMES_0_1 = (
    "CdpmError",
    "SpecError",
    "InputError",
    "ModelError",
    "UnsupportedError",
    "MissingExtraError",
    "CableSpec",
    "load_spec",
    "parse_number",
    "CableRobot",
    "load_robot",
    "EquilibriumResult",
    "equilibrium_tension",
    "check_equilibrium",
    "InfeasibleEquilibriumError",
    "EquilibriumWarning",
    "Linearisation",
    "linearise",
    "Verdict",
    "positive_output_controllability",
    "positive_controllability",
    "output_controllability",
    "controllability",
    "positively_spans",
    "wrench_closure",
    "POCResult",
    "POCCertificate",
    "PositiveControllabilityResult",
    "ControllabilityResult",
    "OutputControllabilityResult",
    "SpanResult",
    "SpanCertificate",
    "simulate",
    "Trajectory",
    "TensionProfile",
    "steer",
    "SteerResult",
    "verify_pose",
    "VerifyReport",
    "PoseReport",
    "analyze_pose",
    "workspace_map",
    "sample_axes",
    "SampledAxes",
    "open_map",
    "StoreSettingsError",
    "evaluate_poses",
    "VERDICT_CODES",
    "STATUS_CODES",
    "label_regions",
    "region_of",
    "poc_path",
    "POCPath",
    "NotConnectedError",
    "ReachSettings",
    "reach_settings",
    "poc_neighbourhood",
    "Neighbourhood",
    "tension_range",
    "TensionRange",
    "best_tension",
    "BestTension",
    "best_tension_batch",
    "plot_map",
    "save_map_plot",
    "Viewer",
    "PoseInspector",
    "PoseState",
    "CableState",
    "pose_state",
    "render_pose",
    "import_caspr",
    "CasprImport",
    "CasprWarning",
    "cable_sets",
)


@pytest.mark.parametrize("name", NAMES_0_1)
def test_every_name_of_0_1_is_public_and_resolves(name):
    assert name in cdpm.__all__
    value = getattr(cdpm, name)
    assert getattr(value, "__name__", name) == name or not callable(value)


def test_submodules_of_0_1_are_attributes():
    assert cdpm.equilibrium.equilibrium_tension is cdpm.equilibrium_tension
    assert cdpm.reach.reach_settings is cdpm.dynamics.reach.reach_settings
    assert cdpm.maps.workspace_map is cdpm.workspace_map
    assert cdpm.analysis.positive_output_controllability is cdpm.positive_output_controllability
    assert cdpm.caspr.import_caspr is cdpm.import_caspr
    assert cdpm.numerics.SPAN_TOL > 0
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        cdpm.no_such_name  # noqa: B018
