"""The one place that knows where sim4endor's static assets live.

``mjcf/`` and ``vessels/`` sit at the repository's top level. An editable install
(``pip install -e .``) imports the package from the checkout, so they are found beside the
package directory; a wheel (``pip install .``) carries them inside the package under
``_assets/``. Both layouts keep the two folders as siblings, so relative ``<include>`` paths
between them hold either way.
"""

from __future__ import annotations

import os
from pathlib import Path

from sim4endor.errors import Sim4EndoRError

_PACKAGE_DIR = Path(__file__).resolve().parent
_CANDIDATE_ROOTS = (_PACKAGE_DIR / "_assets", _PACKAGE_DIR.parent)

#: Environment variable naming extra folders (``os.pathsep``-separated) that hold vessel folders.
VESSEL_PATH_ENV = "SIM4ENDOR_VESSEL_PATH"


class AssetNotFoundError(Sim4EndoRError, FileNotFoundError):
    """Raised when an asset folder or file cannot be found; the message says where it looked."""


def assets_root() -> Path:
    """Returns the folder that holds ``mjcf/`` and ``vessels/`` for this installation."""
    for root in _CANDIDATE_ROOTS:
        if (root / "mjcf").is_dir() and (root / "vessels").is_dir():
            return root
    looked = ", ".join(str(r) for r in _CANDIDATE_ROOTS)
    raise AssetNotFoundError(
        f"sim4endor's mjcf/ and vessels/ folders were not found (looked in: {looked}). "
        "Reinstall the package with `pip install .` or `pip install -e .` from a full checkout."
    )


def mjcf_dir() -> Path:
    """Returns the folder of static MJCF files (options, default classes, materials)."""
    return assets_root() / "mjcf"


def mjcf_path(name: str) -> Path:
    """Returns the path of a static MJCF file in ``mjcf/``, e.g. ``mjcf_path("options.xml")``."""
    path = mjcf_dir() / name
    if not path.is_file():
        available = sorted(p.name for p in mjcf_dir().glob("*.xml"))
        raise AssetNotFoundError(f"No MJCF file {name!r} in {mjcf_dir()}; available: {available}")
    return path


def vessels_dir() -> Path:
    """Returns the folder of the vessel anatomies shipped with the package."""
    return assets_root() / "vessels"


def vessel_search_path() -> tuple[Path, ...]:
    """Returns the folders searched for vessel folders, shipped anatomies first.

    Extra folders come from the ``SIM4ENDOR_VESSEL_PATH`` environment variable, so vessels a
    user built with ``sim4endor vessel build`` can be loaded by name.
    """
    extra = os.environ.get(VESSEL_PATH_ENV, "")
    return (vessels_dir(), *(Path(p).expanduser() for p in extra.split(os.pathsep) if p))


def policies_dir() -> Path:
    """Returns the folder of the pretrained policies shipped with the package: one training
    run folder per name (``config.yaml``, ``checkpoint/state.pt`` without the replay buffer,
    ``MODEL_CARD.md``), loadable wherever a run folder is."""
    return _PACKAGE_DIR / "policies"


def policy_names() -> tuple[str, ...]:
    """Names of the shipped pretrained policies, e.g. ``("generalist",)``."""
    folder = policies_dir()
    return tuple(sorted(p.name for p in folder.iterdir() if (p / "config.yaml").is_file())) \
        if folder.is_dir() else ()


#: A shipped policy's training recipe, beside its ``config.yaml`` (``sim4endor.rl.recipe``).
RECIPE_FILE = "recipe.yaml"


def recipe_names() -> tuple[str, ...]:
    """Shipped policies with a recipe, e.g. ``("generalist",)``."""
    folder = policies_dir()
    return tuple(sorted(p.name for p in folder.iterdir() if (p / RECIPE_FILE).is_file())) \
        if folder.is_dir() else ()


def run_or_policy(spec: str | Path) -> Path:
    """A shipped policy's folder for its name (``"generalist"``), else ``spec`` as a path."""
    if str(spec) in policy_names():
        return policies_dir() / str(spec)
    return Path(spec)
