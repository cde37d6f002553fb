"""Reward terms of the navigation tasks, as named pure functions (paper, "Reward Function Design").

The paper's reward at a control step is the sum of three terms:

============  ==========================================  =========================================
term          value                                       when
============  ==========================================  =========================================
``distance``  ``R_dist = (D_last - D_current) / 100``     every step; D in **millimetres**
``goal``      ``+100``                                    ``D_current <= 1 mm`` (success)
``failure``   ``-100``                                    a failure state (see ``sim4endor.tasks``)
============  ==========================================  =========================================

``D`` is the distance from the wire tip to the target. The paper's numbers (the divisor 100,
the 1 mm threshold) assume millimetres, so the distances below are computed in metres (SI, as
everywhere inside the engine) and converted to millimetres once, in :func:`distance_reward`.
With ``D`` in mm, advancing the tip by 1 mm towards the target earns 0.01.

Two distance metrics are provided:

* :class:`ManifoldDistance` -- the paper's "curvature distance" on the vascular manifold: the
  tip is projected onto the centerline graph and ``D`` is the shortest path along the graph
  from that projection to the target (Dijkstra from the target, computed once per anatomy).
  Edge weights are arc length, optionally inflated on curved segments (``curvature_weight``,
  see :meth:`sim4endor.vessels.CenterlineGraph.edge_weights`), as the paper describes.
* :class:`EuclideanDistance` -- the straight-line baseline of the paper's Table I.

A tip just past a bifurcation in the wrong branch is Euclidean-close to the target but
manifold-far: it has to come back to the bifurcation first.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from sim4endor._checks import is_number, require
from sim4endor.errors import Sim4EndoRError
from sim4endor.vessels.centerline import CenterlineGraph, Projection

FloatArray = NDArray[np.float64]

#: Metres to millimetres: the paper's reward constants assume distances in mm.
MM_PER_M = 1000.0

MetricName = Literal["manifold", "euclidean"]
METRICS: tuple[MetricName, ...] = ("manifold", "euclidean")


class RewardConfigError(Sim4EndoRError, ValueError):
    """Raised for an invalid reward configuration; the message names the bad setting."""


@dataclass(frozen=True)
class RewardConfig:
    """Constants of the paper's reward.

    Attributes:
        metric: ``"manifold"`` (geodesic along the centerline graph, the paper's reward) or
            ``"euclidean"`` (the paper's baseline).
        curvature_weight: Dimensionless gain inflating the weight of curved centerline edges
            (0: plain arc length). Only used by the manifold metric.
        distance_divisor_mm: ``R_dist = (D_last - D_current) / distance_divisor_mm`` with D in
            mm (paper: 100).
        success_distance: Success when ``D <= success_distance`` (m; paper: 1 mm).
        goal_bonus: Reward added on success (paper: +100).
        failure_penalty: Reward added on failure (paper: -100).
    """

    metric: MetricName = "manifold"
    curvature_weight: float = 0.0
    distance_divisor_mm: float = 100.0
    success_distance: float = 1.0e-3
    goal_bonus: float = 100.0
    failure_penalty: float = -100.0

    def __post_init__(self) -> None:
        if self.metric not in METRICS:
            raise RewardConfigError(
                f"Unknown reward metric {self.metric!r}; choose one of {list(METRICS)}."
            )
        require(self, "RewardConfig", RewardConfigError,
                non_negative=("curvature_weight", "goal_bonus"),
                positive=("distance_divisor_mm", "success_distance"))
        if not is_number(self.failure_penalty):
            raise RewardConfigError(
                f"RewardConfig.failure_penalty must be a number, got {self.failure_penalty!r}."
            )


class DistanceToTarget(Protocol):
    """A distance (m) from a point to one fixed target."""

    def __call__(self, point: FloatArray) -> float:
        """Returns the distance from ``point`` (m) to the target (m)."""
        ...


class EuclideanDistance:
    """Straight-line distance to a target point (the paper's baseline metric)."""

    def __init__(self, target: FloatArray) -> None:
        """Stores the target point.

        Args:
            target: (3,) target position (m).
        """
        self.target = np.asarray(target, dtype=np.float64).reshape(3)

    def __call__(self, point: FloatArray) -> float:
        """Returns ``|point - target|`` (m)."""
        return float(np.linalg.norm(np.asarray(point, dtype=np.float64) - self.target))


class ManifoldDistance:
    """Geodesic distance along a centerline graph to one target node.

    Dijkstra from the target runs once, in the constructor; each call then only projects the
    query point onto the graph's edges (vectorised over the edges).
    """

    def __init__(
        self, graph: CenterlineGraph, target_node: int, curvature_weight: float = 0.0
    ) -> None:
        """Precomputes the distances of every node to the target.

        Args:
            graph: The vessel's centerline graph (m).
            target_node: Index of the target node, e.g. ``graph.labels["A"]``.
            curvature_weight: See :meth:`CenterlineGraph.edge_weights`.
        """
        self.graph = graph
        self.target_node = int(target_node)
        self.project = graph.project
        self._edge_weights = graph.edge_weights(curvature_weight)
        self.node_distances = graph.geodesic_from(self.target_node, curvature_weight)
        if not np.all(np.isfinite(self.node_distances)):
            raise RewardConfigError(
                "The centerline graph is not connected: some nodes cannot reach the target "
                f"node {self.target_node}. Rebuild the vessel so its centerline is one tree."
            )

    @property
    def target(self) -> FloatArray:
        """The target node's position (m)."""
        return self.graph.nodes[self.target_node]

    def __call__(self, point: FloatArray) -> float:
        """Returns the manifold distance (m) from ``point``, projected onto the graph."""
        return self.at(self.project(point))

    def at(self, proj: Projection) -> float:
        """Returns the manifold distance (m) from a point already projected onto the graph."""
        return self.graph.distance_at(proj, self.node_distances, self._edge_weights)


def make_distance(
    config: RewardConfig, graph: CenterlineGraph, target_name: str
) -> DistanceToTarget:
    """Returns the configured distance-to-target function for a labelled graph node.

    Args:
        config: Which metric and weighting to use.
        graph: The vessel's centerline graph; ``graph.labels`` must hold ``target_name``.
        target_name: Label of the target node, e.g. ``"A"``.
    """
    if target_name not in graph.labels:
        raise RewardConfigError(
            f"Target {target_name!r} is not a labelled centerline node; labelled nodes: "
            f"{sorted(graph.labels)}."
        )
    node = graph.labels[target_name]
    if config.metric == "euclidean":
        return EuclideanDistance(graph.nodes[node])
    return ManifoldDistance(graph, node, config.curvature_weight)


def distance_reward(d_last: float, d_current: float, divisor_mm: float = 100.0) -> float:
    """Returns the paper's reduction reward ``(D_last - D_current) / divisor`` with D in mm.

    Args:
        d_last: Distance to the target at the previous control step (m).
        d_current: Distance to the target now (m).
        divisor_mm: The paper's divisor (100) for distances in millimetres.
    """
    return (d_last - d_current) * MM_PER_M / divisor_mm


def goal_reward(success: bool, bonus: float = 100.0) -> float:
    """Returns ``bonus`` on success, else 0 (paper: +100 when D <= 1 mm)."""
    return bonus if success else 0.0


def failure_reward(failed: bool, penalty: float = -100.0) -> float:
    """Returns ``penalty`` on failure, else 0 (paper: -100)."""
    return penalty if failed else 0.0


@dataclass(frozen=True)
class RewardTerms:
    """The reward terms of one control step; ``total`` is their sum.

    Attributes:
        distance: Reduction reward ``R_dist``.
        goal: Success bonus (0 or +100).
        failure: Failure penalty (0 or -100).
    """

    distance: float
    goal: float
    failure: float

    @property
    def total(self) -> float:
        """Sum of the terms."""
        return self.distance + self.goal + self.failure


def reward_terms(
    config: RewardConfig, d_last: float, d_current: float, *, success: bool, failed: bool
) -> RewardTerms:
    """Returns every term of the paper's reward for one control step.

    Args:
        config: Reward constants.
        d_last: Distance to the target at the previous step (m).
        d_current: Distance to the target now (m).
        success: Whether this step reached the target.
        failed: Whether this step ended in a failure state.
    """
    return RewardTerms(
        distance=distance_reward(d_last, d_current, config.distance_divisor_mm),
        goal=goal_reward(success, config.goal_bonus),
        failure=failure_reward(failed, config.failure_penalty),
    )
