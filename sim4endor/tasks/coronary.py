"""The ``coronary`` domain: left and right coronary trees of normal calibre behind a guide catheter.

Each episode draws one tree of a seeded pool (seeds ``pool_seed ... pool_seed + pool_size -
1``) and any distal branch end of it as the target. A tree is a
:func:`~sim4endor.vessels.generators.coronary_arteries.coronary_arteries` anatomy: left
(LM → LAD with two diagonals, LCX with an obtuse marginal) for even seeds and right (RCA
with the acute marginal, PDA and posterolateral branch) for odd ones, unless ``side`` says;
it is generated and built the first time an episode draws it, cached on disk (named by seed
and content hash) and compiled once.

The wire defaults to the catalogue's ``workhorse`` (PCI is done with 0.014 in workhorse wires
of about 1 gf); a pre-bent tip wider than the guide catheter's bore, where the wire starts, is
narrowed once, for every tree alike. Each tree's driver travel and wire length are fitted
to its own deepest target (+10 mm), because the physics cost grows about with the square of
the segment count: the deepest targets of trees 0-7 lie 79-137 mm in (mean 119 mm), so most
trees compile with 5-27 fewer wire segments than a wire for the deepest target of any tree
(:data:`MAX_INSERTION`) would need. Only a pool whose observation includes ``wire_shape``
needs one wire length for all trees (``same_wire=True``), so that the entry has one size.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Literal

from sim4endor.models import wires
from sim4endor.models.scene import (
    SOFT_TIP_FILL,
    SceneConfig,
    fit_segments,
    fit_tip,
    with_travel,
)
from sim4endor.tasks.anatomy import Anatomy, AnatomyPool, cached_build, compile_anatomy
from sim4endor.tasks.anatomy import default_cache_dir as anatomy_cache_dir
from sim4endor.tasks.config import TaskConfigError, TerminationConfig

if TYPE_CHECKING:
    from sim4endor.models.guidewire import GuidewireConfig
    from sim4endor.vessels.generators.coronary_arteries import CoronaryArteriesConfig

#: Pool members when ``task_kwargs`` does not say.
DEFAULT_POOL_SIZE = 8
#: The wire when ``task_kwargs`` does not say: the ``workhorse`` with the 2 mm/45° tip it had in
#: the catalogue until 2026-12-04, with which every figure of this domain was measured (the
#: catalogue's shape now is the one for user-built coronary-calibre folders).
DEFAULT_WIRE: Mapping[str, Any] = MappingProxyType(
    {"preset": "workhorse", "tip": wires.TipShape.degrees(2.0, 45.0)}
)
#: Episode limits of the domain. 40 s, not the phantoms' 20 s: the deepest targets lie 156 mm
#: in, 5 s at the driver's top speed, and each of up to four bifurcations on the way may take a
#: roll and a retreat; measured on tuning trees 0-19 with the expert, 3 of 76 targets were
#: reached between 20 and 40 s (and 57 of 76 within 40 s). The tip-force failure at 0.6 N,
#: below the lowest force published for a guidewire-like probe puncturing arterial tissue
#: (0.61 N for a 2-week-old occlusion cap, ex vivo rabbit femoral arteries: Thind, Strauss et
#: al., EuroIntervention; fibrous caps took up to 1.52 N). No puncture force of a healthy
#: coronary wall was found; its wall is thinner than a fibrous cap, so the lowest figure is
#: taken. The paper's phantoms keep its 1 N. The force compared is the tip's mean over the
#: control step (``tip_force_mean``): the threshold is a puncture force measured by a slow
#: push, and the force of the x10^4 mass-scaled wire at one physics step is dominated by
#: the scaled mass's impacts on the wall (docs/guidewire.md, "Inertia honesty").
TERMINATION = TerminationConfig(time_limit=40.0, max_tip_force=0.6, tip_force_mean=True)
#: Insertion travel of the driver when every tree gets the same wire (m): the deepest target
#: of 80 generated trees (40 left, 40 right, seeds 0-39) lies 156 mm along the centerline from
#: the catheter's proximal end.
MAX_INSERTION = 0.16

Sides = Literal["left", "right", "both"]
#: The pool's anatomy: ``normal`` arteries (the generator's default settings), or ``wide``,
#: each tree's settings drawn from
#: :class:`~sim4endor.vessels.generators.coronary_arteries.AnatomyVariation` (tortuous,
#: stenosed, narrower; for training beyond normal anatomy).
Anatomies = Literal["normal", "wide"]
ANATOMIES: tuple[str, ...] = ("normal", "wide")


def default_cache_dir() -> Path:
    """Returns ``$XDG_CACHE_HOME/sim4endor/coronary`` (default under ``~/.cache``)."""
    return anatomy_cache_dir("coronary")


def side_of(seed: int, side: Sides) -> Literal["left", "right"]:
    """The tree side of a pool seed: ``side``, or left for even seeds and right for odd."""
    if side == "both":
        return "left" if seed % 2 == 0 else "right"
    return side


def generator_config(seed: int, side: Sides, anatomy: Anatomies = "normal"
                     ) -> CoronaryArteriesConfig:
    """The generator settings of the tree of ``seed`` in a pool of ``anatomy``."""
    from sim4endor.vessels.generators.coronary_arteries import (
        AnatomyVariation,
        CoronaryArteriesConfig,
    )

    if anatomy not in ANATOMIES:
        raise TaskConfigError(f"task_kwargs anatomy must be one of {list(ANATOMIES)}, got "
                              f"{anatomy!r}.")
    tree_side = side_of(seed, side)
    if anatomy == "wide":
        return AnatomyVariation().draw(tree_side, seed)
    return CoronaryArteriesConfig(side=tree_side)


def scene_for(base: SceneConfig | None, same_wire: bool = False,
              anatomy: Anatomies = "normal") -> SceneConfig:
    """The scene a pool's trees are compiled from: travel to the deepest target, the wire long
    enough for it and a tip wider than the guide catheter's bore allows
    (:data:`~sim4endor.models.scene.SOFT_TIP_FILL`) narrowed to it (the catalogue's coronary
    tips are kept as shaped). Each tree then fits its own travel and shaft segments
    (:func:`build_member`); with ``same_wire`` every tree keeps this scene, its shaft
    segments short enough for the tightest bend the generator draws."""
    from sim4endor.vessels.generators.coronary_arteries import (
        AnatomyVariation,
        CoronaryArteriesConfig,
    )

    scene = with_travel(base or SceneConfig(wire=wires.resolve(DEFAULT_WIRE)), MAX_INSERTION)
    generator = CoronaryArteriesConfig()
    if anatomy == "wide":
        generator = dataclasses.replace(
            generator, min_diameter=AnatomyVariation().min_diameter)
    wire = _fit_to_catheter(scene.wire, generator)
    if not same_wire:
        return dataclasses.replace(scene, wire=wire)
    # The tightest bend: the narrowest lumen at the largest curvature the generator allows
    # (0.75 mm at 2.5 radii, 1.9 mm). A 4.85 mm shaft segment would bow 1.6 mm off the axis
    # there, 2.7 times the room; such pinched segments blew a workhorse with a hydrophilic
    # coat's friction up in 6 of 79 tuning episodes (a 2.6 mm bend of tree 400's OM1).
    # Fitted: about 2.5 mm.
    narrowest = 0.5 * generator.min_diameter
    wire = fit_segments(wire, narrowest / generator.max_curvature_ratio, narrowest,
                        where="a coronary tree")
    return dataclasses.replace(scene, wire=wire)


def build_member(seed: int, cache_dir: Path, side: Sides, scene: SceneConfig,
                 same_wire: bool = False, anatomy: Anatomies = "normal",
                 vary_wire: bool = False) -> Anatomy:
    """Generates the tree of ``seed``, builds it once (cached on disk) and compiles it with
    ``scene``, its travel fitted to the tree's deepest target and its shaft segments to the
    bends and junctions the wire can reach (:func:`~sim4endor.models.scene.config_for_vessel`)
    unless ``same_wire``; with ``vary_wire`` the tree's own unit of the scene's wire
    (:class:`~sim4endor.models.wires.WireVariation`, drawn from ``seed``), its tip narrowed
    to the guide catheter's bore again."""
    from sim4endor.vessels.build import BuildParams
    from sim4endor.vessels.generators.coronary_arteries import coronary_arteries
    from sim4endor.vessels.walls import WallParams

    config = generator_config(seed, side, anatomy)
    # Plain hulls and bisection, as for random_coronary: CoACD saves no hulls on tubes.
    params = BuildParams(wall=WallParams(use_coacd=False))
    name = tree_name(seed, side, anatomy)
    folder = cached_build(coronary_arteries(config, seed=seed), name, cache_dir, config,
                          params)
    if vary_wire:
        unit = wires.WireVariation.catalogue().draw(scene.wire, seed)
        scene = dataclasses.replace(scene, wire=_fit_to_catheter(unit, config))
    return compile_anatomy(folder, scene, fit="none" if same_wire else "all")


def _fit_to_catheter(wire: GuidewireConfig, generator: CoronaryArteriesConfig
                     ) -> GuidewireConfig:
    """``wire`` with a tip wider than the generator's guide catheter allows narrowed to it."""
    return fit_tip(wire, generator.catheter_radius, SOFT_TIP_FILL,
                   where="a coronary tree's guide catheter")


def tree_name(seed: int, side: Sides, anatomy: Anatomies = "normal") -> str:
    """The tree's name, e.g. ``left_coronary_00012`` or ``wide_right_coronary_00301``."""
    prefix = "" if anatomy == "normal" else f"{anatomy}_"
    return f"{prefix}{side_of(seed, side)}_coronary_{seed:05d}"


def pool(size: int, seed: int, side: Sides = "both", cache_dir: Path | None = None,
         scene: SceneConfig | None = None, target: str | None = None,
         same_wire: bool = False, target_weights: Mapping[str, float] | None = None,
         anatomy: Anatomies = "normal", vary_wire: bool = False) -> AnatomyPool:
    """Returns the lazily built pool of ``size`` trees with seeds ``seed ... seed + size - 1``.

    Args:
        size: Number of trees.
        seed: Seed of the first tree.
        side: ``"left"``, ``"right"`` or ``"both"`` (even seeds left, odd seeds right).
        cache_dir: Where built trees are kept (default :func:`default_cache_dir`).
        scene: Wire, driver and timestep; the driver's travel and the wire's length and tip
            are fitted (:func:`scene_for`). Default: the ``workhorse`` wire.
        target: Aim at this branch end (e.g. ``"D1"``) in every episode instead of drawing
            one; every tree drawn must have it (a left target in a right tree is an error).
        same_wire: Give every tree the wire for :data:`MAX_INSERTION` of travel instead of
            fitting each tree's travel to its deepest target (slower; for ``wire_shape``).
        target_weights: Draw targets by these relative weights per label (others 1), e.g.
            ``{"AM": 3, "RV": 3}`` (:class:`~sim4endor.tasks.anatomy.AnatomyPool`).
        anatomy: ``normal`` or ``wide`` (:data:`Anatomies`).
        vary_wire: Give each tree its own unit of the wire (:func:`build_member`): stiffness,
            friction and tip shape drawn within the catalogue's ranges, for training a
            policy that must not rely on one unit's response.

    Raises:
        TaskConfigError: For a bad side or anatomy, or ``vary_wire`` with ``same_wire``.
    """
    if side not in ("left", "right", "both"):
        raise TaskConfigError(f"task_kwargs side must be 'left', 'right' or 'both', got {side!r}.")
    generator_config(seed, side, anatomy)  # refuses an unknown anatomy before any build
    if not isinstance(vary_wire, bool):
        raise TaskConfigError(f"task_kwargs vary_wire must be true or false, got {vary_wire!r}.")
    if vary_wire and same_wire:
        raise TaskConfigError("task_kwargs vary_wire gives each tree its own wire, which the "
                              "wire_shape observation's one wire for every tree cannot be; "
                              "leave one of them out.")
    folder = cache_dir or default_cache_dir()
    fitted = scene_for(scene, same_wire, anatomy)
    return AnatomyPool(
        [functools.partial(build_member, seed + k, folder, side, fitted, same_wire,
                           anatomy=anatomy, vary_wire=vary_wire)
         for k in range(size)],
        target=target,
        target_weights=target_weights,
    )
