"""Reads 3D Slicer centerline curves (``.mrk.json`` markups) into one centerline graph.

Slicer's *Extract Centerline* module writes one markups "Curve" per branch, with a per-point
"Radius" measurement (the maximal inscribed sphere). Curves are joined into a graph where an
end point of one curve lies within ``join_tolerance`` × its radius of a point of another curve
(coincident end points at a bifurcation, or an end touching another curve's interior).

Coordinates: markups files name their ``coordinateSystem`` (``LPS`` or ``RAS``); points are
converted into the frame of the mesh (``mesh_frame``, default ``LPS``, which is how Slicer 4.11+
saves models) by flipping x and y when the two differ, and from the file's
``coordinateUnits`` to metres. For the shared stEVE_bench anatomy the raw LPS points lie inside
the OBJ mesh (median distance to the surface about one radius), so the mesh is in LPS too.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from sim4endor.errors import Sim4EndoRError
from sim4endor.vessels.centerline import CenterlineGraph

Frame = Literal["LPS", "RAS"]
UNITS_TO_M = {"mm": 1e-3, "m": 1.0, "cm": 1e-2, "um": 1e-6}


class SlicerCurveError(Sim4EndoRError, ValueError):
    """Raised for an unreadable or unusable markups file; the message names the file."""


@dataclass(frozen=True, eq=False)
class Curve:
    """One centerline curve in metres, in the mesh frame.

    Attributes:
        name: The curve's file stem.
        points: (N, 3) control points (m).
        radii: (N,) lumen radius at each point (m).
    """

    name: str
    points: NDArray[np.float64]
    radii: NDArray[np.float64]


def read_curve(path: Path, mesh_frame: Frame = "LPS") -> list[Curve]:
    """Reads every "Curve" markup of one ``.mrk.json`` file."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
        markups = data["markups"]
    except FileNotFoundError:
        raise SlicerCurveError(f"{path}: no such centerline file.") from None
    except (json.JSONDecodeError, KeyError, TypeError, UnicodeDecodeError):
        raise SlicerCurveError(
            f"{path} is not a 3D Slicer markups JSON file (.mrk.json with a 'markups' list)."
        ) from None
    curves = []
    for index, markup in enumerate(markups):
        if markup.get("type") != "Curve":
            continue
        points = np.array([p["position"] for p in markup.get("controlPoints", [])], dtype=float)
        if len(points) < 2:
            raise SlicerCurveError(f"{path}: curve {index} has fewer than two control points.")
        system = markup.get("coordinateSystem", "LPS")
        if system not in ("LPS", "RAS"):
            raise SlicerCurveError(f"{path}: unknown coordinateSystem {system!r}.")
        if system != mesh_frame:
            points = points * np.array([-1.0, -1.0, 1.0])
        units = markup.get("coordinateUnits", "mm")
        if units not in UNITS_TO_M:
            raise SlicerCurveError(f"{path}: unknown coordinateUnits {units!r}.")
        radius = next(
            (m for m in markup.get("measurements", []) if m.get("name") == "Radius"), None
        )
        values = None if radius is None else radius.get("controlPointValues")
        if not values or len(values) != len(points):
            raise SlicerCurveError(
                f"{path}: curve {index} has no per-point 'Radius' measurement. Extract the "
                "centerline with Slicer's Extract Centerline module, which adds it."
            )
        scale = UNITS_TO_M[units]
        curves.append(
            Curve(
                name=path.name.removesuffix(".mrk.json"),
                points=points * scale,
                radii=np.asarray(values, dtype=float) * scale,
            )
        )
    if not curves:
        raise SlicerCurveError(f"{path} holds no markups of type 'Curve'.")
    return curves


def join_curves(curves: Sequence[Curve], join_tolerance: float = 0.5) -> CenterlineGraph:
    """Joins curves into one graph (m); see the module docstring for the rule.

    Each node's ``branch`` is its curve (``branch_names`` are the file stems), so later steps
    can name the curve a problem comes from.

    Args:
        curves: The curves.
        join_tolerance: An end point joins the nearest point of another curve within this many
            of its radii.
    """
    offsets = np.cumsum([0] + [len(c.points) for c in curves])
    points = np.vstack([c.points for c in curves])
    radii = np.concatenate([c.radii for c in curves])
    owner = np.repeat(np.arange(len(curves)), [len(c.points) for c in curves])
    edges = np.vstack(
        [
            np.column_stack([np.arange(a, b - 1), np.arange(a + 1, b)])
            for a, b in itertools.pairwise(offsets)
        ]
    )
    parent = np.arange(len(points))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = int(parent[i])
        return i

    tree = cKDTree(points)
    for c, (start, stop) in enumerate(itertools.pairwise(offsets)):
        for end in (int(start), int(stop) - 1):
            reach = join_tolerance * max(float(radii[end]), 1e-9)
            near = [n for n in tree.query_ball_point(points[end], reach) if owner[n] != c]
            if near:
                target = min(near, key=lambda n: float(np.linalg.norm(points[n] - points[end])))
                parent[find(end)] = find(target)
    roots = np.array([find(i) for i in range(len(points))])
    keep, remap = np.unique(roots, return_inverse=True)
    merged_edges = remap[edges]
    merged_edges = merged_edges[merged_edges[:, 0] != merged_edges[:, 1]]
    merged_edges = np.unique(np.sort(merged_edges, axis=1), axis=0)
    names = tuple(dict.fromkeys(c.name for c in curves))
    branch = np.array([names.index(curves[c].name) for c in owner[keep]], dtype=np.int64)
    graph = CenterlineGraph(points[keep], radii[keep], merged_edges, branch=branch,
                            branch_names=names)
    if graph.num_components() > 1:
        raise SlicerCurveError(
            f"The {len(curves)} centerline curves form {graph.num_components()} separate pieces: "
            "some curve ends do not touch another curve. Check the files, or raise "
            "join_tolerance (--join-tolerance, in radii)."
        )
    return graph


def read_slicer_centerline(
    paths: Sequence[Path], *, mesh_frame: Frame = "LPS", join_tolerance: float = 0.5
) -> CenterlineGraph:
    """Reads and joins ``.mrk.json`` centerline files (folders are searched for them)."""
    files: list[Path] = []
    for path in map(Path, paths):
        files.extend(sorted(path.glob("*.mrk.json")) if path.is_dir() else [path])
    if not files:
        raise SlicerCurveError(f"No .mrk.json files in {[str(p) for p in paths]}.")
    curves = [curve for f in files for curve in read_curve(f, mesh_frame)]
    return join_curves(curves, join_tolerance)
