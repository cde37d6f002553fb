"""``sim4endor vessel ...``: build, check and list vessel folders (and generate phantoms).

Each action is a function ``add_<action>_parser(subparsers)`` that adds its parser to the
group and sets ``func``; :func:`register` adds them all, so a new action is one more line.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from sim4endor import _json as strict_json
from sim4endor.cli import args as arg_types
from sim4endor.errors import Sim4EndoRError


class CliInputError(Sim4EndoRError, ValueError):
    """Raised for a malformed command-line value."""


def _point(text: str) -> np.ndarray:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z (three numbers), got {text!r}")
    return np.array(values)


def _target(text: str) -> tuple[str, np.ndarray]:
    name, sep, point = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected NAME=X,Y,Z, got {text!r}")
    return name, _point(point)


def _print(line: str) -> None:
    print(line)  # noqa: T201  (the CLI's result line)


def _mm(metres: float) -> str:
    """Metres as millimetres to 0.1 mm, never "-0.0"."""
    return f"{round(1e3 * metres, 1) + 0.0:.1f}"


def _summary(vessel: Any) -> str:
    checks = vessel.manifest.checks
    inlet = ", ".join(_mm(v) for v in vessel.manifest.inlet.position)
    choice = vessel.manifest.build.get("inlet_choice")
    return (
        f"{vessel.root}: {vessel.manifest.hull_count} hulls, lumen open "
        f"{checks.get('lumen_open', float('nan')):.4f}, wall closed "
        f"{checks.get('wall_closed', float('nan')):.4f}, build "
        f"{checks.get('build_time_s', float('nan')):.1f} s, inlet ({inlet}) mm"
        f"{f' ({choice})' if choice else ''}, targets {sorted(vessel.targets)}"
    )


def run_build(args: argparse.Namespace) -> int:
    """Handles ``sim4endor vessel build``."""
    from sim4endor.vessels.build import BuildParams, build_vessel
    from sim4endor.vessels.centerline import CenterlineGraph
    from sim4endor.vessels.meshio import read_mesh
    from sim4endor.vessels.register import RegistrationParams
    from sim4endor.vessels.slicer import read_slicer_centerline
    from sim4endor.vessels.walls import WallParams

    lumen = read_mesh(args.mesh)
    centerline = None
    if args.centerline:
        if (
            len(args.centerline) == 1
            and args.centerline[0].suffix == ".json"
            and not str(args.centerline[0]).endswith(".mrk.json")
        ):
            centerline = CenterlineGraph.load(args.centerline[0])
        else:
            centerline = read_slicer_centerline(args.centerline, mesh_frame=args.mesh_frame)
    params = BuildParams(
        wall=WallParams(
            thickness=args.wall_thickness * 1e-3,
            workers=args.workers,
            use_coacd=args.decomposition == "coacd",
        ),
        keep_largest=args.keep_largest,
        trim_ends_below=(args.trim_ends_below or 0.0) * 1e-3,
    )
    license_text = args.license.read_text() if args.license else None
    vessel = build_vessel(
        lumen,
        name=args.name,
        out_dir=args.out or Path(args.name),
        units=args.units,
        centerline=centerline,
        inlet=args.inlet,
        targets=dict(args.target) if args.target else None,
        params=params,
        registration=None if args.no_register else RegistrationParams(),
        source=args.source or str(args.mesh),
        license_text=license_text,
        readme_text=args.readme_text,
        progress=not args.no_progress,
        cache=not args.no_cache,
        allow_below_acceptance=args.allow_below_acceptance,
        command=args.command_line,
    )
    _print(_summary(vessel))
    return 0


def run_check(args: argparse.Namespace) -> int:
    """Handles ``sim4endor vessel check``: loads, compiles and re-runs the geometric checks."""
    from sim4endor.vessels import load
    from sim4endor.vessels.checks import check_folder

    vessel = load(args.vessel)
    report = check_folder(vessel)
    _print(strict_json.dumps(report) if args.json else f"{_summary(vessel)}; checked again: "
           + _check_line(report))
    return 0 if report["passed"] else 1


def _check_line(report: Mapping[str, Any]) -> str:
    """``check_folder``'s report in words."""
    holes = report["wall_holes"]
    return (f"lumen open {report['lumen_open']:.4f}, wall closed {report['wall_closed']:.4f}, "
            f"{report['hull_count']} hulls, "
            f"{'loads without warnings' if report['compiles'] else 'MuJoCo warns on loading'}, "
            f"{f'{holes} hole(s) in the wall' if holes else 'no hole in the wall'}: "
            f"{'passed' if report['passed'] else 'FAILED'}")


def run_list(args: argparse.Namespace) -> int:
    """Handles ``sim4endor vessel list``."""
    from sim4endor import vessels

    for name in vessels.names():
        _print(name if not args.long else _summary(vessels.load(name)))
    return 0


def add_build_parser(subparsers: Any) -> None:
    """Adds ``build``: a lumen mesh from a CTA segmentation to a vessel folder."""
    parser = subparsers.add_parser(
        "build",
        help="build a vessel folder from a lumen surface mesh (STL/OBJ/PLY)",
        description="Validate/repair the lumen mesh, build the wall hulls, the MJCF and the "
        "centerline graph, check them, and write the vessel folder atomically.",
    )
    parser.add_argument("mesh", type=Path, help="lumen (blood-pool) surface mesh")
    parser.add_argument("--name", required=True, help="vessel name")
    parser.add_argument("--out", type=Path, default=None, help="vessel folder (default ./NAME)")
    parser.add_argument("--units", choices=("um", "mm", "m"), default="mm",
                        help="mesh units (default mm)")
    parser.add_argument(
        "--centerline",
        type=Path,
        nargs="+",
        default=None,
        help="centerline: Slicer .mrk.json files or a folder of them, or a centerline.json "
        "(metres); default: extracted from the mesh",
    )
    parser.add_argument(
        "--no-register",
        action="store_true",
        help="use the given centerline as is (default: register it onto this lumen: centre "
        "each point, trim curve ends past a vessel end, radius at most the clearance)",
    )
    parser.add_argument(
        "--mesh-frame",
        choices=("LPS", "RAS"),
        default="LPS",
        help="frame of the mesh, for Slicer curves (default LPS)",
    )
    parser.add_argument(
        "--inlet",
        type=_point,
        default=None,
        metavar="X,Y,Z",
        help="inlet point in mesh units (default: end of the widest branch)",
    )
    parser.add_argument(
        "--target",
        type=_target,
        action="append",
        default=None,
        metavar="NAME=X,Y,Z",
        help="named target in mesh units (repeatable)",
    )
    parser.add_argument("--wall-thickness", type=arg_types.positive_float, default=0.8,
                        help="wall thickness (mm, > 0)")
    parser.add_argument(
        "--trim-ends-below", type=arg_types.positive_float, default=None, metavar="MM",
        help="cut the centerline's vessel ends back to where the lumen radius reaches MM: "
        "ends narrower than a wire can use leave the checks and the targets (the lumen and "
        "its wall stay whole)",
    )
    parser.add_argument(
        "--keep-largest",
        action="store_true",
        help="keep only the largest connected part of the mesh",
    )
    parser.add_argument(
        "--decomposition",
        choices=("coacd", "hull"),
        default="coacd",
        help="wall pieces whose plain hull intrudes into the lumen: bisected, and also "
        "decomposed by CoACD where that gives fewer hulls (coacd, default), or only bisected "
        "(hull, about half the build time on large meshes)",
    )
    parser.add_argument("--workers", type=arg_types.positive_int, default=2,
                        help="processes for the wall (2)")
    parser.add_argument("--license", type=Path, default=None, help="LICENSE file of the data")
    parser.add_argument("--source", default="", help="provenance line (default: mesh path)")
    parser.add_argument("--readme-text", default="", help="extra README paragraph")
    parser.add_argument("--no-cache", action="store_true", help="rebuild even if cached")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument(
        "--allow-below-acceptance",
        action="store_true",
        help="write the folder even when its lumen-open or wall-closed check is below "
        "acceptance (for experts; every command that loads it warns)",
    )
    parser.set_defaults(func=run_build)


def add_check_parser(subparsers: Any) -> None:
    """Adds ``check``: re-run the lumen-open / wall-closed checks on a vessel folder."""
    parser = subparsers.add_parser("check", help="load a vessel folder and re-run its checks")
    parser.add_argument("vessel", help="vessel name or folder")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.set_defaults(func=run_check)


def add_list_parser(subparsers: Any) -> None:
    """Adds ``list``: the vessels on the search path."""
    parser = subparsers.add_parser("list", help="list shipped and registered vessels")
    parser.add_argument("--long", action="store_true", help="with hull counts and checks")
    parser.set_defaults(func=run_list)


def register(subparsers: Any) -> None:
    """Adds the ``vessel`` command group to the top-level parser."""
    from sim4endor.vessels.generators.command import add_generate_parser

    parser = subparsers.add_parser("vessel", help="build, generate, check and list vessels")
    actions = parser.add_subparsers(dest="vessel_command", required=True, metavar="ACTION")
    for add in (add_build_parser, add_check_parser, add_list_parser, add_generate_parser):
        add(actions)
