"""Vessel anatomies: shipped phantoms, generated trees and user-built CTA meshes.

Example:
    >>> from sim4endor import vessels
    >>> vessels.names()                          # doctest: +SKIP
    ('simplified_phantom', 'vascular_phantom')
    >>> vessel = vessels.load("simplified_phantom")  # doctest: +SKIP
    >>> vessel.mjcf_path, vessel.targets["A"]        # doctest: +SKIP
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sim4endor import assets
from sim4endor.errors import Sim4EndoRError
from sim4endor.vessels.centerline import INLET_LABEL, CenterlineGraph
from sim4endor.vessels.manifest import MANIFEST_FILE, REBUILD, Manifest

if TYPE_CHECKING:
    import trimesh

logger = logging.getLogger(__name__)

CENTERLINE_FILE = "centerline.json"
SCENE_FILE = "scene.xml"
LUMEN_FILE = "lumen.stl"

__all__ = ["CenterlineGraph", "Manifest", "Vessel", "VesselFolderError", "VesselNotFoundError",
           "load", "names"]


class VesselNotFoundError(Sim4EndoRError, LookupError):
    """Raised when a vessel name or path does not resolve to a vessel folder."""


@dataclass(frozen=True, eq=False)
class Vessel:
    """A built vessel folder, ready to be placed in a scene.

    Attributes:
        root: The vessel folder.
        manifest: Its parsed ``manifest.json``.
        centerline: Its centerline graph (model metres).
    """

    root: Path
    manifest: Manifest
    centerline: CenterlineGraph

    def __repr__(self) -> str:
        # The generated repr printed every centerline node and radius: hundreds of lines.
        graph = self.centerline
        return (
            f"Vessel({self.name!r}, root={str(self.root)!r}, hulls={self.manifest.hull_count}, "
            f"centerline={len(graph.nodes)} nodes / {graph.total_length() * 1e3:.1f} mm, "
            f"radius {graph.radii.min() * 1e3:.2f}-{graph.radii.max() * 1e3:.2f} mm, "
            f"targets={sorted(self.targets)})"
        )

    @property
    def name(self) -> str:
        """The vessel's name."""
        return self.manifest.name

    @property
    def mjcf_path(self) -> Path:
        """The vessel MJCF (hull geoms under the vessel's default class)."""
        return self.root / self.manifest.mjcf

    @property
    def scene_path(self) -> Path:
        """``scene.xml``, which includes the vessel MJCF with lights and a camera."""
        return self.root / SCENE_FILE

    @property
    def inlet_position(self) -> np.ndarray:
        """Centre of the inlet opening (m)."""
        return np.asarray(self.manifest.inlet.position, dtype=np.float64)

    @property
    def inlet_direction(self) -> np.ndarray:
        """Unit vector into the vessel at the inlet."""
        return np.asarray(self.manifest.inlet.direction, dtype=np.float64)

    @property
    def targets(self) -> dict[str, np.ndarray]:
        """Named target points (m)."""
        return {k: np.asarray(v, dtype=np.float64) for k, v in self.manifest.targets.items()}

    @functools.cached_property
    def lumen(self) -> trimesh.Trimesh:
        """The lumen surface (m) with its open vessel ends closed by fans, read on first use:
        the exact inside that the tasks' tip check falls back on where the centerline's tubes
        leave it in doubt (:func:`sim4endor.tasks.navigation.lumen_excess`)."""
        import trimesh

        from sim4endor.vessels.meshio import closed

        return closed(trimesh.load_mesh(self.root / LUMEN_FILE))

    def surface_excess(self, point: np.ndarray) -> float:
        """How far ``point`` (m) lies outside :attr:`lumen` (m; negative inside): exact, about
        2 ms on a real tree's 14,000 faces."""
        import trimesh

        return -float(trimesh.proximity.signed_distance(self.lumen, [point])[0])


def _is_vessel_folder(path: Path) -> bool:
    return (path / MANIFEST_FILE).is_file()


def names() -> tuple[str, ...]:
    """Returns the names of the vessels found on the vessel search path, sorted."""
    found: set[str] = set()
    for folder in assets.vessel_search_path():
        if folder.is_dir():
            found.update(p.name for p in folder.iterdir() if _is_vessel_folder(p))
    return tuple(sorted(found))


def resolve(name_or_path: str | Path) -> Path:
    """Returns the vessel folder for a shipped/registered name or a filesystem path."""
    candidate = Path(name_or_path).expanduser()
    if _is_vessel_folder(candidate):
        return candidate.resolve()
    if isinstance(name_or_path, str) and "/" not in name_or_path and "\\" not in name_or_path:
        for folder in assets.vessel_search_path():
            if _is_vessel_folder(folder / name_or_path):
                return (folder / name_or_path).resolve()
    raise VesselNotFoundError(
        f"No vessel {str(name_or_path)!r}: it is neither a vessel folder (with {MANIFEST_FILE}) "
        f"nor a known name. Known vessels: {list(names())}. Add folders of your own builds to "
        f"${assets.VESSEL_PATH_ENV}."
    )


class VesselFolderError(Sim4EndoRError, ValueError):
    """Raised for a vessel folder whose files disagree; the message names the file and what."""


def load(name_or_path: str | Path) -> Vessel:
    """Loads a vessel by name (e.g. ``"simplified_phantom"``) or by folder path.

    Raises:
        VesselNotFoundError: If it names no vessel folder.
        VesselFolderError: If the manifest names a target, or the centerline lacks an inlet,
            that the tasks would look up in the centerline.
    """
    root = resolve(name_or_path)
    manifest = Manifest.load(root)
    centerline = CenterlineGraph.load(root / CENTERLINE_FILE)
    missing = [name for name in (INLET_LABEL, *manifest.targets) if name not in centerline.labels]
    if missing:
        raise VesselFolderError(
            f"{root}: {CENTERLINE_FILE} has no node labelled {missing} (it labels "
            f"{sorted(centerline.labels)}), which {MANIFEST_FILE} names as inlet and targets; "
            f"{REBUILD}"
        )
    failed = manifest.below_acceptance
    if failed:
        # Built with allow_below_acceptance: every command that loads it says so.
        logger.warning("vessel %s (%s): %s; the wire may not reach its targets", manifest.name,
                       root, failed)
    return Vessel(root=root, manifest=manifest, centerline=centerline)
