"""Steering the J-tip along the centerline towards a labelled node of the vessel.

This is what the scripted experts do at every step (:mod:`sim4endor.tasks.expert`): roll the
wire until the bent tip points into the branch the path takes, push while sweeping the aim
about it, back off from a wrong branch or a hard press. It reads the physics, the anatomy and
a distance to any labelled node, never a task, so the wrong-branch starts
(:mod:`sim4endor.tasks.starts`, which the task itself builds on) steer with it towards a
decoy branch, and the experts, which read the task, build on it in turn.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim4endor import rewards
from sim4endor.physics import GuidewirePhysics
from sim4endor.tasks.anatomy import Anatomy
from sim4endor.vessels.centerline import Projection

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ExpertConfig:
    """Gains and thresholds of the steering, and so of the experts (SI units).

    Attributes:
        lookahead: The path direction is taken from the tip's projection on the centerline to
            the point this far (m) along the path to the target.
        straight: Below this lateral component (of a unit vector, relative to the wire's body
            axis) the path runs straight ahead and the tip's roll does not matter.
        tolerance_deg: Insert only while the tip's bend points within this angle of the path's
            turn; otherwise only roll.
        push: Insertion action while aligned (fraction of the largest step).
        slow_force: Tip contact force (N) above which the push drops to ``slow_push``.
        slow_push: Insertion action while the tip presses on the wall.
        back_force: Tip contact force (N) above which the wire is pulled back a little.
        back_push: Insertion action (negative: retraction) while the tip presses that hard.
        lost: A manifold distance this much (m) above the best of the episode means the tip
            took a wrong branch.
        back_off_steps: Control steps of full retraction after a wrong branch.
        stall: A carriage lagging its commanded insertion by this much (m) pushes at the
            driver's force limit: the wire is blocked (buckled, or caught on the wall), and
            pushing on only winds up the command until the insertion limit ends the episode;
            the expert pulls back (``back_push``) instead, as a hand feels the resistance.
        tip_length: Arc length of the wire's pre-bent tip (m); the body axis is measured just
            proximal of it. ``None`` (default): the shaped part of the wire in the physics
            (its tip, and a secondary curve behind it if it has one), whatever its preset (a
            2 mm workhorse tip measured as a 5 mm one mixes the tip's bend into the body
            axis).
        roll_offset_deg: Aim the tip's bend this far (about the body axis) from the path's
            turn; 0 aims at the turn. :class:`~sim4endor.tasks.expert.ProbingExpert` tries
            several.
        retry_offsets_deg: After each retreat from a wrong branch, and after ``retry_steps``
            control steps that bring the tip no closer to the target, aim with the next of
            these offsets (added to ``roll_offset_deg``, cyclically), as a hand that failed
            to enter a branch tries again at another angle: the same aim meets the same
            ostium the same wrong way (docs/tasks/coronary.md). Empty: always the same aim.
        retry_steps: Control steps without a new closest approach that count as a failed
            attempt.
        sweep_deg: Where the path turns, sweep the aim this far (deg) to either side of it,
            sinusoidally, while pushing: the interventionist's back-and-forth rotation of the
            wire as it advances past a side branch, which lets the bent tip brush over the
            ostium at many rolls instead of meeting it at one. The tip's roll lags and whips
            behind the carriage's (docs/guidewire.md), so which fixed aim enters a narrow
            branch is a guess; the sweep tries them all on the way. While sweeping, the
            expert pushes whenever the bend is within ``max(tolerance_deg, sweep_deg)`` of
            the moving aim: the carriage's top roll rate (180 deg/s) trails the sweep's
            (``2 pi sweep_deg / sweep_period``, 283 deg/s at the defaults). 0: one fixed aim
            at a time (:data:`FIXED_AIM`). The defaults were chosen on the vessel-folder
            check trees (docs/tasks/coronary.md, 2026-11-28).
        sweep_period: Period (s) of the sweep, in episode time.
    """

    lookahead: float = 0.006
    straight: float = 0.15
    tolerance_deg: float = 25.0
    push: float = 0.6
    slow_force: float = 0.25
    slow_push: float = 0.2
    back_force: float = 0.5
    back_push: float = -0.5
    lost: float = 0.004
    back_off_steps: int = 8
    stall: float = 0.002
    tip_length: float | None = None
    roll_offset_deg: float = 0.0
    retry_offsets_deg: tuple[float, ...] = (0.0, 45.0, -45.0, 90.0, -90.0, 180.0)
    retry_steps: int = 60
    sweep_deg: float = 90.0
    sweep_period: float = 2.0


#: The expert without the sweep: one aim at a time. The probing expert
#: (:class:`~sim4endor.tasks.expert.ProbingExpert`) tries its aims so, one per simulated copy
#: (its probes stand in for the sweep, and its published results were measured so), and the
#: redirect tasks' starts drive the wire into the other branch with it
#: (``sim4endor.tasks.starts``; their depths and times were fitted to it).
FIXED_AIM = ExpertConfig(sweep_deg=0.0)


class CenterlineSteering:
    """The expert's steering towards any labelled node, with its state over an episode.

    Call :meth:`reset` at the start of every episode.
    """

    def __init__(self, config: ExpertConfig | None = None) -> None:
        self.config = config or ExpertConfig()
        self._neighbours: dict[str, list[list[int]]] = {}  # per anatomy
        self.reset()

    def reset(self) -> None:
        """Forgets the episode (best distance, retraction under way, failed attempts)."""
        self._best = math.inf
        self._backing_off = 0
        self._attempt = 0
        self._attempt_best = math.inf
        self._attempt_steps = 0

    def steer(self, physics: GuidewirePhysics, anatomy: Anatomy,
              distance: rewards.ManifoldDistance, max_rotation_step: float) -> FloatArray:
        """Returns the action towards the node of ``distance`` (any labelled node, not only
        the task's target), with rotation actions scaled by ``max_rotation_step`` (rad)."""
        cfg = self.config
        points = physics.wire_points()
        proj = distance.project(points[-1])
        d = distance.at(proj)
        if self._backing_off:
            self._backing_off -= 1
            if not self._backing_off:
                # Measure from where the retraction ended: above the bifurcation the tip is
                # further from the target than where the wrong turn was seen, which would
                # otherwise read as another wrong branch and pull the wire all the way out.
                self._best = math.inf
            return np.array([-1.0, 0.0])
        if d > self._best + cfg.lost:
            # The tip went down a branch off the path: pull it back above the bifurcation.
            self._backing_off = cfg.back_off_steps - 1
            self._best = d
            self._attempt, self._attempt_steps = self._attempt + 1, 0
            return np.array([-1.0, 0.0])
        self._best = min(self._best, d)
        if d < self._attempt_best:
            self._attempt_best, self._attempt_steps = d, 0
        else:
            self._attempt_steps += 1
            if self._attempt_steps >= cfg.retry_steps:
                self._attempt, self._attempt_steps = self._attempt + 1, 0

        force = physics.tip_contact_force()
        path = _unit(self._path_ahead(distance, self._adjacency(anatomy), proj))
        body, bend, turn = self._across_body(physics, points, path)
        aligned = True
        rotate = 0.0
        if np.linalg.norm(turn) >= cfg.straight and np.linalg.norm(bend) > 1e-9:
            phi = self._roll_angle(body, bend, turn)
            offset = cfg.roll_offset_deg
            if cfg.retry_offsets_deg:
                offset += cfg.retry_offsets_deg[self._attempt % len(cfg.retry_offsets_deg)]
            if cfg.sweep_deg:
                # Keyed on the episode's time, so a copy of the physics sweeps in step.
                offset += cfg.sweep_deg * math.sin(2 * math.pi * physics.time()
                                                   / cfg.sweep_period)
            if offset:
                phi = _wrap(phi - math.radians(offset))
            rotate = float(np.clip(phi / max_rotation_step, -1.0, 1.0))
            aligned = abs(math.degrees(phi)) < max(cfg.tolerance_deg, cfg.sweep_deg)
        stalled = physics.driver_targets()[0] - physics.insertion_depth() > cfg.stall
        if force > cfg.back_force or stalled:
            insert = cfg.back_push
        elif not aligned:
            insert = 0.0
        elif force > cfg.slow_force:
            insert = cfg.slow_push
        else:
            insert = cfg.push
        return np.array([insert, rotate])

    def roll_error(self, physics: GuidewirePhysics, points: FloatArray,
                   toward: FloatArray) -> float:
        """Roll angle (rad, in [-pi, pi]) that would turn the tip's bend to point at
        ``toward`` (a direction), about the wire's body axis."""
        return self._roll_angle(*self._across_body(physics, points, toward))

    def _across_body(self, physics: GuidewirePhysics, points: FloatArray,
                     toward: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The body axis, and the tip's heading and ``toward`` across it."""
        heading = _unit(points[-1] - points[-2])
        body = self._body_axis(points, physics.shape_start_index())
        return body, heading - (heading @ body) * body, toward - (toward @ body) * body

    @staticmethod
    def _roll_angle(body: FloatArray, bend: FloatArray, turn: FloatArray) -> float:
        """Angle from ``bend`` to ``turn`` about ``body`` (rad)."""
        return math.atan2(float(body @ np.cross(bend, turn)), float(bend @ turn))

    def _adjacency(self, anatomy: Anatomy) -> list[list[int]]:
        key = anatomy.key
        if key not in self._neighbours:
            self._neighbours[key] = anatomy.vessel.centerline.neighbours()
        return self._neighbours[key]

    def _body_axis(self, points: FloatArray, shape_start: int) -> FloatArray:
        """Direction of the wire just proximal of its shaped part (which starts at vertex
        ``shape_start`` unless the config gives the tip's length)."""
        base = shape_start
        if self.config.tip_length is not None:
            from_tip = np.cumsum(np.linalg.norm(np.diff(points[::-1], axis=0), axis=1))
            # 0.999: the tip's segments add up to tip_length only up to rounding.
            length = self.config.tip_length * 0.999
            base = len(points) - 1 - int(np.searchsorted(from_tip, length)) - 1
        base = max(base, 2)
        return _unit(points[base] - points[base - 2])

    def _path_ahead(self, distance: rewards.ManifoldDistance, neighbours: list[list[int]],
                    proj: Projection) -> FloatArray:
        """Vector from the tip's projection to the path point ``lookahead`` further on."""
        graph, dist = distance.graph, distance.node_distances
        i, j = graph.edges[proj.edge]
        node = int(i if dist[i] < dist[j] else j)
        travelled = float(np.linalg.norm(graph.nodes[node] - proj.point))
        ahead = along_path(distance, neighbours, node, self.config.lookahead, travelled)
        return graph.nodes[ahead] - proj.point


def to_target(dist: FloatArray, neighbours: list[list[int]], node: int) -> Iterator[int]:
    """The centerline nodes from ``node`` to the target (``dist`` is each node's distance to
    it), each step to the neighbour nearest the target."""
    yield node
    while closer := [n for n in neighbours[node] if dist[n] < dist[node]]:
        node = min(closer, key=lambda n: dist[n])
        yield node


def along_path(distance: rewards.ManifoldDistance, neighbours: list[list[int]], node: int,
                length: float, travelled: float = 0.0) -> int:
    """The node ``length`` (m) along the path from ``node`` towards the target (the target if
    it is nearer), counting ``travelled`` as already covered."""
    nodes = distance.graph.nodes
    for nxt in itertools.islice(to_target(distance.node_distances, neighbours, node), 1, None):
        if travelled >= length:
            break
        travelled += float(np.linalg.norm(nodes[nxt] - nodes[node]))
        node = nxt
    return node


def _wrap(angle: float) -> float:
    """``angle`` (rad) in [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _unit(v: FloatArray) -> FloatArray:
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else v
