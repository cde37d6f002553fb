"""Bringing a lumen mesh to the resolution the wall hulls need, and splitting it for display.

A CTA segmentation exports a lumen surface at whatever resolution its marching cubes ran:
often several hundred thousand to millions of triangles, more than the wall needs and more
than MuJoCo reads from one STL file (:data:`MUJOCO_MAX_FACES`). A CAD or hand-made mesh can be
the opposite: a capped cylinder of a few long, thin triangles, whose facets are too large for
the wall pieces to follow the lumen. :func:`sim4endor.vessels.meshio.prepare_lumen` brings
both to the resolution of :class:`RemeshParams`:

* a mesh of more than ``max_faces`` faces is decimated to edges of about ``edge_fraction``
  lumen radii (at most ``max_faces``) by quadric edge collapse
  (``fast-simplification``, the Fast-Quadric-Mesh-Simplification library), which keeps the
  open vessel ends;
* faces with edges longer than ``max_edge_fraction`` lumen radii are subdivided until none
  is (``trimesh.Trimesh.subdivide_to_size``). The limit is a few radii, not the fifth of a
  radius a CTA surface has: a 60 mm facet of a 2 mm cylinder subdivided to 0.4 mm edges
  becomes 421,632 triangles, to 6 mm 5,248, and passes the checks.

The full mesh is kept for display: :func:`display_parts` cuts it into pieces below MuJoCo's
limit, each a mesh of its own in the vessel model.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import cast

import fast_simplification
import numpy as np
import trimesh

logger = logging.getLogger(__name__)

#: The most triangles MuJoCo 3.17 reads from one STL file (its ``stl_decoder`` refuses more).
MUJOCO_MAX_FACES = 200_000
#: The size (bounding-box diagonal) of the frame a mesh is decimated in; see :func:`decimate`.
_FRAME = 100.0


@dataclass(frozen=True)
class RemeshParams:
    """The resolution a lumen is brought to before the wall is built (lengths in lumen radii).

    Attributes:
        edge_fraction: The mean edge length of a decimated lumen: the lumens of the
            generated trees the project's tasks and tests build have edges of 0.35-0.4
            median lumen radii on average, and their walls pass the checks.
        max_edge_fraction: Faces with edges longer than this are subdivided. The
            generated lumens' longest edges are 1.0-1.9 median radii and the stEVE CTA
            anatomy's 2.5; a capped 2 mm cylinder of 60 mm facets passes the checks once
            they are split to 3 radii (lumen open 0.0 before, 1.0 after).
        max_faces: A lumen of more faces is decimated, to at most this many: the wall's
            build time grows with the face count, and the lumen it was built from is stored
            in the vessel folder, which MuJoCo reads only below its limit. Meshes of fewer
            faces (every lumen the project generates) are kept as they are.
    """

    edge_fraction: float = 0.3
    max_edge_fraction: float = 3.0
    max_faces: int = 100_000

    def __post_init__(self) -> None:
        if not 0 < self.edge_fraction <= self.max_edge_fraction:
            raise ValueError(
                f"RemeshParams: edge_fraction ({self.edge_fraction}) must be positive and at most "
                f"max_edge_fraction ({self.max_edge_fraction})."
            )
        if not 1000 <= self.max_faces < MUJOCO_MAX_FACES:
            raise ValueError(
                f"RemeshParams: max_faces ({self.max_faces}) must be from 1000 to below "
                f"MuJoCo's {MUJOCO_MAX_FACES} faces per mesh."
            )


def faces_for(mesh: trimesh.Trimesh, edge: float) -> int:
    """The number of equilateral triangles of side ``edge`` that tile ``mesh``'s area."""
    return int(np.ceil(float(mesh.area) / (np.sqrt(3.0) / 4.0 * edge**2)))


def decimate(mesh: trimesh.Trimesh, faces: int) -> trimesh.Trimesh:
    """``mesh`` reduced to about ``faces`` triangles by quadric edge collapse, its open
    boundaries (the vessel ends) kept as they are.

    A mesh of needle-shaped triangles (a long facet split four ways, again and again) hardly
    collapses: every collapse would flip a neighbour. The result then keeps more faces than
    asked, with a warning; the build goes on with them, only slower.
    """
    # The library's collapse thresholds are absolute (squared distances from 1e-9 up), so the
    # mesh goes in a frame 100 units across, as a mesh in millimetres is. And in float32:
    # given float64 coordinates, a Loop-subdivided coronary tree of 1.1 M faces stopped at
    # 79,772 of the 20,000 faces asked (measured, fast-simplification 0.2.0; the same
    # vertices rounded to float32 reach 20,000). The rounding is 1e-7 of the mesh's size.
    centre, size = mesh.bounds.mean(axis=0), float(mesh.scale)
    vertices, kept = fast_simplification.simplify(
        ((np.asarray(mesh.vertices) - centre) * (_FRAME / size)).astype(np.float32),
        np.asarray(mesh.faces, dtype=np.int32), target_count=faces, preserve_border=True,
    )
    vertices = vertices.astype(np.float64) * (size / _FRAME) + centre
    # An edge collapse can leave a triangle on two of its own corners; it covers nothing and
    # makes its edges non-manifold, so it goes (the surface stays closed without it).
    kept = kept[(kept[:, 0] != kept[:, 1]) & (kept[:, 1] != kept[:, 2])
                & (kept[:, 2] != kept[:, 0])]
    result = trimesh.Trimesh(vertices, kept, process=False)
    result.remove_unreferenced_vertices()
    if len(result.faces) > 1.1 * faces:
        logger.warning("decimation stopped at %d faces of the %d asked (needle-shaped triangles "
                       "do not collapse); the wall is built from them, more slowly",
                       len(result.faces), faces)
    return result


def display_parts(mesh: trimesh.Trimesh, max_faces: int = MUJOCO_MAX_FACES - 1
                  ) -> list[trimesh.Trimesh]:
    """``mesh`` cut into pieces of at most ``max_faces`` triangles, each a contiguous slab
    along the mesh's longest extent (so a renderer can cull them), for MuJoCo's limit."""
    if len(mesh.faces) <= max_faces:
        return [mesh]
    centres = mesh.triangles_center
    order = np.argsort(centres[:, int(np.argmax(np.ptp(centres, axis=0)))], kind="stable")
    pieces = int(np.ceil(len(order) / max_faces))
    # One mesh per face list: a list (submesh's return type also allows one merged mesh).
    return cast(list[trimesh.Trimesh], mesh.submesh(np.array_split(order, pieces)))
