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

The steering itself, towards any labelled node, is :mod:`sim4endor.tasks.steering`'s (with
:class:`ExpertConfig`): the redirect tasks' wrong-branch starts drive with it too, below the
task that this module's experts read.

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
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from dm_control.rl import control

from sim4endor import rewards
from sim4endor.physics import GuidewirePhysics
from sim4endor.tasks.navigation import NavigationTask
from sim4endor.tasks.steering import (
    FIXED_AIM,
    CenterlineSteering,
    ExpertConfig,
    FloatArray,
    along_path,
    to_target,
)
from sim4endor.vessels.centerline import INLET_LABEL

#: Anything that maps the simulation's state to an action, as the experts do.
Policy = Callable[[GuidewirePhysics, NavigationTask], FloatArray]


class CenterlineExpert(CenterlineSteering):
    """Scripted policy for a :class:`~sim4endor.tasks.NavigationTask`: the steering towards
    the task's target.

    Call :meth:`reset` at the start of every episode (:func:`run_expert` does).
    """

    def __call__(self, physics: GuidewirePhysics, task: NavigationTask) -> FloatArray:
        """Returns the action ``[insert, rotate]`` in [-1, 1] for the current state."""
        return self.steer(physics, task.anatomy, task.manifold_distance(),
                          task.config.action.max_rotation_step)


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

    @property
    def probes(self) -> int:
        """Probes made this episode (at most ``probe.max_probes``)."""
        return self._probes

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
                node = next(n for n in to_target(dist, neighbours, start) if n in on_path)
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
        branch = along_path(distance, neighbours, self.junction, self.into)
        phi = self.plain.roll_error(physics, points, graph.nodes[branch] - points[-1])
        rotate = float(np.clip(phi / task.config.action.max_rotation_step, -1.0, 1.0))
        if self.phase == "turn":
            if abs(math.degrees(phi)) >= self.plain.config.tolerance_deg:
                return np.array([0.0, rotate])
            self.phase = "draw"
        return np.array([self.pull, rotate])


def _path_nodes(distance: rewards.ManifoldDistance, neighbours: list[list[int]]) -> set[int]:
    """The centerline nodes on the path from the inlet to the target of ``distance``."""
    inlet = int(distance.graph.labels[INLET_LABEL])
    return set(to_target(distance.node_distances, neighbours, inlet))


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
