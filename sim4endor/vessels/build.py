"""Turns a lumen surface mesh into a vessel folder (the output contract of issue 2, item 6).

``build_vessel`` validates and repairs the mesh (:mod:`.meshio`), gets a centerline graph (given,
read from 3D Slicer curves by :mod:`.slicer`, or extracted by :mod:`.skeleton`), cuts the wall
into convex hulls (:mod:`.walls`), checks them (:mod:`.checks`) and writes the folder
atomically (:mod:`.mjcf_writer`). Results are cached by content hash, so an unchanged rebuild
only copies the cached folder.

Inlet: the given point, snapped to the nearest vessel end of the centerline graph; without one,
the end of the widest terminal branch (largest median radius). The inlet direction points
from that end into the vessel along the graph.
Targets: the given points (snapped to their nearest graph node for the labels); without them,
every other vessel end, named ``T1``, ``T2``... by increasing path length from the inlet.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from tqdm.auto import tqdm

from sim4endor._atomic import atomic_directory, holds_output
from sim4endor.errors import Sim4EndoRError
from sim4endor.vessels import CENTERLINE_FILE, LUMEN_FILE, SCENE_FILE, Vessel, load
from sim4endor.vessels.axis import AxisSamples, branch_chains, sample_axis
from sim4endor.vessels.centerline import (
    INLET_LABEL,
    CenterlineGraph,
    arc_lengths,
    points_along,
)
from sim4endor.vessels.checks import (
    CheckParams,
    LumenProbes,
    Opening,
    blocked_place,
    inlet_cap,
    lumen_probes,
    stray_openings,
    wall_closed_fraction,
    wall_probes,
)
from sim4endor.vessels.ends import OPENING_BESIDE_RADII, graft_to, trim_narrow_ends
from sim4endor.vessels.manifest import MANIFEST_FILE, Inlet, Manifest, below_acceptance
from sim4endor.vessels.meshio import (
    UNIT_SCALE,
    MeshInputError,
    PreparedLumen,
    Units,
    capped,
    close_openings,
    prepare_lumen,
)
from sim4endor.vessels.mjcf_writer import (
    DISPLAY_DIR,
    HULL_DIR,
    write_meshes,
    write_scene,
    write_vessel_mjcf,
)
from sim4endor.vessels.register import RegistrationParams, register_centerline
from sim4endor.vessels.remesh import RemeshParams
from sim4endor.vessels.skeleton import SkeletonParams, extract_centerline
from sim4endor.vessels.walls import (
    Hull,
    WallContext,
    WallParams,
    bin_faces,
    build_hulls,
    wall_thickness,
)

logger = logging.getLogger(__name__)

CACHE_ENV = "XDG_CACHE_HOME"


class BuildError(Sim4EndoRError, ValueError):
    """Raised when the inputs of a build do not fit together (inlet, targets, centerline)."""


@dataclass(frozen=True)
class BuildParams:
    """Everything that controls a build besides the inputs (SI units).

    Attributes:
        wall: Wall thickness and decomposition settings.
        checks: Lumen-open / wall-closed check settings.
        skeleton: Centerline extraction settings (used when no centerline is given).
        keep_largest: Keep only the largest connected component of the input mesh.
        max_hole_perimeter: Side-wall holes below this many lumen radii around are filled.
        resolution: When the lumen is decimated or its long edges split before the wall is
            built (:mod:`.remesh`).
        trim_ends_below: Cut the centerline's vessel ends back to where the lumen radius is
            at least this (m; 0: keep them): such ends leave the checks and the targets
            (:mod:`.ends`). The lumen and its wall are kept whole.
    """

    wall: WallParams = field(default_factory=WallParams)
    checks: CheckParams = field(default_factory=CheckParams)
    skeleton: SkeletonParams = field(default_factory=SkeletonParams)
    keep_largest: bool = False
    max_hole_perimeter: float = 3.0
    resolution: RemeshParams = field(default_factory=RemeshParams)
    trim_ends_below: float = 0.0


def cache_root() -> Path:
    """Returns ``$XDG_CACHE_HOME/sim4endor/vessels`` (default ``~/.cache/sim4endor/vessels``)."""
    base = os.environ.get(CACHE_ENV) or str(Path.home() / ".cache")
    return Path(base).expanduser() / "sim4endor" / "vessels"


def _package_version() -> str:
    try:
        return metadata.version("sim4endor")
    except metadata.PackageNotFoundError:
        return "unknown"


def _pipeline_source_digest() -> bytes:
    """Hash of the build pipeline's own source, so a code change never reuses a stale build."""
    digest = hashlib.sha256()
    for path in sorted(Path(__file__).parent.glob("*.py")):
        digest.update(path.read_bytes())
    return digest.digest()


def content_hash(lumen: trimesh.Trimesh, **inputs: object) -> str:
    """Returns a SHA-256 over the mesh, the other inputs, the version and the pipeline source."""
    digest = hashlib.sha256()
    digest.update(_pipeline_source_digest())
    digest.update(np.ascontiguousarray(lumen.vertices, dtype=np.float64).tobytes())
    digest.update(np.ascontiguousarray(lumen.faces, dtype=np.int64).tobytes())
    digest.update(json.dumps(inputs, sort_keys=True, default=_jsonable).encode())
    digest.update(_package_version().encode())
    return digest.hexdigest()


def _jsonable(value: object) -> object:
    if isinstance(value, np.ndarray):
        return np.round(value.astype(np.float64), 12).tolist()
    if isinstance(value, CenterlineGraph):
        return value.to_json_dict()
    if hasattr(value, "__dataclass_fields__"):
        return asdict(value)  # type: ignore[call-overload]
    raise TypeError(f"cannot hash {type(value).__name__}")


def _progress(
    enabled: bool, desc: str
) -> Callable[[Iterator[list[Hull]], int], Iterator[list[Hull]]]:
    def wrap(items: Iterator[list[Hull]], total: int) -> Iterator[list[Hull]]:
        return iter(
            tqdm(items, total=total, desc=desc, unit="piece", disable=not enabled, leave=False)
        )

    return wrap


def _vec3(value: np.ndarray) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in np.asarray(value).reshape(3))
    return (x, y, z)


def _terminal_direction(graph: CenterlineGraph, node: int) -> np.ndarray:
    """Unit vector from a vessel end into the vessel, over about two radii of the graph."""
    chain = next(c for c in branch_chains(graph) if node in (c[0], c[-1]))
    if chain[0] != node:
        chain = chain[::-1]
    points = graph.nodes[chain]
    arc = arc_lengths(points)
    reach = min(float(arc[-1]), max(2.0 * float(graph.radii[node]), 1e-9))
    ahead = points_along(points, np.array([reach]))[0]
    direction = ahead - graph.nodes[node]
    return direction / np.linalg.norm(direction)


def _inlet_direction(graph: CenterlineGraph, node: int, grafted: Sequence[Opening],
                     vertices: np.ndarray) -> np.ndarray:
    """Unit vector into the vessel at the inlet: square to its opening where the centerline
    was grafted onto that open end (``grafted``, from :func:`_grafted_to_openings`, whose
    loops index ``vertices``), else along the centerline (:func:`_terminal_direction`).

    A graft is a straight run from a node of some branch to the opening's centre and says
    nothing of the vessel's axis there. On NARCO_119's left tree, cut 2.7 mm before its
    bifurcation, it ran 12.8° off the cut's normal towards a branch, and every episode began
    with the wire's tip pressed into the wall (a tip-force stop at 180 N). An end the skeleton
    traced follows the axis, which an oblique cut leaves at an angle to its normal, and keeps
    its own direction.
    """
    along = _terminal_direction(graph, node)
    for opening in grafted:
        if np.allclose(graph.nodes[node], opening.centre, rtol=0.0, atol=1e-12):
            normal = np.linalg.svd(vertices[opening.loop] - opening.centre)[2][2]
            return normal if normal @ along > 0 else -normal
    return along


def _close_wall_holes(
    prepared: PreparedLumen, graph: CenterlineGraph, source: str, max_perimeter: float
) -> PreparedLumen:
    """Fills small openings of the lumen that are not vessel ends; refuses large ones.

    :func:`.meshio.prepare_lumen` fills small side-wall holes and refuses large ones it can
    tell from a cut vessel end by their shape; a hole in a curved wall, or a slit left by a
    mesh union, can look like an end there. With the centerline known it cannot: a vessel end
    is where the centerline ends. Openings below ``max_perimeter`` lumen radii around are
    filled as :func:`.meshio.prepare_lumen` fills them; a larger one is an error naming it.

    Raises:
        MeshInputError: for a hole of ``max_perimeter`` lumen radii or more.
    """
    stray = stray_openings(prepared.mesh.vertices, prepared.end_loops, graph)
    limit = max_perimeter * prepared.radius_estimate
    large = [o for o in stray if o.perimeter > limit]
    if large:
        hole = max(large, key=lambda o: o.perimeter)
        where = np.round(hole.centre / prepared.scale, 3).tolist()
        raise MeshInputError(
            f"{source} has {len(large)} hole(s) in the vessel wall that are not vessel ends "
            f"(the largest {hole.perimeter * 1e3:.3g} mm around, near {where} in input units; "
            "no centerline end is there). Close them in the segmentation or a mesh tool (holes "
            f"below {max_perimeter:g} lumen radii around are filled automatically)."
        )
    if stray:
        closed = close_openings(prepared, [o.loop for o in stray])
        # Named one by one: a thin vessel end that the extracted centerline stops short of
        # looks the same here, and a user must be able to tell which openings were closed.
        where = "; ".join(
            f"{o.radius * 1e3:.2f} mm radius near "
            f"{np.round(o.centre / prepared.scale, 2).tolist()}" for o in stray)
        logger.warning(
            "%s: closed %d opening(s) that no centerline end reaches as holes in the wall: %s "
            "(the manifest counts %d filled holes in all). If one is a vessel end, the "
            "centerline stops short of it, beyond a straight run's reach: pass one that "
            "reaches it with --centerline.",
            source, len(stray), where, closed.report.filled_holes)
        return closed
    return prepared


#: What to do about a build below acceptance, after the place is named.
_REMEDY = ("Where the lumen is narrower than a wire can use, trim those ends off the centerline "
           "(--trim-ends-below MM, BuildParams.trim_ends_below); elsewhere the wall hulls reach "
           "into the lumen: look at the mesh there (a fold, a flat facet across a bend, a "
           "narrowing) and smooth or subdivide it, or pass --allow-below-acceptance "
           "(allow_below_acceptance=True) to keep the folder as it is.")


def _where_blocked(probes: LumenProbes, axis: AxisSamples, graph: CenterlineGraph,
                   scale: float) -> str:
    """``": N of the M blocked probes lie ..."`` naming the worst branch, or nothing."""
    place = blocked_place(probes, axis)
    return "" if place is None else f": {place.describe(scale, graph)}"


#: How far (in lumen radii) a given inlet or target may lie outside the lumen before the build
#: refuses it: further than that it was given in another frame (LPS against RAS), in other
#: units, or for another mesh, and snapping it to the nearest node would hide that.
MAX_POINT_OUTSIDE_RADII = 2.0


def _grafted(graph: CenterlineGraph, inlet: np.ndarray | None,
             targets: Mapping[str, np.ndarray] | None, lumen: trimesh.Trimesh, scale: float,
             name: str) -> CenterlineGraph:
    """The centerline extended to each given point (input units) that none of its vessel ends
    reaches but that lies in the vessel around it (:func:`.ends.graft_to`)."""
    points = {"inlet": inlet, **(dict(targets) if targets is not None else {})}
    for what, point in points.items():
        if point is None:
            continue
        graph, length = graft_to(graph, np.asarray(point, dtype=np.float64) * scale,
                                 MAX_POINT_OUTSIDE_RADII, lumen)
        if length:
            logger.info("%s: extended the centerline %.3g mm to the given %s at %s (input "
                        "units): no vessel end of it was there", name, length * 1e3, what,
                        np.round(np.asarray(point, dtype=np.float64), 3).tolist())
    return graph


def _grafted_to_openings(graph: CenterlineGraph, prepared: PreparedLumen,
                         lumen: trimesh.Trimesh, name: str
                         ) -> tuple[CenterlineGraph, list[Opening]]:
    """The centerline extended to each open vessel end of the lumen that none of its vessel
    ends reaches but that lies in the vessel around it (:func:`.ends.graft_to`), and those
    openings (each now a vessel end at its centre).

    The skeleton leaves out the ends it cannot see (a short end past a junction, a thin side
    branch inside its parent's covering ball), and the walls would then close them as holes.
    """
    grafted = []
    for opening in stray_openings(prepared.mesh.vertices, prepared.end_loops, graph):
        graph, length = graft_to(graph, opening.centre, 0.0, lumen, wall=prepared.mesh,
                                 beside=OPENING_BESIDE_RADII)
        if length:
            grafted.append(opening)
            logger.info("%s: extended the centerline %.3g mm to the open vessel end of %.2f mm "
                        "radius at %s (input units), which it stopped short of", name,
                        length * 1e3, opening.radius * 1e3,
                        np.round(opening.centre / prepared.scale, 3).tolist())
    return graph, grafted


def _check_near(graph: CenterlineGraph, node: int, point: np.ndarray, what: str, scale: float,
                name: str) -> None:
    """Raises :class:`BuildError` if ``point`` (m) lies more than
    :data:`MAX_POINT_OUTSIDE_RADII` lumen radii outside the lumen at ``node``, its snap."""
    radius = float(graph.radii[node])
    outside = float(np.linalg.norm(graph.nodes[node] - point)) - radius
    if outside > MAX_POINT_OUTSIDE_RADII * radius:
        nearest = np.round(graph.nodes[node] / scale, 3).tolist()
        raise BuildError(
            f"{name}: the {what} lies {outside * 1e3:.3g} mm outside the lumen ("
            f"{outside / radius:.1f} lumen radii from {nearest}, in input units, where it would "
            "snap to). Check its units and frame (LPS or RAS), or give a point inside the "
            "vessel."
        )


def _choose_inlet(graph: CenterlineGraph, inlet: np.ndarray | None) -> tuple[int, str]:
    """The inlet's node and how it was chosen (recorded in the manifest, printed by the CLI)."""
    ends = graph.terminal_nodes()
    if len(ends) == 0:
        raise BuildError("The centerline graph has no vessel end for the inlet (it is a loop).")
    if inlet is not None:
        return int(ends[np.argmin(np.linalg.norm(graph.nodes[ends] - inlet, axis=1))]), "given"
    widths = []
    for end in ends:
        # The median over the whole branch: near the end itself the radius of an extracted
        # centerline falls at a cap and at a cut.
        chain = next(c for c in branch_chains(graph) if end in (c[0], c[-1]))
        widths.append(float(np.median(graph.radii[chain])))
    order = np.argsort(widths)[::-1]
    choice = "widest vessel end"
    # Ends of about equal calibre make "widest" a coin toss: say so, so the user passes --inlet.
    if len(ends) > 1 and widths[order[1]] > 0.9 * widths[order[0]]:
        choice += (f", but another end is within 10 % ({widths[order[0]] * 1e3:.2f} vs "
                   f"{widths[order[1]] * 1e3:.2f} mm radius): pass --inlet X,Y,Z if it is not "
                   "the vessel's entry")
    return int(ends[order[0]]), choice


def _choose_targets(
    graph: CenterlineGraph, inlet_node: int, targets: Mapping[str, np.ndarray] | None
) -> dict[str, np.ndarray]:
    if targets is not None:
        return {str(k): np.asarray(v, dtype=np.float64).reshape(3) for k, v in targets.items()}
    distance = graph.geodesic_from(inlet_node)
    ends = [int(e) for e in graph.terminal_nodes() if e != inlet_node]
    ends.sort(key=lambda e: (distance[e], e))
    return {f"T{k + 1}": graph.nodes[e].copy() for k, e in enumerate(ends)}


def _orient_outward(mesh: trimesh.Trimesh, axis: AxisSamples) -> trimesh.Trimesh:
    """Makes face normals point out of the lumen (away from the centerline)."""
    idx, _, _ = axis.locate(mesh.triangles_center)
    outward = np.einsum("ij,ij->i", mesh.triangles_center - axis.points[idx], mesh.face_normals)
    if np.sum(outward * mesh.area_faces) < 0:
        mesh = mesh.copy()
        mesh.invert()
    return mesh


def _labelled(
    graph: CenterlineGraph, inlet_node: int, targets: Mapping[str, np.ndarray]
) -> CenterlineGraph:
    labels = dict(graph.labels)
    labels[INLET_LABEL] = inlet_node
    for name, point in targets.items():
        labels[name] = int(np.argmin(np.linalg.norm(graph.nodes - point, axis=1)))
    return CenterlineGraph(
        graph.nodes, graph.radii, graph.edges, labels, graph.branch, graph.branch_names
    )


def _require_connected(graph: CenterlineGraph, name: str, extracted: bool) -> None:
    """Raises :class:`BuildError` unless every labelled node is joined to the inlet along the
    centerline: a target apart from it can be neither navigated to nor measured."""
    component = graph.components()
    inlet = component[graph.labels[INLET_LABEL]]
    apart = sorted(label for label, node in graph.labels.items() if component[node] != inlet)
    if apart:
        source = "extracted from the mesh" if extracted else "given"
        remedy = ("pass one with --centerline" if extracted else
                  "join its curves, or check that each one reaches the next")
        raise BuildError(
            f"{name}: the centerline {source} is in {int(component.max()) + 1} pieces, and "
            f"{', '.join(apart)} {'is' if len(apart) == 1 else 'are'} not joined to the inlet "
            f"along it; {remedy}."
        )


#: Files a build writes into a vessel folder besides ``<name>.xml`` and the hull meshes.
_BUILD_FILES = (MANIFEST_FILE, CENTERLINE_FILE, SCENE_FILE, LUMEN_FILE, "README.md", "LICENSE")


def check_output_folder(out_dir: Path) -> None:
    """Raises :class:`BuildError` unless a build may write ``out_dir``.

    A build replaces its output folder as a whole, so the folder must not exist, be empty, or
    be a vessel folder holding only what a build writes. Anything else (a file, a folder of
    other files, a vessel folder with files added to it) is refused, naming what is in the way:
    a build never deletes what it did not write.
    """
    out_dir = Path(out_dir)
    if not out_dir.exists():
        return
    if not out_dir.is_dir():
        raise BuildError(f"{out_dir} exists and is not a folder; choose another output folder.")
    entries = sorted(p.name for p in out_dir.iterdir())
    if not entries:
        return
    try:
        mjcf = Manifest.load(out_dir).mjcf
    except Sim4EndoRError:
        raise BuildError(
            f"{out_dir} is not empty and not a vessel folder (it holds {_listing(entries)}); "
            "choose a new or empty output folder. A build replaces its folder as a whole."
        ) from None
    foreign = [e for e in entries if e not in (*_BUILD_FILES, mjcf, HULL_DIR, DISPLAY_DIR)]
    for folder, stem in ((HULL_DIR, "hull_"), (DISPLAY_DIR, "part_")):
        if (out_dir / folder).is_dir():
            foreign += [f"{folder}/{p.name}" for p in sorted((out_dir / folder).iterdir())
                        if not (p.is_file() and p.name.startswith(stem) and p.suffix == ".stl")]
    if foreign:
        raise BuildError(
            f"{out_dir} is a vessel folder with files a build did not write "
            f"({_listing(foreign)}); "
            "move them out or choose another output folder: a build replaces the folder."
        )


def _listing(names: list[str], shown: int = 3) -> str:
    more = f" and {len(names) - shown} more" if len(names) > shown else ""
    return ", ".join(names[:shown]) + more


def _store_in_cache(out_dir: Path, cached: Path) -> None:
    """Copies a finished build into the cache; a cache that cannot be written only warns."""
    try:
        with atomic_directory(cached) as staging:
            shutil.copytree(out_dir, staging, dirs_exist_ok=True)
    except OSError as exc:
        logger.warning("could not store the build in the cache (%s); the vessel folder %s is "
                       "complete", exc, out_dir)


def _readme(name: str, source: str, units: str, text: str, manifest: Manifest,
            command: str = "") -> str:
    checks = manifest.checks
    rebuild = f"Rebuild it with:\n\n```bash\n{command}\n```\n\n" if command else ""
    return (
        f"# {name}\n\n{text.strip()}\n\n{rebuild}"
        f"- Source: {source or 'not given'}\n"
        f"- Input units: {units}; the model is in metres (`mesh_to_model` in manifest.json).\n"
        f"- Built by `sim4endor` {_package_version()} with `build_vessel`: {manifest.hull_count} "
        f"convex wall hulls of {manifest.build['wall']['thickness'] * 1e3:g} mm thickness.\n"
        f"- Checks: lumen open {checks['lumen_open']:.4f}, wall closed "
        f"{checks['wall_closed']:.4f}, build time {checks['build_time_s']:.1f} s.\n"
        "- Files: manifest.json, the vessel MJCF, scene.xml, centerline.json, hulls/, "
        f"lumen.stl{_lumen_files(manifest.build['repairs'])}.\n"
    )


def _lumen_files(repairs: Mapping[str, Any]) -> str:
    """What the README says of the lumen files when the build remeshed the lumen."""
    said = ""
    if repairs.get("decimated_from"):
        said += (f" (the lumen the wall was built from, decimated from "
                 f"{repairs['decimated_from']:,} faces), {DISPLAY_DIR}/ (the full lumen, for "
                 "display, in parts under MuJoCo's 200,000 faces per mesh)")
    if repairs.get("subdivided_from"):
        said += (f"; the lumen's faces with long edges were subdivided (from "
                 f"{repairs['subdivided_from']:,} faces)")
    return said


@holds_output("out_dir")
def build_vessel(
    lumen: trimesh.Trimesh,
    *,
    name: str,
    out_dir: Path,
    units: Units = "m",
    centerline: CenterlineGraph | None = None,
    inlet: np.ndarray | None = None,
    targets: Mapping[str, np.ndarray] | None = None,
    params: BuildParams = BuildParams(),
    registration: RegistrationParams | None = None,
    source: str = "",
    license_text: str | None = None,
    readme_text: str = "",
    progress: bool = True,
    cache: bool = True,
    allow_below_acceptance: bool = False,
    command: str = "",
) -> Vessel:
    """Builds a vessel folder from a lumen (blood-pool) surface mesh.

    Args:
        lumen: The lumen surface in ``units``.
        name: Vessel name (MJCF model name and file stem).
        out_dir: The vessel folder to write (replaced atomically).
        units: Units of ``lumen``, ``inlet`` and ``targets``.
        centerline: Centerline graph in model metres; None extracts it from the mesh.
        inlet: Inlet point (input units); None takes the end of the widest terminal branch.
        targets: Named target points (input units); None names the other ends ``T1``...
        params: Build parameters.
        registration: Register the given ``centerline`` onto this lumen first (see
            :mod:`.register`; for curves made on another surface). None uses it as given.
        source: Provenance line for the manifest and README.
        license_text: Written as LICENSE when the data came from elsewhere.
        readme_text: Extra README paragraph (provenance, how it was made).
        progress: Show a progress bar (only on a terminal).
        cache: Reuse and fill the build cache.
        allow_below_acceptance: Write the folder even when its checks are below acceptance
            (``Manifest.below_acceptance``); every load of it then warns.
        command: The command line that builds it, written into its README so that ``vessel
            check``'s advice to rebuild it can be followed (not part of the build's identity:
            the same inputs built from another command share the cache).

    Returns:
        The loaded vessel.
    """
    out_dir = Path(out_dir)
    if not name or any(c in name for c in "/\\ ") or name.startswith("."):
        raise BuildError(f"Vessel name {name!r} must be a non-empty file name without spaces.")
    check_output_folder(out_dir)
    key = content_hash(
        lumen,
        name=name,
        units=units,
        centerline=centerline,
        inlet=inlet,
        targets=dict(targets) if targets is not None else None,
        params=params,
        registration=registration,
        source=source,
        license=license_text,
        readme=readme_text,
    )
    cached = cache_root() / key
    if cache and (cached / MANIFEST_FILE).is_file():
        logger.info("%s: unchanged inputs, using the cached build %s", name, key[:12])
        stored = Manifest.load(cached)
        failed = stored.below_acceptance
        if failed and not allow_below_acceptance:
            where = stored.build.get("below_acceptance", failed)
            raise BuildError(
                f"{name}: {where} (a cached build of the same inputs); nothing was written. "
                f"{_REMEDY}")
        with atomic_directory(out_dir) as staging:
            shutil.copytree(cached, staging, dirs_exist_ok=True)
            (staging / "README.md").write_text(
                _readme(name, source, units, readme_text, Manifest.load(cached), command))
        return load(out_dir)
    show = progress and sys.stderr.isatty()
    start = time.perf_counter()
    prepared = prepare_lumen(
        lumen,
        units=units,
        source=source or name,
        keep_largest=params.keep_largest,
        max_hole_perimeter=params.max_hole_perimeter,
        resolution=params.resolution,
    )
    scale = UNIT_SCALE[units]
    given_centerline, registration_report = centerline, None
    closed = capped(prepared)
    if centerline is not None and registration is not None:
        centerline, registration_report = register_centerline(
            centerline, closed, registration, params.checks.clearance
        )
    if centerline is None:
        centerline = extract_centerline(
            closed, params.skeleton, radius_hint=prepared.radius_estimate
        )
    centerline = _grafted(centerline, inlet, targets, closed, scale, name)
    centerline, grafted_ends = _grafted_to_openings(centerline, prepared, closed, name)
    prepared = _close_wall_holes(prepared, centerline, source or name,
                                 params.max_hole_perimeter)
    inlet_node, inlet_choice = _choose_inlet(
        centerline, None if inlet is None else np.asarray(inlet) * scale
    )
    if inlet is not None:
        _check_near(centerline, inlet_node, np.asarray(inlet, dtype=np.float64) * scale,
                    "inlet (snapped to the nearest vessel end)", scale, name)
    if inlet_choice.startswith("widest vessel end, but"):
        logger.warning("%s: inlet chosen as the %s", name, inlet_choice)
    # The wall is cut and thickened on the whole centerline; the checks and targets use the
    # trimmed one.
    wall_graph = centerline
    centerline, trimmed, new_index = trim_narrow_ends(centerline, params.trim_ends_below,
                                                      keep=[inlet_node])
    inlet_node = int(new_index[inlet_node])
    for end in trimmed:
        logger.info("%s: trimmed %.3g mm of the centerline narrower than %.3g mm off the vessel "
                    "end at %s (input units; its widest %.3g mm)", name, end.length * 1e3,
                    params.trim_ends_below * 1e3, np.round(np.asarray(end.end) / scale, 2).tolist(),
                    end.radius * 1e3)
    target_points = _choose_targets(
        centerline,
        inlet_node,
        None if targets is None else {k: np.asarray(v) * scale for k, v in targets.items()},
    )
    if not target_points:
        raise BuildError(f"{name}: no targets given and the centerline has no second vessel end.")
    graph = _labelled(centerline, inlet_node, target_points)
    if targets is not None:
        for label, point in target_points.items():
            _check_near(graph, graph.labels[label], point, f"target {label}", scale, name)
    _require_connected(graph, name, extracted=given_centerline is None)
    # Closing holes appended vertices only: the grafted loops' indices still hold.
    inlet_dir = _inlet_direction(graph, inlet_node, grafted_ends, prepared.mesh.vertices)
    inlet_pos = graph.nodes[inlet_node]
    inlet_radius = float(graph.radii[inlet_node])

    axis = sample_axis(graph)
    wall_axis = sample_axis(wall_graph) if trimmed else axis
    mesh = _orient_outward(prepared.mesh, wall_axis)
    walled = ~inlet_cap(mesh, inlet_pos, inlet_dir, inlet_radius)
    pieces, face_radius, face_u, face_angle = bin_faces(mesh, wall_axis, params.wall)
    pieces = [p[walled[p]] for p in pieces]
    pieces = [p for p in pieces if len(p)]
    vertices, vertex_normals = np.asarray(mesh.vertices), np.asarray(mesh.vertex_normals)
    ctx = WallContext(
        vertices=vertices,
        faces=np.asarray(mesh.faces, dtype=np.int64),
        vertex_normals=vertex_normals,
        face_normals=np.asarray(mesh.face_normals),
        face_radius=face_radius,
        face_u=face_u,
        face_angle=face_angle,
        vertex_thickness=wall_thickness(vertices, vertex_normals, wall_graph,
                                        params.wall.thickness),
        params=params.wall,
    )
    hulls = build_hulls(ctx, pieces, progress=_progress(show, f"{name}: wall hulls"))
    centerline_probes = lumen_probes(hulls, axis, params.checks)
    probes = wall_probes(
        ctx.vertices, ctx.faces, ctx.vertex_normals, ctx.face_normals, walled, ctx.vertex_thickness
    )
    wall_closed = wall_closed_fraction(hulls, probes, slack=1e-3 * float(face_radius.min()))
    given_checks: dict[str, float] = {}
    if given_centerline is not None and registration_report is not None:
        # The given curves, as they came, judged against the same hulls: nothing is hidden.
        given_checks["lumen_open_given_centerline"] = lumen_probes(
            hulls, sample_axis(given_centerline), params.checks).open_fraction
    elapsed = time.perf_counter() - start
    checks = {
        "lumen_open": centerline_probes.open_fraction,
        "lumen_probes": float(len(centerline_probes.open)),
        "wall_closed": wall_closed,
        "wall_probes": float(len(probes)),
        "hull_count": float(len(hulls)),
        "build_time_s": round(elapsed, 3),
        **given_checks,
    }
    build_record = {**asdict(params), "repairs": asdict(prepared.report)}
    if inlet_choice != "given":  # a given inlet needs no word (and keeps old folders equal)
        build_record["inlet_choice"] = inlet_choice
    if trimmed:
        build_record["trimmed_ends"] = [
            {"end": list(t.end), "length_mm": round(t.length * 1e3, 3),
             "largest_radius_mm": round(t.radius * 1e3, 3)} for t in trimmed]
    if registration is not None and registration_report is not None:
        build_record["centerline_registration"] = {
            "params": asdict(registration),
            "report": asdict(registration_report),
        }
    failed = below_acceptance(checks, params.checks.min_lumen_open,
                              params.checks.min_wall_closed)
    if failed:
        failed += _where_blocked(centerline_probes, axis, graph, scale)
        build_record["below_acceptance"] = failed
        if not allow_below_acceptance:
            raise BuildError(f"{name}: {failed}; nothing was written. {_REMEDY}")
        logger.warning("%s: %s; kept as asked (allow_below_acceptance)", name, failed)
    matrix = np.diag([scale, scale, scale, 1.0])
    manifest = Manifest(
        name=name,
        source=source,
        units=units,
        mesh_to_model=tuple(tuple(float(x) for x in row) for row in matrix),
        inlet=Inlet(_vec3(inlet_pos), _vec3(inlet_dir), inlet_radius),
        targets={k: _vec3(v) for k, v in target_points.items()},
        build=build_record,
        hull_count=len(hulls),
        mjcf=f"{name}.xml",
        checks=checks,
        content_hash=key,
    )
    with atomic_directory(out_dir) as staging:
        part_count = write_meshes(staging, hulls, mesh, prepared.display)
        try:
            write_vessel_mjcf(
                staging, name=name, hull_count=len(hulls), inlet=inlet_pos,
                targets=target_points, display_part_count=part_count,
            )
        except ValueError as exc:  # MuJoCo's compiler, on a mesh the build wrote
            reason = "; ".join(str(exc).strip().removeprefix("Error: ").splitlines())
            raise BuildError(
                f"{name}: MuJoCo cannot compile the vessel model built from "
                f"{source or 'the mesh'} ({reason}); nothing was written. This is a fault of "
                "the build, not of your mesh: please report it with the mesh."
            ) from None
        lo, hi = mesh.bounds
        write_scene(
            staging,
            name=name,
            vessel_file=f"{name}.xml",
            extent=float(np.linalg.norm(hi - lo)),
            centre=0.5 * (lo + hi),
        )
        graph.save(staging / CENTERLINE_FILE)
        manifest.save(staging)
        (staging / "README.md").write_text(
            _readme(name, source, units, readme_text, manifest, command))
        if license_text is not None:
            (staging / "LICENSE").write_text(license_text)
    if cache:
        _store_in_cache(out_dir, cached)
    logger.info(
        "%s: %d hulls, lumen open %.4f, wall closed %.4f, %.1f s",
        name,
        len(hulls),
        centerline_probes.open_fraction,
        wall_closed,
        elapsed,
    )
    return load(out_dir)
