"""dm_control-style suite of guidewire navigation tasks.

Example:
    >>> from sim4endor import suite
    >>> env = suite.load("simplified_phantom", "task_a", {"random": 0})  # doctest: +SKIP
    >>> timestep = env.reset()                                            # doctest: +SKIP
    >>> timestep = env.step([1.0, 0.0])  # insert 1.5 mm, no rotation     # doctest: +SKIP

The names come from :mod:`sim4endor.registry` (``ALL_TASKS``, ``BENCHMARKING``). Domains:
``simplified_phantom`` and ``vascular_phantom`` (tasks ``task_a``, ``task_b``: reach target A
or B, the paper's; ``task_a_redirect``, ``task_b_redirect``: the same from a wire already
5-20 mm down the other target's branch and rolled anywhere on the circle, which no constant
action solves), ``random_coronary`` (task ``navigate``: a seeded random tree and target per episode)
and ``vessel`` (task ``navigate``: any built vessel folder,
``task_kwargs={"vessel": NAME_OR_PATH, "target": LABEL}``).

**Observation** (ordered dict; the paper's state is the default):

=====================  =========  ======  =================================================
entry                  shape      unit    meaning
=====================  =========  ======  =================================================
``tip_position``       (3,)       m       wire tip in the vessel frame (default)
``tip_velocity``       (3,)       m/s     wire tip velocity (default)
``target_position``    (3,)       m       opt-in: the target point
``wire_shape``         (3·(N+1),) m       opt-in: wire centreline points, proximal first
``last_action``        (2,)       --      opt-in: the previous (clipped) action
``insertion``          (1,)       m       opt-in: measured insertion depth of the carriage
``rotation``           (1,)       rad     opt-in: measured rotation of the carriage
``manifold_distance``  (1,)       m       opt-in: geodesic tip-to-target distance
``pixels``             (H, W, 1)  uint8   opt-in: fluoroscopy-like top-down projection
``path_ahead``         (24,)      m       opt-in: route to the target, 8 points, tip frame
``axis_offset``        (3,)       1       opt-in: tip to centerline, lumen radii, tip frame
``lumen_radius``       (1,)       m       opt-in: lumen radius at the tip
``tip_velocity_local`` (3,)       m/s     opt-in: tip velocity, tip frame
``tip_force``          (1,)       N       opt-in: normal wall force on the pre-bent tip
``wall_force``         (1,)       N       opt-in: total normal wall force on the wire
``stall_time``         (1,)       s       opt-in: time since the last 1 mm of progress
``tracked_wire``       (8,)       m       opt-in: tracked wire behind the tracked tip, image
``roadmap_offset``     (2,)       m       opt-in: tracked tip to its roadmap match, image
``roadmap_ahead``      (16,)      m       opt-in: roadmap ahead of the match, image
``roadmap_remaining``  (1,)       m       opt-in: roadmap length left to the target
``roadmap_stall``      (1,)       s       opt-in: time since the match last advanced 1 mm
``tracking_age``       (1,)       s       opt-in: age of the shown track
``proximal_force``     (1,)       N       opt-in: the driver's load cell
=====================  =========  ======  =================================================

Opt in with ``task_kwargs={"observations": ("target_position", ...)}``, or replace the whole
observation by a named set: ``task_kwargs={"observations": "generalist"}`` gives the
tip-frame entries that do not change when the anatomy moves
(:mod:`sim4endor.tasks.tip_frame`; docs/tasks/index.md), and ``"deployable"`` only what a
robot in a cath lab measures: the wire tracked on fluoroscopy, the roadmap, the encoders and
the load cell (:mod:`sim4endor.tasks.cathlab`, set by ``task_kwargs={"cathlab": {...}}``;
docs/tasks/cathlab.md).

**Wire**: ``task_kwargs={"wire": "workhorse"}`` picks a catalogue preset
(:mod:`sim4endor.models.wires`: ``paper``, ``workhorse``, ``intermediate``, ``stiff``); a
:class:`~sim4endor.models.guidewire.GuidewireConfig` or a mapping
(``{"preset": "workhorse", "tip": "J"}``) also works. Defaults: ``paper`` on the phantoms and
``vessel`` folders, ``workhorse`` with a 2 mm/45° tip on ``coronary`` and with its tip shaped
3 mm at 75° on ``random_coronary``. The catalogue shapes the ``workhorse`` 3 mm at 75° with a
50° curve 5 mm back, for coronary-calibre vessel folders. A preset comes at
``task_kwargs={"fidelity": ...}``: ``"converged"`` (default; trajectories that do not depend
on the wire's artificial mass) or ``"fast"`` (the x1e4 wire, for exploring; for ``paper`` the
published model of Table I), :mod:`sim4endor.models.fidelity`. The simplified phantom's own
wire defaults to ``"fast"``, which is converged there (:func:`default_fidelity`).

**Action**: shape (2,), bounded [-1, 1]: ``[Δd / max_insertion_step, Δθ / max_rotation_step]``
per control step; defaults 1.5 mm and 9° at 20 Hz (``control_timestep`` 0.05 s), i.e. at most
30 mm/s and 180 °/s (:class:`sim4endor.tasks.ActionConfig`). Values outside [-1, 1] are
clipped; NaN/inf raise :class:`sim4endor.tasks.InvalidActionError`.

**Reward** (paper): ``R_dist = (D_last − D_current)/100`` with D in mm, ``+100`` when
D <= 1 mm (success, terminal), ``−100`` on failure (terminal: tip force > 1 N, tip > 0.5 mm
outside the lumen, commanded insertion beyond the driver's travel (fitted to the deepest
target + 10 mm), |rotation| > 10 turns, instability). D is the manifold
distance; ``task_kwargs={"reward": "euclidean"}`` gives the Euclidean baseline. Episodes are
truncated after 20 s of simulated time (discount 1); terminal steps have discount 0. Each
episode starts with the wire rolled by a random angle in ±30° and advanced by 0–1 mm, drawn
from the task's seeded generator (``task_kwargs={"initial_state": InitialStateConfig(...)}``;
the redirect tasks start from ``tasks.WRONG_BRANCH_START`` instead). The
terms of each step are in ``env.task.step_info()`` (the gymnasium ``info``).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import dm_env
import numpy as np
from dm_control.mujoco.wrapper import MjModel
from dm_control.rl import control

from sim4endor import registry
from sim4endor.errors import Sim4EndoRError
from sim4endor.models import fidelity as fidelities
from sim4endor.models import wires
from sim4endor.models.guidewire import GuidewireConfig
from sim4endor.models.motion import MotionRanges
from sim4endor.models.scene import SceneConfig
from sim4endor.physics import GuidewirePhysics
from sim4endor.rewards import RewardConfig
from sim4endor.tasks import (
    DEFAULT_OBSERVATIONS,
    OBSERVATION_SETS,
    WRONG_BRANCH_START,
    ActionConfig,
    Anatomy,
    AnatomySource,
    CathLabConfig,
    FixedAnatomy,
    InitialStateConfig,
    NavigationConfig,
    NavigationTask,
    PixelsConfig,
    TaskConfigError,
    TerminationConfig,
    coronary,
    random_coronary,
)
from sim4endor.tasks.anatomy import compile_anatomy
from sim4endor.tasks.config import LPS_AXES, PHANTOM_AXES, RANDOMISATION, Randomisation

ALL_TASKS = registry.ALL_TASKS
BENCHMARKING = registry.BENCHMARKING

_LOG = logging.getLogger(__name__)
_Config = TypeVar("_Config")

#: task_kwargs understood by every task (besides the domain-specific ones below).
_COMMON_KWARGS = (
    "random", "reward", "curvature_weight", "observations", "action", "termination",
    "initial_state", "pixels", "cathlab", "randomise", "wire", "fidelity",
)
#: task_kwargs of the domains whose trees a heart carries (the phantoms lie on a table).
_HEART_KWARGS = ("motion",)
_DOMAIN_KWARGS: Mapping[str, tuple[str, ...]] = {
    "vessel": ("vessel", "target", *_HEART_KWARGS),
    "random_coronary": ("pool_size", "pool_seed", "cache_dir", *_HEART_KWARGS),
    "coronary": ("pool_size", "pool_seed", "side", "anatomy", "vary_wire", "target",
                 "target_weights", "cache_dir", *_HEART_KWARGS),
}


class NavigationEnvironment(control.Environment):
    """``control.Environment`` that turns a MuJoCo instability into a failed terminal step.

    dm_control raises ``PhysicsError`` from inside ``step`` when MuJoCo warns (e.g. a
    diverging solver); for RL that is a failure state of the MDP (paper: -100), not a crash.
    """

    def __init__(self, physics: GuidewirePhysics, task: NavigationTask, **kwargs: Any) -> None:
        """Wraps ``control.Environment``; kwargs are passed on (time_limit, ...)."""
        super().__init__(physics, task, **kwargs)
        self._last_observation: Mapping[str, Any] | None = None

    @property
    def task(self) -> NavigationTask:
        """The navigation task (typed)."""
        return self._task

    def reset(self) -> dm_env.TimeStep:
        """Starts a new episode."""
        timestep = super().reset()
        self._last_observation = timestep.observation
        return timestep

    def step(self, action: Any) -> dm_env.TimeStep:
        """Steps; an instability ends the episode with the failure reward."""
        try:
            timestep = super().step(action)
        except control.PhysicsError as exc:
            _LOG.warning("Simulation instability, ending the episode: %s", exc)
            self.task.mark_unstable(self._physics)
            self._reset_next_step = True
            return dm_env.TimeStep(
                dm_env.StepType.LAST,
                self.task.get_reward(self._physics),
                0.0,
                self._last_observation,
            )
        self._last_observation = timestep.observation
        return timestep


def _navigation_config(kwargs: Mapping[str, Any], termination: TerminationConfig,
                       initial_state: InitialStateConfig, cathlab: CathLabConfig
                       ) -> NavigationConfig:
    """The task config of ``kwargs``; ``termination``, ``initial_state`` and ``cathlab`` are
    the task's defaults."""
    reward = kwargs.get("reward", "manifold")
    if isinstance(reward, str):
        reward = RewardConfig(metric=reward)  # type: ignore[arg-type]
    reward = _config(reward, RewardConfig, "reward")
    if "curvature_weight" in kwargs:
        reward = dataclasses.replace(reward, curvature_weight=kwargs["curvature_weight"])
    return NavigationConfig(
        action=_config(kwargs.get("action", ActionConfig()), ActionConfig, "action"),
        reward=reward,
        termination=_config(kwargs.get("termination", termination), TerminationConfig,
                            "termination", termination),
        initial_state=_config(kwargs.get("initial_state", initial_state),
                              InitialStateConfig, "initial_state", initial_state),
        observations=_observations(kwargs.get("observations", ())),
        pixels=_config(kwargs.get("pixels", PixelsConfig()), PixelsConfig, "pixels"),
        cathlab=_config(kwargs.get("cathlab", cathlab), CathLabConfig, "cathlab", cathlab),
        randomisation=_randomisation(kwargs.get("randomise", False)),
        motion=_motion(kwargs.get("motion", False)),
    )


def _motion(value: Any) -> MotionRanges | None:
    """task_kwargs ``motion``: a beating and breathing heart with the literature's ranges
    (:class:`~sim4endor.models.motion.MotionRanges`), or others; None: a still one."""
    return _switch(value, MotionRanges, "motion", MotionRanges())


def _randomisation(value: Any) -> Randomisation | None:
    """task_kwargs ``randomise``: :data:`~sim4endor.tasks.config.RANDOMISATION` or other
    ranges; None: no randomisation."""
    return _switch(value, Randomisation, "randomise", RANDOMISATION)


def _switch(value: Any, cls: type[_Config], name: str, default: _Config) -> _Config | None:
    """A task_kwargs switch with settings: true for ``default``, a mapping of ``cls``'s fields
    for ``default`` changed, false or None (not given) for off."""
    if value is True:
        return default
    if value is False or value is None:
        return None
    if isinstance(value, Mapping):
        return _config(value, cls, name, default)
    raise TaskConfigError(f"task_kwargs {name} must be true, false or a mapping of "
                          f"{cls.__name__}'s fields, got {value!r}.")


def _observations(value: Any) -> tuple[str, ...]:
    """The observation entries of ``task_kwargs["observations"]``: a set's name (used as it
    is) or a list of entries appended to the paper's defaults."""
    if isinstance(value, str):
        if value not in OBSERVATION_SETS:
            raise TaskConfigError(
                f"task_kwargs observations {value!r} is not an observation set; sets: "
                f"{sorted(OBSERVATION_SETS)} (or give a list of entry names, e.g. ['rotation'])."
            )
        return OBSERVATION_SETS[value]
    if not all(isinstance(o, str) for o in value):
        raise TaskConfigError(
            f"task_kwargs observations must be a set name such as 'generalist' or a list of "
            f"entry names, e.g. ['rotation'], got {value!r}."
        )
    return DEFAULT_OBSERVATIONS + tuple(o for o in value if o not in DEFAULT_OBSERVATIONS)


def _config(value: Any, cls: type[_Config], name: str, base: _Config | None = None
            ) -> _Config:
    """A task_kwargs setting as its config dataclass: given as one, or as a mapping of fields
    (changing ``base``, the domain's default, when given)."""
    if isinstance(value, cls):
        return value
    if isinstance(value, Mapping):
        fields = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
        unknown = sorted(set(value) - fields)
        if unknown:
            raise TaskConfigError(
                f"task_kwargs {name}: unknown fields {unknown}; valid: {sorted(fields)}."
            )
        return cls(**value) if base is None else dataclasses.replace(base, **value)  # type: ignore[type-var]
    raise TaskConfigError(
        f"task_kwargs {name} must be a {cls.__name__} or a mapping of its fields, got {value!r}."
    )


def _seed(random: Any) -> int | np.random.RandomState | None:
    """The task's ``random``: None, a seed in [0, 2**32) or a RandomState."""
    if random is None or isinstance(random, np.random.RandomState):
        return random
    if isinstance(random, int | np.integer) and not isinstance(random, bool):
        if 0 <= random < 2**32:
            return int(random)
    raise TaskConfigError(
        f"task_kwargs random must be an integer seed in [0, 2**32) or a numpy RandomState, "
        f"got {random!r}."
    )


def _integer(kwargs: Mapping[str, Any], name: str, default: int, minimum: int) -> int:
    value = kwargs.get(name, default)
    if isinstance(value, int | np.integer) and not isinstance(value, bool) and value >= minimum:
        return int(value)
    raise TaskConfigError(f"task_kwargs {name} must be an integer >= {minimum}, got {value!r}.")


def _target_weights(kwargs: Mapping[str, Any]) -> dict[str, float] | None:
    """task_kwargs ``target_weights``: a mapping of target label to a number, or None."""
    value = kwargs.get("target_weights")
    if value is None:
        return None
    if isinstance(value, Mapping) and all(
            isinstance(label, str) and isinstance(weight, int | float)
            and not isinstance(weight, bool) for label, weight in value.items()):
        return {label: float(weight) for label, weight in value.items()}
    raise TaskConfigError(f"task_kwargs target_weights must map target labels to numbers, "
                          f"e.g. {{'AM': 3, 'RV': 3}}, got {value!r}.")


#: environment_kwargs that control.Environment takes besides physics and task.
_ENVIRONMENT_KWARGS = ("time_limit", "control_timestep", "n_sub_steps", "flat_observation",
                       "legacy_step")


def _environment_kwargs(given: Mapping[str, Any]) -> dict[str, Any]:
    """Checks environment_kwargs by name and value (dm_control accepts a negative time limit
    and a NaN one, which end every episode after one step or never)."""
    unknown = sorted(set(given) - set(_ENVIRONMENT_KWARGS))
    if unknown:
        raise TaskConfigError(
            f"Unknown environment_kwargs {unknown}; valid: {list(_ENVIRONMENT_KWARGS)}."
        )
    for name in ("time_limit", "control_timestep"):
        value = given.get(name, 1.0)
        if not (isinstance(value, int | float) and not isinstance(value, bool) and value > 0):
            raise TaskConfigError(
                f"environment_kwargs {name} must be a positive number of seconds, got {value!r}."
            )
    steps = given.get("n_sub_steps", 1)
    if steps is not None and not (isinstance(steps, int) and not isinstance(steps, bool)
                                  and steps >= 1):
        raise TaskConfigError(f"environment_kwargs n_sub_steps must be >= 1, got {steps!r}.")
    return dict(given)


def default_wire(domain_name: str) -> str | Mapping[str, Any]:
    """The wire a domain's tasks use when ``task_kwargs`` names none, as ``wire`` takes it:
    the workhorse shaped 2 mm at 45° on ``coronary``, 3 mm at 75° on ``random_coronary``
    and ``paper`` elsewhere (``sim4endor.models.wires.resolve`` turns it into a config)."""
    if domain_name == "coronary":
        return coronary.DEFAULT_WIRE
    if domain_name == "random_coronary":
        return random_coronary.DEFAULT_WIRE
    return wires.PAPER


def default_fidelity(domain_name: str) -> str:
    """The fidelity of a domain's :func:`default_wire` when ``task_kwargs`` names none:
    ``"converged"`` (:mod:`sim4endor.models.fidelity`), except on the simplified phantom,
    whose paper wire keeps the published model of Table I (``"fast"``): in its two straight
    2 mm tubes that model is already converged (the expert's episodes within 0.38 and 0.39 mm,
    0.05 and 0.08 mm on average, of a 10 times lighter wire at half the step, with no hull
    overlap; docs/guidewire.md, "Converged by default") at a third of the converged setting's
    cost. A wire the task arguments name takes ``"converged"`` everywhere."""
    return fidelities.FAST if domain_name == "simplified_phantom" else fidelities.DEFAULT


def wire_config(domain_name: str, task_kwargs: Mapping[str, Any] | None = None
                ) -> GuidewireConfig:
    """The wire a task of ``domain_name`` builds from ``task_kwargs`` ``wire`` (a preset
    name, a GuidewireConfig or a mapping; default: the domain's :func:`default_wire`) and
    ``fidelity`` (default: the domain's :func:`default_fidelity` for its own wire,
    ``"converged"`` for another).

    Raises:
        sim4endor.tasks.TaskConfigError: For a bad wire or fidelity; the message names it.
    """
    kwargs = task_kwargs or {}
    fidelity = kwargs.get("fidelity")
    if fidelity is None and "wire" not in kwargs:
        fidelity = default_fidelity(domain_name)
    try:
        return wires.resolve(kwargs.get("wire", default_wire(domain_name)), fidelity)
    except Sim4EndoRError as exc:
        raise TaskConfigError(f"task_kwargs wire: {exc}") from None


def _scene(kwargs: Mapping[str, Any], domain_name: str) -> SceneConfig:
    return SceneConfig(wire=wire_config(domain_name, kwargs),
                       moving_walls=_motion(kwargs.get("motion", False)) is not None)


def _termination(entry: registry.TaskEntry, kwargs: Mapping[str, Any]) -> TerminationConfig:
    """The task's default limits: the coronary domain's (40 s, 0.6 N tip force) on its trees
    and on any vessel folder wired with a tapered-core coronary wire (the catalogue's
    ``workhorse``, ``intermediate``, ``stiff``): a coronary procedure's pace and its wall's
    injury threshold, whatever the anatomy. The paper's (20 s, 1 N) elsewhere. On four
    generated coronary trees built as vessel folders the scripted expert succeeded in 16 of
    32 episodes with the paper's limits and in 22 with these (docs/tasks/coronary.md,
    Measured)."""
    if entry.domain == "coronary":
        return coronary.TERMINATION
    if entry.domain == "vessel" and _scene(kwargs, entry.domain).wire.core_profile is not None:
        return coronary.TERMINATION
    return TerminationConfig()


def _cache_dir(kwargs: Mapping[str, Any]) -> Path | None:
    return None if kwargs.get("cache_dir") is None else Path(kwargs["cache_dir"])


def _anatomy_source(entry: registry.TaskEntry, kwargs: Mapping[str, Any]) -> AnatomySource:
    # Pools fit each tree's wire to its deepest target, unless the wire's vertices are
    # observed: then every tree needs the same wire, for one observation size.
    same_wire = "wire_shape" in _observations(kwargs.get("observations", ()))
    if entry.domain == "coronary":
        return coronary.pool(
            size=_integer(kwargs, "pool_size", coronary.DEFAULT_POOL_SIZE, minimum=1),
            seed=_integer(kwargs, "pool_seed", 0, minimum=0),
            side=kwargs.get("side", "both"),
            cache_dir=_cache_dir(kwargs),
            scene=_scene(kwargs, entry.domain),
            target=None if kwargs.get("target") is None else str(kwargs["target"]),
            same_wire=same_wire,
            target_weights=_target_weights(kwargs),
            anatomy=kwargs.get("anatomy", "normal"),
            # Randomisation gives each tree its own wire unit unless told otherwise (and
            # cannot where one wire must serve every tree).
            vary_wire=kwargs.get("vary_wire", bool(kwargs.get("randomise")) and not same_wire),
        )
    if entry.domain == "random_coronary":
        return random_coronary.pool(
            size=_integer(kwargs, "pool_size", random_coronary.DEFAULT_POOL_SIZE, minimum=1),
            seed=_integer(kwargs, "pool_seed", 0, minimum=0),
            cache_dir=_cache_dir(kwargs),
            scene=_scene(kwargs, entry.domain),
            same_wire=same_wire,
        )
    scene = _scene(kwargs, entry.domain)
    if entry.vessel is not None and entry.target is not None:
        return FixedAnatomy(compile_anatomy(entry.vessel, scene), entry.target)
    missing = [k for k in ("vessel", "target") if k not in kwargs]
    if missing:
        raise TaskConfigError(
            f"Domain {entry.domain!r} needs task_kwargs {missing}, e.g. "
            "{'vessel': 'simplified_phantom', 'target': 'A'} or a vessel folder path."
        )
    return FixedAnatomy(compile_anatomy(kwargs["vessel"], scene), str(kwargs["target"]))


def load(
    domain_name: str,
    task_name: str,
    task_kwargs: Mapping[str, Any] | None = None,
    environment_kwargs: Mapping[str, Any] | None = None,
) -> NavigationEnvironment:
    """Returns a navigation environment from the suite.

    Args:
        domain_name: A registered domain, e.g. ``"simplified_phantom"``.
        task_name: A task of that domain, e.g. ``"task_a"``.
        task_kwargs: ``wire`` (a preset of :func:`sim4endor.models.wires.names`, e.g.
            ``"workhorse"``, a :class:`~sim4endor.models.guidewire.GuidewireConfig` or a
            mapping of its fields with optional ``preset`` and ``tip``; default: the domain's,
            above), ``fidelity`` (``"converged"``, the default, or ``"fast"``: the numerical
            settings of a preset wire, :mod:`sim4endor.models.fidelity`),
            ``random`` (seed), ``reward`` (``"manifold"``/``"euclidean"`` or a
            :class:`~sim4endor.rewards.RewardConfig`), ``curvature_weight``, ``observations``
            (extra entries), ``action`` / ``termination`` / ``initial_state`` / ``pixels`` /
            ``cathlab`` (config dataclasses);
            domain ``vessel``: ``vessel``, ``target``; domain ``random_coronary``:
            ``pool_size``, ``pool_seed``, ``cache_dir``; domain ``coronary``: those and
            ``side``, ``anatomy`` (``"normal"``, the default, or ``"wide"``: tortuous, stenosed
            and narrower trees, :data:`sim4endor.tasks.coronary.Anatomies`), ``vary_wire``
            (each tree its own unit of the wire: stiffness, friction and tip shape drawn
            within :class:`sim4endor.models.wires.WireVariation`'s ranges), ``target``,
            ``target_weights`` (relative weights of drawing each target label, e.g.
            ``{"AM": 3}``; others 1); the coronary domains and ``vessel``: ``motion``
            (a beating and breathing heart moves the walls, :mod:`sim4endor.models.motion`:
            true, or a mapping of :class:`~sim4endor.models.motion.MotionRanges`' ranges).
            Every domain: ``cathlab`` (the sensors of the ``deployable`` observation set,
            :class:`~sim4endor.tasks.CathLabConfig`) and ``randomise`` (domain randomisation
            of the sensors and the driver, :mod:`sim4endor.tasks.randomisation`).
        environment_kwargs: Passed to ``control.Environment`` (e.g. ``time_limit``).

    Raises:
        sim4endor.registry.UnknownTaskError: For an unknown name; lists the valid ones.
        sim4endor.tasks.TaskConfigError: For an unknown or invalid task keyword.
    """
    entry = registry.find(domain_name, task_name)
    kwargs = dict(task_kwargs or {})
    valid = _COMMON_KWARGS + _DOMAIN_KWARGS.get(entry.domain, ())
    unknown = sorted(set(kwargs) - set(valid))
    if unknown:
        raise TaskConfigError(f"Unknown task_kwargs {unknown} for {domain_name}/{task_name}; "
                              f"valid: {list(valid)}.")
    termination = _termination(entry, kwargs)
    initial_state = (WRONG_BRANCH_START if entry.start == registry.START_WRONG_BRANCH
                     else InitialStateConfig())
    # The phantoms lie in their x-y plane: on the table, face up, for the C-arm's views.
    cathlab = CathLabConfig(patient_axes=PHANTOM_AXES if registry.TAG_PHANTOM in entry.tags
                            else LPS_AXES)
    config = _navigation_config(kwargs, termination, initial_state, cathlab)
    seed = _seed(kwargs.get("random"))
    extra_env_kwargs = _environment_kwargs(environment_kwargs or {})
    anatomies = _anatomy_source(entry, kwargs)
    physics = physics_for(anatomies.initial())
    task = NavigationTask(anatomies, config, random=seed)
    env_kwargs = {
        "time_limit": config.termination.time_limit,
        "control_timestep": config.action.control_timestep,
        # Plain mj_step: every reading (tip, contacts, forces) then describes one consistent
        # state, 5 ms before the end of the control step, and the wall force needs no extra
        # constraint solve (legacy stepping costs ~10 % more per step; see GuidewirePhysics).
        "legacy_step": False,
        **extra_env_kwargs,
    }
    return NavigationEnvironment(physics, task, **env_kwargs)


def physics_for(anatomy: Anatomy) -> GuidewirePhysics:
    """Returns a fresh Physics (own MjData) of an anatomy's compiled model."""
    return GuidewirePhysics.from_model(MjModel(anatomy.model))
