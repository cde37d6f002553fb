"""A scripted expert that steers the J-tip along the centerline to the task's target.

It does what an interventionist does at a bifurcation: roll the wire until the bent tip points
into the branch the path takes, then push while rotating the wire back and forth about that aim
(the sweep, so the tip brushes over the ostium at many rolls); back off when the wire went the
wrong way or the tip presses hard on the wall, and try again at another aim. It reads
privileged state (the wire's shape and the centerline graph), so it is not an RL baseline on
the paper's observation; it is

- the **reachability check** of an anatomy: a target the expert cannot reach with the wire is
  a defect of the geometry, not a hard task (``tests/test_expert.py`` runs it on the shipped
  phantoms);
- a source of demonstrations and a sanity reference for learnt policies.

:class:`ProbingExpert` adds lookahead for the reachability check: where the expert is stuck it
simulates several aims on a copy of the simulation and follows the one that gets furthest.
One of them, :class:`PullBackEntry`, is the interventionist's way into an angulated side
branch: push past its ostium, turn the tip towards it, and draw the wire back until the tip
drops in.

Example:
    >>> from sim4endor import suite
    >>> from sim4endor.tasks.expert import CenterlineExpert, run_expert
    >>> env = suite.load("simplified_phantom", "task_b", {"random": 0})   # doctest: +SKIP
    >>> run_expert(env, CenterlineExpert())["is_success"]                 # doctest: +SKIP
    True
"""

from __future__ import annotations

import copy
import dataclasses
import itertools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from dm_control.rl import control
from numpy.typing import NDArray

from sim4endor import rewards
from sim4endor.physics import GuidewirePhysics
from sim4endor.tasks.anatomy import Anatomy
from sim4endor.vessels.centerline import INLET_LABEL, Projection

if TYPE_CHECKING:  # navigation imports this module for its wrong-branch starts
    from sim4endor.tasks.navigation import NavigationTask

FloatArray = NDArray[np.float64]
#: Anything that maps the simulation's state to an action, as the experts do.
Policy = Callable[[GuidewirePhysics, "NavigationTask"], FloatArray]


@dataclass(frozen=True)
class ExpertConfig:
    """Gains and thresholds of :class:`CenterlineExpert` (SI units).

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
            turn; 0 aims at the turn. :class:`ProbingExpert` tries several.
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


#: The expert without the sweep: one aim at a time. :class:`ProbingExpert` tries its aims so,
#: one per simulated copy (its probes stand in for the sweep, and its published results were
#: measured so), and the redirect tasks' starts drive the wire into the other branch with it
#: (``sim4endor.tasks.starts``; their depths and times were fitted to it).
FIXED_AIM = ExpertConfig(sweep_deg=0.0)


class CenterlineExpert:
    """Scripted policy for a :class:`~sim4endor.tasks.NavigationTask`.

    Call :meth:`reset` at the start of every episode (:func:`run_expert` does).
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

    def __call__(self, physics: GuidewirePhysics, task: NavigationTask) -> FloatArray:
        """Returns the action ``[insert, rotate]`` in [-1, 1] for the current state."""
        return self.steer(physics, task.anatomy, task.manifold_distance(),
                          task.config.action.max_rotation_step)

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
        ahead = _along_path(distance, neighbours, node, self.config.lookahead, travelled)
        return graph.nodes[ahead] - proj.point


@dataclass(frozen=True)
class ProbeConfig:
    """When and how far :class:`ProbingExpert` looks ahead.

    Attributes:
        roll_offsets_deg: The aims tried at each probe (``ExpertConfig.roll_offset_deg``); 0
            is the plain expert's.
        horizon: Control steps each aim is simulated ahead.
        stall_steps: Control steps without a new closest approach to the target that count
            as stuck (besides the end of a back-off from a wrong branch).
        max_probes: Probes per episode. Each costs ``len(roll_offsets_deg) * horizon``
            simulated control steps.
        min_gain: A plan is followed only if it brings the tip this much (m) closer to the
            target than the episode's closest approach so far, or reaches it.
        pull_back: Also try :class:`PullBackEntry` at each probe, for ``pull_back_horizon``
            control steps (it needs more than ``horizon``: past the ostium, turn, draw back,
            push on).
        pull_back_horizon: Control steps the pull-back entry is simulated ahead.
        screen: Simulate each action that is not a plan's one control step ahead on a copy,
            and replace one that would end the episode with a failure (a tip-force spike as
            the tip snaps off a ledge, an instability) by the first safe one of: hold the
            insertion and roll, pull back and roll, pull straight back. Plans need no screen:
            their lookahead stops before a failure. Costs about one extra control step of
            simulation per step.
    """

    roll_offsets_deg: tuple[float, ...] = (0.0, 30.0, -30.0, 60.0, -60.0, 90.0, -90.0, 180.0)
    horizon: int = 40
    stall_steps: int = 60
    max_probes: int = 12
    min_gain: float = 0.001
    pull_back: bool = True
    pull_back_horizon: int = 90
    screen: bool = True


class ProbingExpert(CenterlineExpert):
    """:class:`CenterlineExpert` with lookahead, for reachability checks.

    Entering a side branch depends on where the tip's bend points at the moment it meets the
    ostium, and the tip's roll lags and whips behind the carriage's, so the plain expert's
    next aim after a failed attempt is a guess (docs/tasks/coronary.md). When it
    is stuck (it has just backed off from a wrong branch, or ``probe.stall_steps`` steps
    brought the tip no closer), this expert simulates each aim of ``probe.roll_offsets_deg`` for
    ``probe.horizon`` steps on a copy of the physics and the task, and then replays the
    actions of the aim that got closest, up to its closest approach. MuJoCo is deterministic,
    so the episode reaches the state the copy reached. With ``probe.screen`` it also never
    takes a step that it has simulated to end in a failure.

    It is a planner with a perfect model of the simulation: it answers whether the wire can
    reach a target at all (the reachability check of an anatomy), not how a robot without
    that model would get there. Its steps and aims hold one aim at a time
    (:data:`FIXED_AIM`, unless ``config`` says otherwise): the probes try the aims the plain
    expert's sweep passes through.
    """

    def __init__(self, config: ExpertConfig | None = None,
                 probe: ProbeConfig | None = None) -> None:
        self.probe = probe or ProbeConfig()
        super().__init__(config or FIXED_AIM)

    def reset(self) -> None:
        """Forgets the episode, its plan and its probes."""
        super().reset()
        self._plan: list[FloatArray] = []
        self._closest = math.inf
        self._since = 0
        self._probes = 0

    def __call__(self, physics: GuidewirePhysics, task: NavigationTask) -> FloatArray:
        """Returns the next action: the plan's while one is being followed."""
        distance = task.manifold_distance()
        d = distance.at(distance.project(physics.tip_position()))
        if d < self._closest - self.probe.min_gain:
            self._closest, self._since = d, 0
        else:
            self._since += 1
        if not self._plan:
            stuck = self._backing_off == 1 or self._since >= self.probe.stall_steps
            if stuck and self._probes < self.probe.max_probes:
                self._probes += 1
                self._since = 0
                self._plan = self.plan(physics, task, self._closest)
                if self._plan:
                    # Start afresh after the plan, as after a back-off: its closest approach
                    # is no wrong branch.
                    self._backing_off, self._best = 0, math.inf
        if self._plan:
            return self._plan.pop(0)
        action = super().__call__(physics, task)
        return self._screened(physics, task, action) if self.probe.screen else action

    def _screened(self, physics: GuidewirePhysics, task: NavigationTask,
                  action: FloatArray) -> FloatArray:
        """``action``, or the first fallback whose next step does not fail (see ``screen``)."""
        substeps = task.config.action.physics_steps(physics.timestep())
        fallbacks = ([0.0, action[1]], [self.config.back_push, action[1]], [-1.0, 0.0])
        for candidate in (action, *map(np.array, fallbacks)):
            _, _, safe = lookahead(physics, task, lambda *_, a=candidate: a, substeps, 1)
            if safe:
                return candidate
        return action  # every choice fails: the state is lost whatever the expert does

    def plan(self, physics: GuidewirePhysics, task: NavigationTask,
             closest: float) -> list[FloatArray]:
        """Probes every aim from the present state; returns the actions of the one that gets
        closest to the target (up to its closest approach), or [] if none reaches it or gets
        ``probe.min_gain`` closer than ``closest`` (m, the episode's closest approach).

        It reads only the simulation, not the episode's history, so it can also take over
        from another policy where that one is stuck (sim4endor.rl.imitation.Takeover).
        """
        substeps = task.config.action.physics_steps(physics.timestep())
        aims: list[tuple[Policy, int]] = []
        for offset in self.probe.roll_offsets_deg:
            offset_aim = CenterlineExpert(dataclasses.replace(self.config,
                                                              roll_offset_deg=offset))
            offset_aim._neighbours = self._neighbours  # the anatomy's graph, read only
            aims.append((offset_aim, self.probe.horizon))
        if self.probe.pull_back:
            entry = PullBackEntry(self.config)
            entry.plain._neighbours = self._neighbours
            aims.append((entry, self.probe.pull_back_horizon))
        best: tuple[bool, float, list[FloatArray]] = (False, math.inf, [])
        for aim, horizon in aims:
            outcome = lookahead(physics, task, aim, substeps, horizon)
            if (outcome[0], -outcome[1]) > (best[0], -best[1]):
                best = outcome
        reached, approach, actions = best
        return actions if reached or approach < closest - self.probe.min_gain else []


class PullBackEntry:
    """The pull-back entry into a side branch, as one plan of :class:`ProbingExpert`.

    An interventionist who cannot push the tip into an angulated side branch advances past its
    ostium, turns the bent tip towards the branch's side and slowly draws the wire back: the
    tip slides back along the wall and drops into the ostium, and the wire is pushed on. This
    policy does the same, on the branch where the path to the target leaves the vessel the tip
    is in (the *junction*, the last node of that path the tip passed):

    1. ``advance``: the plain expert's steering, without its retreat from a wrong branch, until
       the tip is ``overshoot`` past the junction off the path;
    2. ``turn``: roll, without insertion, until the tip's bend points within the expert's
       tolerance of the branch (a point ``into`` along the path past the junction);
    3. ``draw``: retract at ``pull`` while keeping that roll, until the tip is on the path
       past the junction (it dropped in) or ``give_up`` above it (it slid past);
    4. ``push``: the plain expert from there on.

    A fresh instance is made for each probe; its state is the phase and the junction.

    Args:
        config: The plain expert's gains; its ``tolerance_deg`` ends the turn.
        overshoot: How far (m, along the centerline) past the junction the tip goes first.
        into: The tip is turned towards the path's point this far (m) past the junction.
        pull: Insertion action while drawing back (negative: 0.2 of the largest step).
        give_up: The draw ends once the tip is this far (m) above the junction.
    """

    def __init__(self, config: ExpertConfig, overshoot: float = 0.003, into: float = 0.003,
                 pull: float = -0.2, give_up: float = 0.005) -> None:
        self.plain = CenterlineExpert(config)
        self.overshoot, self.into, self.pull, self.give_up = overshoot, into, pull, give_up
        self.phase = "advance"
        self.junction = -1
        self._on_path: set[int] | None = None  # the path's nodes, found on the first call

    def __call__(self, physics: GuidewirePhysics, task: NavigationTask) -> FloatArray:
        """Returns the next action of the phase the wire is in."""
        if self.phase == "push":
            return self.plain(physics, task)
        distance = task.manifold_distance()
        graph, dist = distance.graph, distance.node_distances
        neighbours = self.plain._adjacency(task.anatomy)
        if self._on_path is None:
            self._on_path = _path_nodes(distance, neighbours)
        on_path = self._on_path
        points = physics.wire_points()
        proj = distance.project(points[-1])
        d = distance.at(proj)
        i, j = (int(n) for n in graph.edges[proj.edge])
        tip_on_path = i in on_path and j in on_path
        if self.phase == "advance":
            if not tip_on_path:
                start = i if dist[i] < dist[j] else j
                node = next(n for n in _to_target(dist, neighbours, start) if n in on_path)
                if d - dist[node] >= self.overshoot:
                    self.junction, self.phase = node, "turn"
            if self.phase == "advance":
                self.plain.reset()  # no retreat: going past the branch is the point
                return self.plain(physics, task)
        junction = dist[self.junction]
        if tip_on_path and (d < junction or d > junction + self.give_up):
            self.phase = "push"
            self.plain.reset()
            return self.plain(physics, task)
        branch = _along_path(distance, neighbours, self.junction, self.into)
        phi = self.plain.roll_error(physics, points, graph.nodes[branch] - points[-1])
        rotate = float(np.clip(phi / task.config.action.max_rotation_step, -1.0, 1.0))
        if self.phase == "turn":
            if abs(math.degrees(phi)) >= self.plain.config.tolerance_deg:
                return np.array([0.0, rotate])
            self.phase = "draw"
        return np.array([self.pull, rotate])


def _to_target(dist: FloatArray, neighbours: list[list[int]], node: int) -> Iterator[int]:
    """The centerline nodes from ``node`` to the target (``dist`` is each node's distance to
    it), each step to the neighbour nearest the target."""
    yield node
    while closer := [n for n in neighbours[node] if dist[n] < dist[node]]:
        node = min(closer, key=lambda n: dist[n])
        yield node


def _along_path(distance: rewards.ManifoldDistance, neighbours: list[list[int]], node: int,
                length: float, travelled: float = 0.0) -> int:
    """The node ``length`` (m) along the path from ``node`` towards the target (the target if
    it is nearer), counting ``travelled`` as already covered."""
    nodes = distance.graph.nodes
    for nxt in itertools.islice(_to_target(distance.node_distances, neighbours, node), 1, None):
        if travelled >= length:
            break
        travelled += float(np.linalg.norm(nodes[nxt] - nodes[node]))
        node = nxt
    return node


def _path_nodes(distance: rewards.ManifoldDistance, neighbours: list[list[int]]) -> set[int]:
    """The centerline nodes on the path from the inlet to the target of ``distance``."""
    inlet = int(distance.graph.labels[INLET_LABEL])
    return set(_to_target(distance.node_distances, neighbours, inlet))


def lookahead(physics: GuidewirePhysics, task: NavigationTask, expert: Policy,
              substeps: int, steps: int) -> tuple[bool, float, list[FloatArray]]:
    """Runs ``expert`` for up to ``steps`` control steps on copies of ``physics`` and
    ``task``; returns (target reached, closest distance, actions up to the closest). The
    actions stop before a step that fails: none if the first one does."""
    sim = physics.copy(share_model=True)
    sim_task = copy.copy(task)  # its state is a few scalars, replaced (not mutated) by a step
    actions: list[FloatArray] = []
    closest, until = math.inf, 0
    for _ in range(steps):
        action = expert(sim, sim_task)
        sim_task.before_step(action, sim)
        try:
            sim.step(substeps)
        except control.PhysicsError:
            break
        sim_task.after_step(sim)
        info = sim_task.step_info()
        if info["failure"]:
            break
        actions.append(action)
        d = float(info["manifold_distance"])
        if d < closest:
            closest, until = d, len(actions)
        if info["is_success"]:
            return True, closest, actions
    return False, closest, actions[:until]


def run_expert(env: control.Environment, expert: CenterlineExpert | None = None,
               max_steps: int | None = None) -> dict[str, float | bool | str]:
    """Runs one episode of ``expert`` on a suite environment; returns the last step's info."""
    expert = expert or CenterlineExpert()
    expert.reset()
    timestep = env.reset()
    steps = 0
    while not timestep.last() and (max_steps is None or steps < max_steps):
        timestep = env.step(expert(env.physics, env.task))
        steps += 1
    return env.task.step_info()


def _wrap(angle: float) -> float:
    """``angle`` (rad) in [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _unit(v: FloatArray) -> FloatArray:
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else v
