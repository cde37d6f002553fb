"""Anatomies a navigation task can run in: a vessel, its compiled scene and its targets.

A task draws one (anatomy, target) per episode from an :class:`AnatomySource`. A fixed
source always returns the same compiled model, so a reset only resets the state; a pool of
randomly generated trees compiles each anatomy once, the first time it is drawn.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import mujoco
import numpy as np
from filelock import FileLock

from sim4endor import vessels
from sim4endor._checks import is_number
from sim4endor.models.scene import SceneConfig, build_model, config_for_vessel, fit_travel
from sim4endor.tasks.config import TaskConfigError
from sim4endor.vessels import Vessel
from sim4endor.vessels.manifest import MANIFEST_FILE

if TYPE_CHECKING:
    from sim4endor.vessels.build import BuildParams
    from sim4endor.vessels.generators import GeneratedAnatomy


@dataclass(frozen=True, eq=False)
class Anatomy:
    """A vessel with its compiled scene (vessel + wire + driver).

    Attributes:
        key: Stable identifier (the vessel folder), used to cache per-anatomy data.
        vessel: The vessel folder's contents.
        model: The compiled MuJoCo model of the scene.
    """

    key: str
    vessel: Vessel
    model: mujoco.MjModel


#: How :func:`compile_anatomy` fits the scene to the vessel: travel and tip
#: (:func:`~sim4endor.models.scene.config_for_vessel`), the travel only
#: (:func:`~sim4endor.models.scene.fit_travel`), or not at all.
Fit = Literal["all", "travel", "none"]


def compile_anatomy(
    vessel: str | Path | Vessel, scene: SceneConfig | None = None, fit: Fit = "all"
) -> Anatomy:
    """Loads a vessel (name, folder or :class:`Vessel`) and compiles its scene.

    The scene module caches compiled models per (vessel folder, scene config), so calling
    this again for the same anatomy does not recompile.

    Args:
        vessel: Vessel name, folder or loaded vessel.
        scene: Wire, driver and timestep (defaults: :class:`SceneConfig`).
        fit: ``"all"``: fit the insertion range and wire length to the deepest target (fewer
            segments, faster) and the tip bend to the narrowest lumen
            (:func:`sim4endor.models.scene.config_for_vessel`); ``"travel"``: only the
            former (pools whose tip is fitted to the generator's narrowest lumen);
            ``"none"``: use ``scene`` as it is (pools whose members must all have the same
            wire, e.g. for the ``wire_shape`` observation).
    """
    vessel = vessel if isinstance(vessel, Vessel) else vessels.load(vessel)
    config = scene or SceneConfig()
    if fit == "all":
        config = config_for_vessel(vessel, config)
    elif fit == "travel":
        config = fit_travel(vessel, config)
    model = build_model(vessel, config)
    return Anatomy(key=str(vessel.root), vessel=vessel, model=model)


class AnatomySource:
    """Yields the (anatomy, target name) of each episode; subclasses decide how."""

    def draw(self, random: np.random.RandomState) -> tuple[Anatomy, str]:
        """Returns the anatomy and target label for a new episode."""
        raise NotImplementedError

    def initial(self) -> Anatomy:
        """Returns the anatomy the physics is first built with."""
        raise NotImplementedError


class FixedAnatomy(AnatomySource):
    """One anatomy and one target for every episode (the phantom tasks)."""

    def __init__(self, anatomy: Anatomy, target: str) -> None:
        """Checks that ``target`` is a labelled target of the vessel.

        Args:
            anatomy: The compiled anatomy.
            target: Centerline label of the target, e.g. ``"A"``.
        """
        check_target(anatomy.vessel, target)
        self._anatomy = anatomy
        self._target = target

    def draw(self, random: np.random.RandomState) -> tuple[Anatomy, str]:
        """Returns the fixed anatomy and target (``random`` is unused)."""
        return self._anatomy, self._target

    def initial(self) -> Anatomy:
        """Returns the fixed anatomy."""
        return self._anatomy


class AnatomyPool(AnatomySource):
    """A seeded pool of anatomies built on demand; each episode draws one and a target.

    Building an anatomy (generating a tree, decomposing its wall, compiling the scene) costs
    seconds, so the pool holds ``size`` builders and calls each at most once; the builders
    themselves cache their vessel folders on disk.
    """

    def __init__(self, builders: Sequence[Callable[[], Anatomy]], target: str | None = None,
                 target_weights: Mapping[str, float] | None = None) -> None:
        """Stores the builders.

        Args:
            builders: One zero-argument function per pool member returning its anatomy.
            target: Aim every episode at this target label (every member drawn must have
                it); ``None`` draws one of the member's targets.
            target_weights: Relative weight of drawing a target, by label (e.g. ``{"AM": 3}``
                draws a tree's acute marginal three times as often as each of its other
                targets, whose weight is 1): a curriculum that trains more on the branches a
                policy misses. ``None`` draws uniformly.

        Raises:
            TaskConfigError: For no builders, a weight that is negative or not finite, or
                weights given with ``target``.
        """
        if not builders:
            raise TaskConfigError("An anatomy pool needs at least one member.")
        if target_weights is not None:
            if target is not None:
                raise TaskConfigError("task_kwargs target fixes the target; target_weights "
                                      "weigh drawn ones: give one of them.")
            bad = {label: weight for label, weight in target_weights.items()
                   if not (is_number(weight) and weight >= 0)}
            if bad:
                raise TaskConfigError(f"task_kwargs target_weights must be finite and >= 0, "
                                      f"got {bad}.")
        self._builders = tuple(builders)
        self._built: dict[int, Anatomy] = {}
        self._target = target
        self._weights = None if target_weights is None else dict(target_weights)

    def _get(self, index: int) -> Anatomy:
        if index not in self._built:
            self._built[index] = self._builders[index]()
        return self._built[index]

    def draw(self, random: np.random.RandomState) -> tuple[Anatomy, str]:
        """Draws a member uniformly, then one of its targets (uniformly, or by the pool's
        ``target_weights``).

        Raises:
            TaskConfigError: If ``target_weights`` weigh every target of the member drawn 0.
        """
        anatomy = self._get(int(random.randint(len(self._builders))))
        if self._target is not None:
            check_target(anatomy.vessel, self._target)
            return anatomy, self._target
        targets = sorted(anatomy.vessel.targets)
        if self._weights is None:
            return anatomy, targets[int(random.randint(len(targets)))]
        weights = np.array([self._weights.get(label, 1.0) for label in targets])
        if weights.sum() <= 0:
            raise TaskConfigError(f"task_kwargs target_weights weigh every target of "
                                  f"{anatomy.vessel.name} ({targets}) 0.")
        return anatomy, targets[int(random.choice(len(targets), p=weights / weights.sum()))]

    def initial(self) -> Anatomy:
        """Returns the first member (built now if needed)."""
        anatomy = self._get(0)
        if self._target is not None:
            check_target(anatomy.vessel, self._target)
        return anatomy


def cache_folder(tree: GeneratedAnatomy, name: str, cache_dir: Path, config: object,
                 params: BuildParams) -> Path:
    """The vessel folder :func:`cached_build` keeps ``tree`` in.

    Its name carries a hash of the generated lumen, the generator config and the build
    settings, so a changed generator or package version builds a new folder instead of
    silently reusing a stale one, and processes sharing the cache never rewrite a folder
    another one is reading.
    """
    from sim4endor.vessels.build import content_hash

    digest = content_hash(tree.lumen, config=repr(config), params=repr(params))[:12]
    return cache_dir / f"{name}_{digest}"


def cached_build(tree: GeneratedAnatomy, name: str, cache_dir: Path, config: object,
                 params: BuildParams) -> Path:
    """Builds a generated tree into ``cache_dir`` once (:func:`cache_folder`); returns its
    vessel folder."""
    from sim4endor.vessels.build import build_vessel

    def build(out_dir: Path) -> None:
        # A pool draws its trees during training: one whose checks fall below acceptance is
        # kept, and every load of it warns, rather than ending the run.
        build_vessel(tree.lumen, name=name, out_dir=out_dir, units="m",
                     centerline=tree.centerline, inlet=tree.inlet_position,
                     targets=tree.targets, source=tree.description, params=params,
                     progress=False, allow_below_acceptance=True)

    return build_once(cache_folder(tree, name, cache_dir, config, params), build)


def build_once(folder: Path, build: Callable[[Path], object]) -> Path:
    """Runs ``build(folder)`` unless ``folder`` already holds a finished vessel; returns it.

    ``folder`` must be named after everything its build depends on (a content hash), so it
    is never rewritten once built. A process that finds another one building the same folder
    waits for it and uses its result: training workers draw from one pool, and without the
    lock two of them built the same tree at once, each replacing the folder the other was
    still copying into the build cache.
    """
    if (folder / MANIFEST_FILE).is_file():
        return folder
    folder.parent.mkdir(parents=True, exist_ok=True)
    with FileLock(lock_path(folder)):
        if not (folder / MANIFEST_FILE).is_file():  # else built by another process meanwhile
            build(folder)
    return folder


def lock_path(folder: Path) -> Path:
    """The lock file held while ``folder`` is being built (beside it)."""
    return folder.with_name(folder.name + ".lock")


def default_cache_dir(domain: str) -> Path:
    """Returns ``$XDG_CACHE_HOME/sim4endor/DOMAIN`` (default under ``~/.cache``)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "sim4endor" / domain


def check_target(vessel: Vessel, target: str) -> None:
    """Raises :class:`TaskConfigError` unless ``target`` is a labelled target of ``vessel``."""
    valid = sorted(t for t in vessel.targets if t in vessel.centerline.labels)
    if target not in valid:
        raise TaskConfigError(
            f"Vessel {vessel.name!r} has no target {target!r}; valid targets: {valid}."
        )
