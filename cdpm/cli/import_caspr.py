"""``cdpm import-caspr``: convert a CASPR model (bodies + cables XML) to URDF + spec."""

from __future__ import annotations

import argparse
import sys
import warnings

from cdpm.printing import json_text

NAME = "import-caspr"
HELP = "convert a CASPR model (bodies + cables XML) into a URDF and a cable spec"
DESCRIPTION = """\
Read a CASPR model (<name>_bodies.xml and <name>_cables.xml, plus
<name>_operational_spaces.xml beside them if present) and write <name>.urdf
and <name>.yaml into --out. The spec loads with cdpm.load_robot and carries
CASPR's gravity (-z), the cables of one cable set with their force bounds,
outputs from one operational set, and CASPR's q_initial as pose 'initial'.
Position axes x, y, z become world coordinates of the operational point [m];
orientation axes a, b, g become rx, ry, rz, the world components of the link
frame's rotation vector [rad] (not CASPR's Euler angles; see docs/caspr.md).
The summary lists every output with its unit. Multi-DOF joints become chains
of 1-DOF joints with CASPR's own coordinates.
Pulleys, passive springs, actuated (hybrid) joints and quaternion joints are
refused with an error naming the element; ignored details are printed as
warnings. The mapping is documented in docs/caspr.md."""
EPILOG = """\
examples:
  cdpm import-caspr BMArm_bodies.xml BMArm_cables.xml --out models/BMArm
  cdpm import-caspr IPAnema_1_bodies.xml IPAnema_1_cables.xml --out ipanema \\
      --cable-set IROS_CASPR_2016
  cdpm import-caspr SJTUSnake_bodies.xml SJTUSnake_cables.xml --out snake \\
      --operational-set tip_pose        # tip position and orientation
  cdpm analyze models/BMArm/BMArm.yaml --pose initial"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bodies", metavar="BODIES", help="CASPR <name>_bodies.xml")
    parser.add_argument("cables", metavar="CABLES", help="CASPR <name>_cables.xml")
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="folder for <name>.urdf and <name>.yaml"
    )
    parser.add_argument(
        "--cable-set", metavar="ID", help="cable set to import (default: the file's default)"
    )
    parser.add_argument(
        "--operational-spaces",
        metavar="FILE",
        help="CASPR operational spaces XML (default: <name>_operational_spaces.xml beside BODIES)",
    )
    parser.add_argument(
        "--operational-set",
        metavar="ID",
        help="operational set whose components become outputs: x y z [m], a b g as rx ry rz "
        "[rad] (default: the file's)",
    )
    parser.add_argument("--name", help="model name for the files (default: from BODIES)")
    parser.add_argument(
        "--json", action="store_true", help="print the import summary as JSON instead of text"
    )


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.caspr import CasprWarning, import_caspr

    with warnings.catch_warnings():
        # the summary lists every warning; do not print them twice
        warnings.simplefilter("ignore", CasprWarning)
        result = import_caspr(
            args.bodies,
            args.cables,
            args.out,
            cable_set=args.cable_set,
            operational_spaces_xml=args.operational_spaces,
            operational_set=args.operational_set,
            name=args.name,
        )
    if args.json:
        print(json_text(result.as_dict()))
    else:
        print(result)
        if result.warnings:
            print(f"{len(result.warnings)} warning(s), listed above", file=sys.stderr)
    return 0
