"""``manifest.json``: what a vessel folder holds and how it was made."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim4endor._atomic import atomic_write_text
from sim4endor._checks import check_schema_version
from sim4endor.errors import Sim4EndoRError

MANIFEST_FILE = "manifest.json"
SCHEMA_VERSION = 1
#: What a message about a damaged or inconsistent vessel folder tells its user to do.
REBUILD = "rebuild the folder (its README names the command that built it)."


class ManifestError(Sim4EndoRError, ValueError):
    """Raised for a missing or malformed ``manifest.json``; the message names the file."""


def below_acceptance(checks: Mapping[str, float], min_lumen_open: float,
                     min_wall_closed: float) -> str:
    """A build's ``checks`` below acceptance, as one phrase ("checks below acceptance: lumen
    open 0.0000 (needs >= 0.99)"), or "" when they all pass (or are missing)."""
    failed = [f"{label} {checks[key]:.4f} (needs >= {limit:g})" for key, label, limit in (
        ("lumen_open", "lumen open", min_lumen_open),
        ("wall_closed", "wall closed", min_wall_closed)) if key in checks and checks[key] < limit]
    return ("checks below acceptance: " + ", ".join(failed)) if failed else ""


@dataclass(frozen=True)
class Inlet:
    """Where the wire enters the vessel.

    Attributes:
        position: Centre of the inlet opening in model metres.
        direction: Unit vector pointing into the vessel.
        radius: Lumen radius at the inlet (m).
    """

    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    radius: float


@dataclass(frozen=True)
class Manifest:
    """Contents of a vessel folder's ``manifest.json`` (SI units unless named otherwise).

    Attributes:
        name: Vessel name, also the folder and MJCF model name.
        source: Where the geometry came from (generator call or input mesh path).
        units: Units of the input mesh (``"um"``, ``"mm"`` or ``"m"``).
        mesh_to_model: 4×4 matrix from input-mesh coordinates (input units) to model metres.
        inlet: Wire entry point and direction.
        targets: Named target points in model metres (e.g. ``{"A": (...), "B": (...)}``).
        build: Build parameters (wall thickness, CoACD settings, ...), as given.
        hull_count: Number of convex hull geoms in the vessel MJCF.
        mjcf: File name of the vessel MJCF in the folder.
        checks: Build-time check figures (lumen-open and wall-closed fractions, build time).
        content_hash: Hash of the inputs and parameters; equal hashes mean an identical build.
    """

    name: str
    source: str
    units: str
    mesh_to_model: tuple[tuple[float, ...], ...]
    inlet: Inlet
    targets: Mapping[str, tuple[float, float, float]]
    build: Mapping[str, Any]
    hull_count: int
    mjcf: str
    checks: Mapping[str, float] = field(default_factory=dict)
    content_hash: str = ""
    schema_version: int = SCHEMA_VERSION

    @property
    def below_acceptance(self) -> str:
        """The build's checks below their acceptance thresholds (those recorded with the build,
        ``build["checks"]``), as one phrase, or "" when they pass or were not recorded."""
        limits = self.build.get("checks", {})
        return below_acceptance(self.checks, limits.get("min_lumen_open", 0.0),
                                limits.get("min_wall_closed", 0.0))

    @property
    def mesh_to_model_matrix(self) -> np.ndarray:
        """Returns ``mesh_to_model`` as a 4×4 array."""
        return np.asarray(self.mesh_to_model, dtype=np.float64).reshape(4, 4)

    def save(self, folder: Path) -> None:
        """Writes ``manifest.json`` into ``folder`` (atomically)."""
        text = json.dumps(asdict(self), indent=1, sort_keys=False)
        atomic_write_text(Path(folder) / MANIFEST_FILE, text + "\n")

    @classmethod
    def load(cls, folder: Path) -> Manifest:
        """Reads ``manifest.json`` from a vessel folder."""
        path = Path(folder) / MANIFEST_FILE
        try:
            data = json.loads(path.read_text())
        except FileNotFoundError:
            raise ManifestError(
                f"{folder} is not a vessel folder: it has no {MANIFEST_FILE}. Build one with "
                "`sim4endor vessel build MESH --name NAME --out DIR`."
            ) from None
        except json.JSONDecodeError as exc:
            raise ManifestError(f"{path} is not valid JSON: {exc}") from None
        check_schema_version(data, SCHEMA_VERSION, str(path), ManifestError)
        try:
            inlet = Inlet(
                position=tuple(data["inlet"]["position"]),
                direction=tuple(data["inlet"]["direction"]),
                radius=float(data["inlet"]["radius"]),
            )
            return cls(
                name=data["name"],
                source=data["source"],
                units=data["units"],
                mesh_to_model=tuple(tuple(row) for row in data["mesh_to_model"]),
                inlet=inlet,
                targets={k: tuple(v) for k, v in data["targets"].items()},
                build=data.get("build", {}),
                hull_count=int(data["hull_count"]),
                mjcf=data["mjcf"],
                checks=data.get("checks", {}),
                content_hash=data.get("content_hash", ""),
                schema_version=int(data.get("schema_version", SCHEMA_VERSION)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ManifestError(f"{path} is malformed ({type(exc).__name__}: {exc}).") from None
