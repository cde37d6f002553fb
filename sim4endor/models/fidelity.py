"""Fidelity: the numerical settings a wire preset is simulated with, named in one place.

A :class:`~sim4endor.models.guidewire.GuidewireConfig` mixes the wire's physics (core,
jacket, coat, tip) with numerical devices that are not properties of a real wire: the
quasi-static mass scaling and joint armature, the joint damping, the split into kinematic
chains, the physics time step, MuJoCo's integrator, friction cone and contact impedance.
:class:`Numerics` is that second part, and :data:`FIDELITIES` names the two settings the
catalogue's presets come in (:func:`sim4endor.models.wires.preset`):

``converged`` (the default)
    The wire 100 times heavier than a real one, not 10,000: its trajectories no longer
    depend on the mass scaling (a 10 times lighter wire at half the step follows the same
    tip path, ``experiments/benchmarks/guidewire_convergence.py``), with MuJoCo's
    ``discrete`` integrator, whose metric holds the joints' damping, so that the light wire
    stays stable and its contacts hold; the time step is the longest at which no push or
    episode of the validation puts the wire more than a quarter radius into a wall.
``fast``
    The wire as it was simulated until 2026-12-06: 10,000 times heavier, ``implicitfast``.
    About twice as fast on the coronary trees and good for exploring, but its trajectories
    depend on the mass scaling by up to tens of millimetres (another branch) on the coronary
    trees. For the ``paper`` preset it is the published model bit for bit
    (``GuidewireConfig()``), which Table I's benchmark uses.

Every figure behind these choices is in docs/guidewire.md, "Converged by default".
"""

from __future__ import annotations

import dataclasses
import types
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

from sim4endor.errors import Sim4EndoRError

if TYPE_CHECKING:  # the command line's parser lists the names without loading MuJoCo
    from sim4endor.models.guidewire import GuidewireConfig

#: The fidelity of every wire a task builds unless told otherwise.
DEFAULT = "converged"
#: The x1e4 fidelity, for exploring (and for ``paper``, the published model).
FAST = "fast"


class FidelityError(Sim4EndoRError, ValueError):
    """An unknown fidelity; the message lists the valid ones."""


@dataclass(frozen=True)
class Numerics:
    """The numerical fields of a :class:`~sim4endor.models.guidewire.GuidewireConfig`.

    The defaults are ``GuidewireConfig()``'s, the paper's published model; each field's
    meaning is documented there.
    """

    mass_scale: float = 1e4
    armature_time: float = 0.015
    damping_time: float = 0.025
    chain_bodies: int | None = None
    max_timestep: float | None = None
    friction_cone: str | None = None
    integrator: str | None = None
    contact_solimp: tuple[float, float, float, float, float] | None = None

    def apply(self, wire: GuidewireConfig) -> GuidewireConfig:
        """Returns ``wire`` with these numerical settings."""
        return dataclasses.replace(wire, **dataclasses.asdict(self))


#: The catalogue's wires as simulated until 2026-12-06: x1e4, implicitfast, 2.5 ms, elliptic
#: cones, chains of 6 bodies (docs/guidewire.md and docs/performance.md give the measurements
#: behind each).
_FAST = Numerics(chain_bodies=6, max_timestep=0.0025, friction_cone="elliptic")
#: The converged setting of the catalogue's soft and intermediate wires.
_CONVERGED = Numerics(
    mass_scale=100.0, armature_time=0.0015, damping_time=0.1, chain_bodies=6,
    max_timestep=0.0025, friction_cone="elliptic", integrator="discrete",
    contact_solimp=(0.9, 0.999, 0.0001, 0.5, 2.0),
)

#: Per fidelity, the numerics of each preset (``"*"``: every preset not named).
FIDELITIES: Mapping[str, Mapping[str, Numerics]] = types.MappingProxyType({
    DEFAULT: types.MappingProxyType({
        "*": _CONVERGED,
        # A stiff tip snaps through faster than a soft one when it buckles in a dead end:
        # at 2.5 ms its segments crossed the 0.1 mm contact margin within a step.
        "stiff": dataclasses.replace(_CONVERGED, max_timestep=0.00125),
        # The paper's stiff uniform rod presses the vascular phantom's walls hardest: at 2.5 ms
        # its pushes went up to 0.8 radii into the hulls. Half the damping: at 100 ms its
        # rolls wound up so slowly that the expert's episode to target B there took 16 s
        # instead of 10 s and ended 0.9 mm from the lighter reference instead of 0.38 mm.
        "paper": dataclasses.replace(_CONVERGED, max_timestep=0.00125, damping_time=0.05),
    }),
    FAST: types.MappingProxyType({"*": _FAST, "paper": Numerics()}),
})


def names() -> tuple[str, ...]:
    """The fidelities, the default first."""
    return tuple(FIDELITIES)


def numerics(fidelity: str, preset: str) -> Numerics:
    """The numerical settings of ``preset`` at ``fidelity``.

    Raises:
        FidelityError: For an unknown fidelity; the message lists the valid ones.
    """
    try:
        table = FIDELITIES[fidelity]
    except (KeyError, TypeError):
        raise FidelityError(
            f"Unknown fidelity {fidelity!r}; valid: {list(FIDELITIES)}."
        ) from None
    return table.get(preset, table["*"])
