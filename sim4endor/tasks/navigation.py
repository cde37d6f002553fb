"""The guidewire navigation task: the paper's MDP as a dm_control ``base.Task``.

One control step applies the action, advances the physics ``control_timestep`` seconds and
then evaluates the new state once (:meth:`NavigationTask.after_step`); reward, termination
and the per-step ``info`` all read that evaluation, so they always agree.
"""

from __future__ import annotations

import collections
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from dm_control.mujoco.wrapper import MjData, MjModel
from dm_control.rl import control
from dm_control.suite import base
from dm_env import specs
from numpy.typing import NDArray

from sim4endor import rewards
from sim4endor.errors import Sim4EndoRError
from sim4endor.models import constants as names
from sim4endor.models.motion import HeartMotion, WallMotion
from sim4endor.observations import (
    BIPLANE_OBSERVATIONS,
    CATHLAB_OBSERVATIONS,
    DISTANCE_HORIZON,
    FORCE_HORIZON,
    OBSERVATION_UNITS,
    STALL_HORIZON,
    STALL_PROGRESS,
)
from sim4endor.tasks import starts
from sim4endor.tasks.anatomy import Anatomy, AnatomySource
from sim4endor.tasks.cathlab import CathLab, CathLabView, Measurement
from sim4endor.tasks.config import NavigationConfig, TaskConfigError
from sim4endor.tasks.fluoroscopy import Fluoroscope
from sim4endor.tasks.randomisation import DriverModel, draw_driver, draw_sensors
from sim4endor.tasks.tip_frame import PathToTarget, TipView, tip_view
from sim4endor.vessels.centerline import INLET_LABEL, Projection

FloatArray = NDArray[np.float64]

#: Failure reasons, in the order they are checked.
FAILURES: tuple[str, ...] = (
    "instability",
    "tip_force",
    "outside_lumen",
    "insertion_limit",
    "rotation_limit",
    "push_force",
)


#: Observation entries read from one :class:`~sim4endor.tasks.tip_frame.TipView` per step.
_TIP_VIEW_ENTRIES = frozenset({"path_ahead", "axis_offset", "lumen_radius", "tip_velocity_local"})
#: Observation entries read from one :class:`~sim4endor.tasks.cathlab.CathLabView` per step.
_CATHLAB_ENTRIES = frozenset((*CATHLAB_OBSERVATIONS, *BIPLANE_OBSERVATIONS))


def failure_code(failure: str) -> int:
    """``failure`` as a number for numeric-only consumers (TorchRL): 0 for none, else its
    1-based position in :data:`FAILURES`."""
    return FAILURES.index(failure) + 1 if failure else 0


class InvalidActionError(Sim4EndoRError, ValueError):
    """Raised for a NaN/inf or wrongly shaped action; it never reaches MuJoCo."""


@dataclass(frozen=True)
class StepEvaluation:
    """Everything the task concludes about the state after a control step.

    Attributes:
        distance: Reward-metric distance from the tip to the target (m).
        manifold_distance: Geodesic distance along the centerline graph (m), for reporting.
        wall_force: Total normal wire–wall contact force (N), for reporting.
        tip_force: Normal force of the tip section on the wall (N), the safety signal
            (``TerminationConfig.tip_force_mean``).
        lumen_excess: Distance of the tip outside the lumen (m; <= 0 inside).
        tip_position: The tip (m, vessel frame), for metrics whatever the observation holds.
        success: Whether the tip reached the target.
        failure: Failure reason (one of :data:`FAILURES`) or ``""``.
        terms: The reward terms of this step.
    """

    distance: float
    manifold_distance: float
    wall_force: float
    tip_force: float
    lumen_excess: float
    tip_position: FloatArray
    success: bool
    failure: str
    terms: rewards.RewardTerms


def lumen_excess(anatomy: Anatomy, point: FloatArray, proj: Projection | None = None) -> float:
    """Returns how far ``point`` lies outside the lumen (m; negative inside).

    Inside the union of the tubes around the centerline graph's edges
    (:meth:`~sim4endor.vessels.centerline.CenterlineGraph.tube_excess`) the point is inside,
    and the excess is the distance to the nearest edge minus its interpolated radius: the
    every-step case, cheap. A tube's radius is the distance to the nearest wall, so a lumen
    that is not round (a real patient's, or at a junction) reaches past its tubes; outside
    them the lumen surface itself decides (:meth:`~sim4endor.vessels.Vessel.surface_excess`).
    On a dfemtoolz patient tree the tubes alone ended an episode as 0.53 mm outside the lumen
    with the tip 0.34 mm inside the mesh. Points behind the inlet plane are in the introducer
    sheath and count as inside.

    Args:
        anatomy: The anatomy.
        point: Query point (m).
        proj: ``point``'s projection onto the centerline graph, if already known.
    """
    vessel = anatomy.vessel
    inlet = vessel.manifest.inlet
    # Plain floats: three numbers, and this runs every control step.
    offsets = zip(np.asarray(point).tolist(), inlet.position, inlet.direction, strict=True)
    behind = sum((p - o) * d for p, o, d in offsets)
    if behind < 0.0:
        return -math.inf
    graph = vessel.centerline
    proj = proj or graph.project(point)
    excess = proj.distance - graph.radius_at_projection(proj)
    # Inside the nearest tube is inside; only the rare point outside it pays for the union,
    # and only a point outside the union for the surface.
    if excess <= 0.0 or (excess := min(excess, graph.tube_excess(point))) <= 0.0:
        return excess
    return vessel.surface_excess(point)


class NavigationTask(base.Task):
    """Steer the guidewire tip to a target point of a vessel tree.

    See :mod:`sim4endor.suite` for the observation, action and reward tables.
    """

    def __init__(
        self,
        anatomies: AnatomySource,
        config: NavigationConfig | None = None,
        random: int | np.random.RandomState | None = None,
    ) -> None:
        """Initialises the task.

        Args:
            anatomies: Where each episode's anatomy and target come from.
            config: Action, reward, termination and observation settings.
            random: Seed or ``RandomState`` of the task's own generator.
        """
        super().__init__(random=random)
        self.config = config or NavigationConfig()
        self._anatomies = anatomies
        self._distances: dict[tuple[str, str, str], rewards.DistanceToTarget] = {}
        self._paths: dict[tuple[str, str], PathToTarget] = {}
        self._anatomy = anatomies.initial()
        self._target = ""
        self._insertion = 0.0
        self._rotation = 0.0
        self._last_action = np.zeros(2)
        self._d_last = 0.0
        # The closest approach to the target so far (m) and the episode time it was made (s),
        # for the ``stall_time`` entry.
        self._closest = math.inf
        self._closest_time = 0.0
        self._max_insertion = math.inf
        self._max_rotation = math.inf
        self._evaluation: StepEvaluation | None = None
        self._fluoroscopes: dict[str, Fluoroscope] = {}
        self._variation = _variation_stream(self.random)
        self._cathlab = (CathLab(self.config.cathlab, 2 if self.config.cathlab.biplane else 1)
                         if _CATHLAB_ENTRIES & set(self.config.observations) else None)
        # This episode's driver between the commands and the carriage; None: commands go
        # straight to the carriage (no randomisation).
        self._driver: DriverModel | None = None
        # Per anatomy: its wall chunks' centres at rest.
        self._chunks: dict[str, FloatArray] = {}

    def reseed(self, seed: int) -> None:
        """Replaces the task's random generator by one seeded with ``seed``."""
        self._random = np.random.RandomState(seed)
        self._variation = _variation_stream(self._random)

    # ------------------------------------------------------------------------ anatomy
    @property
    def anatomy(self) -> Anatomy:
        """The current episode's anatomy."""
        return self._anatomy

    @property
    def cathlab(self) -> CathLab | None:
        """The cath lab's sensor model, when its entries are observed."""
        return self._cathlab

    @property
    def target(self) -> str:
        """The current episode's target label."""
        return self._target

    @property
    def target_position(self) -> FloatArray:
        """The current target point (m)."""
        graph = self._anatomy.vessel.centerline
        return np.array(graph.nodes[graph.labels[self._target]])

    def _distance(self, metric: rewards.MetricName, label: str | None = None
                  ) -> rewards.DistanceToTarget:
        """Returns the distance function to the labelled node ``label`` (default: the current
        target), built once per anatomy and label."""
        label = self._target if label is None else label
        key = (self._anatomy.key, label, metric)
        if key not in self._distances:
            cfg = dataclasses.replace(self.config.reward, metric=metric)
            self._distances[key] = rewards.make_distance(
                cfg, self._anatomy.vessel.centerline, label
            )
        return self._distances[key]

    def manifold_distance(self, label: str | None = None) -> rewards.ManifoldDistance:
        """The geodesic distance along the centerline to the labelled node ``label`` (default:
        the current target, which the success test and the ``manifold_distance`` entry use);
        built once per anatomy and label."""
        distance = self._distance("manifold", label)
        assert isinstance(distance, rewards.ManifoldDistance)
        return distance

    def path_to_target(self) -> PathToTarget:
        """The route to the current target along the centerline (built once per anatomy and
        target), for the ``path_ahead`` observation."""
        key = (self._anatomy.key, self._target)
        if key not in self._paths:
            graph = self._anatomy.vessel.centerline
            self._paths[key] = PathToTarget.to_node(graph, graph.labels[self._target])
        return self._paths[key]

    # ------------------------------------------------------------------------ episode
    def initialize_episode(self, physics: control.Physics) -> None:
        """Draws the anatomy/target, swaps the compiled model if it changed, homes the wire."""
        anatomy, self._target = self._anatomies.draw(self.random)
        if anatomy is not self._anatomy:
            # Physics was compiled for another anatomy: load this one's cached model.
            physics._reload_from_data(MjData(MjModel(anatomy.model)))
        self._anatomy = anatomy
        self._max_insertion, self._max_rotation = self._limits(physics)
        start = self.config.initial_state
        self._insertion = float(self.random.uniform(0.0, start.insertion_range))
        self._rotation = float(self.random.uniform(-start.rotation_range, start.rotation_range))
        self._last_action = np.zeros(2)
        physics.set_wall_motion(None if self.config.motion is None else
                                self._wall_motion(physics,
                                                  self.config.motion.draw(self._variation)))
        if start.off_path_depth is None:
            physics.place_driver(self._insertion, self._rotation)
        else:
            driven = physics.time()
            self._start_off_path(physics, start.off_path_depth)
            motion = physics.wall_motion
            if motion is not None:  # the clock restarts where the wall has moved to
                physics.set_wall_motion(motion.later(driven))
        tip = self._rest_tip(physics)
        self._d_last = self._distance(self.config.reward.metric)(tip)
        self._closest = self.manifold_distance()(tip)
        self._closest_time = physics.time()
        self._evaluation = None
        randomisation = self.config.randomisation
        if randomisation is not None:
            self._driver = draw_driver(randomisation, self._variation)
            self._driver.reset(self._insertion, self._rotation)
        if self._cathlab is not None:
            graph = self._anatomy.vessel.centerline
            route = self.path_to_target().route(graph.labels[INLET_LABEL])
            sensors = (None if randomisation is None
                       else draw_sensors(randomisation, self.config.cathlab, self._variation))
            self._cathlab.reset(graph.nodes[route], self._variation, sensors)

    def _wall_motion(self, physics: control.Physics, motion: HeartMotion) -> WallMotion:
        """This episode's motion of the anatomy's wall chunks."""
        vessel = self._anatomy.vessel
        if self._anatomy.key not in self._chunks:
            centroids = physics.wall_chunk_centroids()
            if not len(centroids):
                raise TaskConfigError(f"The heart's motion needs the scene of {vessel.name!r} "
                                      "built with moving walls (SceneConfig.moving_walls).")
            self._chunks[self._anatomy.key] = centroids
        return WallMotion(motion, self._chunks[self._anatomy.key], vessel.inlet_position,
                          np.asarray(self.config.cathlab.patient_axes))

    def _rest_tip(self, physics: control.Physics) -> FloatArray:
        """The tip where it lies in the still tree: the geometry of reward, termination and
        the privileged observation is the preoperative centerline's."""
        motion = physics.wall_motion
        tip = physics.tip_position()
        return tip if motion is None else motion.to_rest(tip, physics.time())

    def _start_off_path(self, physics: control.Physics, depths: tuple[float, float]) -> None:
        """Drives the wire down the path to another target, then turns in the drawn roll (see
        :class:`~sim4endor.tasks.config.InitialStateConfig`)."""
        decoys = sorted(t for t in self._anatomy.vessel.targets
                        if t != self._target and t in self._anatomy.vessel.centerline.labels)
        if not decoys:
            raise TaskConfigError(
                f"A wrong-branch start (InitialStateConfig.off_path_depth) needs a labelled "
                f"target besides {self._target!r} in {self._anatomy.vessel.name!r}; set "
                "off_path_depth=None for this vessel."
            )
        decoy = decoys[int(self.random.randint(len(decoys)))]
        depth = float(self.random.uniform(*depths))
        physics.place_driver(self._insertion, 0.0)
        distances = (self.manifold_distance(decoy), self.manifold_distance(),
                     self.manifold_distance(INLET_LABEL))
        action = self.config.action
        self._insertion, rotation = starts.drive_off_path(
            physics, self._anatomy, distances, depth, action)
        self._rotation = starts.turn_in(physics, self._insertion, rotation, self._rotation,
                                        action)
        physics.data.time = 0.0  # the episode's clock starts when the agent takes over

    def _limits(self, physics: control.Physics) -> tuple[float, float]:
        """Returns the failure limits of commanded insertion and |rotation| (m, rad)."""
        term = self.config.termination
        ranges = physics.named.model.actuator_ctrlrange
        max_insertion = float(ranges[names.INSERTION_ACTUATOR][1])
        max_rotation = float(np.max(np.abs(ranges[names.ROTATION_ACTUATOR])))
        return (
            max_insertion if term.max_insertion is None else term.max_insertion,
            max_rotation if term.max_rotation is None else term.max_rotation,
        )

    def action_spec(self, physics: control.Physics) -> specs.BoundedArray:
        """Normalised [insertion, rotation] increments in [-1, 1]."""
        return specs.BoundedArray(
            shape=(2,), dtype=np.float64, minimum=-1.0, maximum=1.0, name="insert_rotate"
        )

    def before_step(self, action: np.ndarray, physics: control.Physics) -> None:
        """Validates the action and moves the driver targets by Δd, Δθ."""
        a = np.asarray(action)
        if a.dtype.kind not in "iuf":  # not bools, text or objects, which numpy would cast
            raise InvalidActionError(
                f"Action must be two numbers [insertion, rotation] in [-1, 1], got "
                f"{a.tolist()!r} (dtype {a.dtype})."
            )
        a = a.astype(np.float64, copy=False)
        if a.shape != (2,):
            raise InvalidActionError(
                f"Action must have shape (2,) = [insertion, rotation], got {a.shape}."
            )
        # Plain floats: this runs every control step, and numpy calls on two numbers cost
        # more than the arithmetic.
        insert, rotate = float(a[0]), float(a[1])
        if not (math.isfinite(insert) and math.isfinite(rotate)):
            raise InvalidActionError(
                f"Action {a.tolist()} is not finite; NaN/inf actions are rejected so they "
                "never reach MuJoCo. Check the policy's outputs."
            )
        insert, rotate = min(max(insert, -1.0), 1.0), min(max(rotate, -1.0), 1.0)
        cfg = self.config.action
        # The carriage cannot retract behind its home position: a hard stop, not a failure.
        insertion = max(0.0, self._insertion + insert * cfg.max_insertion_step)
        rotation = self._rotation + rotate * cfg.max_rotation_step
        self._last_action = np.array([insert, rotate])
        if self._driver is None:
            physics.set_driver_targets(insertion, rotation)
        else:
            physics.set_driver_targets(*self._driver.move(insertion - self._insertion,
                                                          rotation - self._rotation))
        self._insertion, self._rotation = insertion, rotation

    def after_step(self, physics: control.Physics) -> None:
        """Evaluates the new state once: distance, success, failure, reward terms."""
        self._evaluation = self._evaluate(physics, unstable=False)

    def mark_unstable(self, physics: control.Physics) -> None:
        """Records that the last physics step raised an error (see the suite's environment)."""
        self._evaluation = self._evaluate(physics, unstable=True)

    def _evaluate(self, physics: control.Physics, unstable: bool) -> StepEvaluation:
        term = self.config.termination
        # No NaN check needed here: MuJoCo resets a non-finite state inside mj_step and warns,
        # and dm_control turns the warning into the PhysicsError that calls mark_unstable.
        tip = self._rest_tip(physics)
        if unstable:
            distance = manifold = self._d_last
            force, tip_force, excess, push = math.inf, math.inf, math.inf, math.inf
        else:
            to_target = self.manifold_distance()
            proj = to_target.project(tip)  # one projection serves every term
            manifold = to_target.at(proj)
            distance = (
                manifold
                if self.config.reward.metric == "manifold"
                else self._distance(self.config.reward.metric)(tip)
            )
            force = physics.wall_contact_force()
            tip_force = self._tip_force(physics)
            excess = lumen_excess(self._anatomy, tip, proj)
            push = physics.insertion_force()
            if manifold < self._closest - STALL_PROGRESS:
                self._closest, self._closest_time = manifold, physics.time()
        checks = {
            "instability": unstable,
            "tip_force": tip_force > term.max_tip_force,
            "outside_lumen": excess > term.lumen_margin,
            "insertion_limit": self._insertion > self._max_insertion,
            "rotation_limit": abs(self._rotation) > self._max_rotation,
            "push_force": push > term.max_push_force,
        }
        failure = next((name for name in FAILURES if checks[name]), "")
        success = not failure and distance <= self.config.reward.success_distance
        terms = rewards.reward_terms(
            self.config.reward, self._d_last, distance, success=success, failed=bool(failure)
        )
        self._d_last = distance
        return StepEvaluation(
            distance, manifold, force, tip_force, excess, tip, success, failure, terms
        )

    def _tip_force(self, physics: control.Physics) -> float:
        """The tip's wall force as the task's termination config defines it (N)."""
        if self.config.termination.tip_force_mean:
            return physics.mean_tip_contact_force()
        return physics.tip_contact_force()

    def get_reward(self, physics: control.Physics) -> float:
        """Returns the sum of this step's reward terms."""
        return self._current().terms.total

    def get_termination(self, physics: control.Physics) -> float | None:
        """Returns 0.0 (discount) on success or failure, else None."""
        evaluation = self._current()
        return 0.0 if evaluation.success or evaluation.failure else None

    def _current(self) -> StepEvaluation:
        if self._evaluation is None:
            raise RuntimeError("The task has not evaluated a step yet; call after_step first.")
        return self._evaluation

    def step_info(self) -> dict[str, float | bool | str | FloatArray]:
        """Returns the reward terms and diagnostics of the last step (for ``info``)."""
        ev = self._current()
        return {
            "tip_position": ev.tip_position,
            "reward_distance": ev.terms.distance,
            "reward_goal": ev.terms.goal,
            "reward_failure": ev.terms.failure,
            "distance": ev.distance,
            "manifold_distance": ev.manifold_distance,
            "wall_force": ev.wall_force,
            "tip_force": ev.tip_force,
            "lumen_excess": ev.lumen_excess,
            "is_success": ev.success,
            "failure": ev.failure,
            "failure_code": failure_code(ev.failure),
            "insertion_command": float(self._insertion),
            "rotation_command": float(self._rotation),
        }

    # -------------------------------------------------------------------- observation
    def observation_spec(self, physics: control.Physics) -> Mapping[str, specs.Array]:
        """Returns the spec of every configured entry without rendering or stepping."""
        pixels = self.config.pixels
        variable = {
            "wire_shape": (3 * len(physics.wire_points()),),
            "pixels": (pixels.height, pixels.width, 1),
        }
        return collections.OrderedDict(
            (name, specs.Array(variable.get(name, (OBSERVATION_UNITS[name][1],)),
                               np.uint8 if name == "pixels" else np.float64, name))
            for name in self.config.observations
        )

    def get_observation(self, physics: control.Physics) -> Mapping[str, np.ndarray]:
        """Returns the configured observation entries, in order (SI units)."""
        return self.observe(physics, self.config.observations)

    def observe(self, physics: control.Physics, entries: tuple[str, ...]
                ) -> Mapping[str, np.ndarray]:
        """Returns any observation entries of the current state, in order: the configured
        ones (:meth:`get_observation`), or a teacher's privileged set beside a student's
        (:mod:`sim4endor.rl.imitation`). The cath lab's entries need the lab configured."""
        obs: collections.OrderedDict[str, np.ndarray] = collections.OrderedDict()
        names = set(entries)
        view = self._tip_view(physics) if _TIP_VIEW_ENTRIES & names else None
        lab = None
        if names & _CATHLAB_ENTRIES:
            if self._cathlab is None:
                raise TaskConfigError(f"Observation entries {sorted(names & _CATHLAB_ENTRIES)} "
                                      "need the cath lab, which this task does not observe.")
            # The cath lab's sensors see the imaged wire (carried in the lab by the breath),
            # the load cell and the clock, no more.
            motion = physics.wall_motion
            wire = physics.wire_points()
            if motion is not None:
                wire = wire + motion.lab_offset(physics.time())
            lab = self._cathlab.observe(Measurement(physics.time(), wire,
                                                    physics.insertion_force()))
        for name in entries:
            if name in _CATHLAB_ENTRIES:
                assert lab is not None  # built whenever a cath-lab entry is configured
                obs[name] = _cathlab_entry(name, lab)
            else:
                obs[name] = self._observe(name, physics, view)
        return obs

    def _tip_view(self, physics: control.Physics) -> TipView:
        """The tip-frame entries of the current state, computed once per observation."""
        motion = physics.wall_motion
        turn = np.eye(3) if motion is None else motion.rest_rotation(physics.time())
        return tip_view(self.path_to_target(), self._rest_tip(physics),
                        turn @ physics.tip_frame(), physics.tip_velocity() @ turn.T)

    def _observe(self, name: str, physics: control.Physics, view: TipView | None
                 ) -> np.ndarray:
        # The physics accessors already return fresh float64 arrays.
        if name == "tip_position":
            return physics.tip_position()
        if name == "tip_velocity":
            return physics.tip_velocity()
        if name == "target_position":
            return self.target_position
        if name == "wire_shape":
            return np.asarray(physics.wire_points(), dtype=np.float64).reshape(-1)
        if name == "last_action":
            return self._last_action.copy()
        if name == "insertion":
            return np.array([physics.insertion_depth()], dtype=np.float64)
        if name == "rotation":
            return np.array([physics.rotation_angle()], dtype=np.float64)
        if name == "manifold_distance":
            distance = self.manifold_distance()(self._rest_tip(physics))
            return np.array([min(distance, DISTANCE_HORIZON)])
        if name == "pixels":
            return self._fluoroscopy(physics)
        if name == "tip_force":
            return np.array([min(self._tip_force(physics), FORCE_HORIZON)])
        if name == "wall_force":
            return np.array([min(physics.wall_contact_force(), FORCE_HORIZON)])
        if name == "stall_time":
            return np.array([min(physics.time() - self._closest_time, STALL_HORIZON)])
        assert view is not None  # get_observation computes it for these entries
        if name == "path_ahead":
            return view.path_ahead.reshape(-1)
        if name == "axis_offset":
            return view.axis_offset
        if name == "lumen_radius":
            return np.array([view.lumen_radius])
        if name == "tip_velocity_local":
            return view.tip_velocity
        raise KeyError(name)  # unreachable: NavigationConfig validates the names

    def _fluoroscopy(self, physics: control.Physics) -> np.ndarray:
        """Returns the fluoroscopy-like projection (lumen grey, wire black, field white)."""
        key = self._anatomy.key
        if key not in self._fluoroscopes:
            self._fluoroscopes[key] = Fluoroscope(self._anatomy.vessel.centerline,
                                                  self.config.pixels)
        return self._fluoroscopes[key].image(physics.wire_points())


def _cathlab_entry(name: str, lab: CathLabView) -> np.ndarray:
    """One cath-lab entry as a flat array; ``*_b`` entries are the second plane's."""
    plane = 1 if name.endswith("_b") else 0
    base = name.removesuffix("_b")
    if base == "roadmap_remaining":
        return np.array([lab.roadmap_remaining])
    if base == "roadmap_stall":
        return np.array([lab.roadmap_stall])
    if base == "proximal_force":
        return np.array([lab.proximal_force])
    per_plane: FloatArray = getattr(lab, base)[plane]
    return np.array(per_plane, dtype=np.float64).reshape(-1)


def _variation_stream(random: np.random.RandomState) -> np.random.RandomState:
    """The generator of what varies besides the episode itself (the heart's motion, the cath
    lab's views and noise, randomised sensors and driver): seeded from the task's generator
    without drawing from it, so that the episodes (anatomy, target, start) are the same with
    these on or off, and a policy can be compared with and without them episode by episode."""
    state = random.get_state(legacy=True)
    assert isinstance(state, tuple)  # legacy: ("MT19937", key, position, ...)
    return np.random.RandomState(np.asarray(state[1], dtype=np.uint32)[:8])
