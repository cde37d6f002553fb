"""Procedural vessel anatomies: the shipped phantoms and seeded random coronary trees.

Every generator is a pure function ``generate(config, seed) -> GeneratedAnatomy`` of a typed
frozen config and a seed; the same arguments give the identical lumen mesh and centerline.
:data:`GENERATORS` maps each generator's name (as used by ``sim4endor vessel generate NAME``)
to its function and config type.

Example:
    >>> from sim4endor.vessels.generators import CoronaryTreeConfig, coronary_tree
    >>> anatomy = coronary_tree(CoronaryTreeConfig(levels=2), seed=7)  # doctest: +SKIP
    >>> anatomy.lumen.is_watertight, sorted(anatomy.targets)           # doctest: +SKIP
    (True, ['T1', 'T2', 'T3', 'T4'])
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from sim4endor.vessels.generators.anatomy import GeneratedAnatomy, MeshResolution
from sim4endor.vessels.generators.coronary import CoronaryTreeConfig, coronary_tree
from sim4endor.vessels.generators.coronary_arteries import (
    CoronaryArteriesConfig,
    coronary_arteries,
)
from sim4endor.vessels.generators.paths import GeneratorConfigError
from sim4endor.vessels.generators.phantoms import (
    SimplifiedPhantomConfig,
    VascularPhantomConfig,
    simplified_phantom,
    vascular_phantom,
)
from sim4endor.vessels.walls import WallParams

__all__ = [
    "GENERATORS",
    "SHIPPED_PHANTOM_WALL",
    "CoronaryArteriesConfig",
    "CoronaryTreeConfig",
    "GeneratedAnatomy",
    "Generator",
    "GeneratorConfigError",
    "MeshResolution",
    "SimplifiedPhantomConfig",
    "VascularPhantomConfig",
    "coronary_arteries",
    "coronary_tree",
    "simplified_phantom",
    "vascular_phantom",
]


@dataclass(frozen=True)
class Generator:
    """A named generator.

    Attributes:
        config_type: Its frozen config dataclass (default-constructible).
        generate: ``generate(config, seed) -> GeneratedAnatomy``.
        summary: One line for ``--help``.
        wall: Wall decomposition its vessel folders are built with.
    """

    config_type: type
    generate: Callable[[Any, int], GeneratedAnatomy]
    summary: str
    wall: WallParams = field(default_factory=WallParams)


#: The shipped phantom folders (vessels/) were built with plain hulls and bisection and these
#: (then default) CoACD settings, which the manifest records; a training job uses the folders
#: and a test regenerates them byte for byte, so their generators stay pinned to it.
SHIPPED_PHANTOM_WALL = WallParams(
    use_coacd=False, coacd_threshold=0.05, coacd_mcts_iterations=20, coacd_resolution=300
)


GENERATORS: MappingProxyType[str, Generator] = MappingProxyType({
    "simplified_phantom": Generator(
        SimplifiedPhantomConfig, simplified_phantom,
        "paper Fig. 2: straight inlet, one bifurcation, End Points A and B",
        SHIPPED_PHANTOM_WALL,
    ),
    "vascular_phantom": Generator(
        VascularPhantomConfig, vascular_phantom,
        "complex 3D phantom: 3 bifurcations, straight and tortuous segments, targets A and B",
        SHIPPED_PHANTOM_WALL,
    ),
    "coronary_tree": Generator(
        CoronaryTreeConfig, coronary_tree,
        "seeded random coronary tree (Murray's law radii, tortuous branches, 2-4 levels)",
    ),
    "coronary_arteries": Generator(
        CoronaryArteriesConfig, coronary_arteries,
        "seeded left or right coronary tree of normal calibre (Dodge 1992, Finet's law) "
        "behind a 7F guide catheter; optional stenoses",
        WallParams(use_coacd=False),
    ),
})
