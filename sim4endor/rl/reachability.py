"""Which targets of a real patient's vessel are within the wire's reach, and why not.

A real tree's target can lie where no wire goes: a distal end narrower than the wire, or an
ostium the tip cannot enter without pressing past the task's tip-force limit. The probing
scripted expert (:class:`~sim4endor.rl.baselines.ScriptedExpert` with ``probing=True``: it
simulates aims ahead where it is stuck) is the reachability reference. A target it misses is
reported as unreachable with how its episode ended and the lumen's calibre, at the target and
at the narrowest point of the route from the inlet, so a policy's misses there are read
against what the wire can do instead of being dropped silently.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from sim4endor import vessels
from sim4endor.rl.metrics import Episode, largest_tip_force
from sim4endor.tasks.tip_frame import PathToTarget


@dataclasses.dataclass(frozen=True)
class Reach:
    """The probing expert's episode on one target, and the lumen on the way there.

    Attributes:
        outcome: How the episode ended (``success``, a failure reason or ``timeout``).
        target_radius_m: Lumen radius at the target node (m).
        narrowest_radius_m: Smallest lumen radius of the route from the inlet (m).
        max_tip_force_n: Largest step-mean tip force of the episode (N).
    """

    outcome: str
    target_radius_m: float
    narrowest_radius_m: float
    max_tip_force_n: float

    @property
    def reachable(self) -> bool:
        """Whether the probing expert reached the target."""
        return self.outcome == "success"

    def reason(self) -> str:
        """Why it is out of reach, e.g. ``tip_force (1.20 N); lumen 0.50 mm across at the
        target, 0.48 mm at the narrowest``; empty when reachable."""
        if self.reachable:
            return ""
        force = f" ({self.max_tip_force_n:.2f} N)" if self.outcome == "tip_force" else ""
        return (f"{self.outcome}{force}; lumen {2e3 * self.target_radius_m:.2f} mm across at "
                f"the target, {2e3 * self.narrowest_radius_m:.2f} mm at the narrowest")


def route_calibre(vessel: vessels.Vessel, target: str) -> tuple[float, float]:
    """The lumen radius (m) at ``target`` and the smallest along the route from the inlet."""
    graph = vessel.centerline
    route = PathToTarget.to_node(graph, graph.labels[target]).route(graph.labels["inlet"])
    return float(graph.radii[graph.labels[target]]), float(graph.radii[route].min())


def reach_of(episode: Episode, vessel: str | Path, target: str) -> Reach:
    """The :class:`Reach` of the probing expert's ``episode`` on ``target`` of a vessel
    folder."""
    at_target, narrowest = route_calibre(vessels.load(vessel), target)
    return Reach(episode.outcome, at_target, narrowest, largest_tip_force(episode))


def reachable_successes(reach: Mapping[str, Reach], targets: Mapping[str, Any]
                        ) -> tuple[float, int]:
    """A policy's summed success rate over the reachable targets (``targets``: each case
    label's success rate), and how many there are."""
    reachable = [label for label, r in reach.items() if r.reachable]
    return sum(targets[label] for label in reachable), len(reachable)


def as_json(reach: Mapping[str, Reach]) -> dict[str, dict[str, Any]]:
    """Each target's :class:`Reach` fields, its reachability and reason."""
    return {label: dataclasses.asdict(r) | {"reachable": r.reachable, "reason": r.reason()}
            for label, r in reach.items()}
