"""Anatomies a navigation task can run in: a vessel, its compiled scene and its targets.

A task draws one (anatomy, target) per episode from an :class:`AnatomySource`. A fixed
source always returns the same compiled model, so a reset only resets the state; a pool of
randomly generated trees compiles each anatomy once, the first time it is drawn.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from sim4endor import vessels
from sim4endor.models.scene import SceneConfig, build_model, config_for_vessel
from sim4endor.tasks.config import TaskConfigError
from sim4endor.vessels import Vessel


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


def compile_anatomy(
    vessel: str | Path | Vessel, scene: SceneConfig | None = None, fit: bool = True
) -> Anatomy:
    """Loads a vessel (name, folder or :class:`Vessel`) and compiles its scene.

    The scene module caches compiled models per (vessel folder, scene config), so calling
    this again for the same anatomy does not recompile.

    Args:
        vessel: Vessel name, folder or loaded vessel.
        scene: Wire, driver and timestep (defaults: :class:`SceneConfig`).
        fit: Fit the insertion range and wire length to the deepest target (fewer segments,
            faster) and the tip bend to the narrowest lumen
            (:func:`sim4endor.models.scene.config_for_vessel`). Pools of anatomies pass
            ``False`` so every member has the same wire, hence the same observation sizes.
    """
    vessel = vessel if isinstance(vessel, Vessel) else vessels.load(vessel)
    config = scene or SceneConfig()
    model = build_model(vessel, config_for_vessel(vessel, config) if fit else config)
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

    def __init__(self, builders: Sequence[Callable[[], Anatomy]]) -> None:
        """Stores the builders.

        Args:
            builders: One zero-argument function per pool member returning its anatomy.
        """
        if not builders:
            raise TaskConfigError("An anatomy pool needs at least one member.")
        self._builders = tuple(builders)
        self._built: dict[int, Anatomy] = {}

    def _get(self, index: int) -> Anatomy:
        if index not in self._built:
            self._built[index] = self._builders[index]()
        return self._built[index]

    def draw(self, random: np.random.RandomState) -> tuple[Anatomy, str]:
        """Draws a member uniformly, then one of its targets uniformly."""
        anatomy = self._get(int(random.randint(len(self._builders))))
        targets = sorted(anatomy.vessel.targets)
        return anatomy, targets[int(random.randint(len(targets)))]

    def initial(self) -> Anatomy:
        """Returns the first member (built now if needed)."""
        return self._get(0)


def check_target(vessel: Vessel, target: str) -> None:
    """Raises :class:`TaskConfigError` unless ``target`` is a labelled target of ``vessel``."""
    valid = sorted(t for t in vessel.targets if t in vessel.centerline.labels)
    if target not in valid:
        raise TaskConfigError(
            f"Vessel {vessel.name!r} has no target {target!r}; valid targets: {valid}."
        )
