"""Typed training configuration with the paper's hyper-parameters as defaults.

The paper (Implementation Details) trains with a target smoothing coefficient τ = 0.005, the
target network updated every optimisation step, learning rate 1e-4, discount γ = 0.99, a
replay buffer of 1e6 transitions, mini-batches of 100, exploration noise 0.1, 2000 initial
random steps ("sampling performed every 2000 steps", read here as the warm-up before learning
starts), 10 evaluation trials and 100k environment steps. Those are the defaults below; every
field can be overridden with a ``section.field=value`` string (see :func:`apply_overrides`).
"""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Literal

import yaml

from sim4endor._argtypes import MAX_SEED
from sim4endor._checks import require
from sim4endor.errors import Sim4EndoRError
from sim4endor.observations import (
    BIPLANE_OBSERVATIONS,
    OBSERVATION_SETS,
    OBSERVATION_UNITS,
    PLANE_OBSERVATIONS,
)

Algorithm = Literal["ddpg", "sac", "ppo"]
ALGORITHMS: tuple[str, ...] = ("ddpg", "sac", "ppo")
#: Where the environment workers of a run step: in this machine's processes, or on Ray.
CollectorBackend = Literal["local", "ray"]


class ConfigError(Sim4EndoRError, ValueError):
    """A configuration file or override names an unknown field or holds a bad value."""


def _check(config: object, section: str, **rules: tuple[str, ...]) -> None:
    require(config, section, ConfigError, **rules)


#: Factor per observation entry that brings its typical magnitude to O(1) (the network's
#: default input scaling): positions over ~0.05-0.1 m (×20), speeds up to 0.03 m/s (×30),
#: the route ahead up to 20 mm (×50), radii of ~2 mm (×500), tip forces up to the 0.6-1 N
#: failure (×2), wall forces of a few N (×0.5), stall times up to 5 s (×0.2), rotation
#: within ±10 turns (×0.02); the tracked wire up to 10 mm behind the tip (×100), the roadmap's
#: offset from it up to a few mm (×200), a track's age up to 0.7 s (×2), the load cell's
#: reading up to the 1 N push limit (×2).
_SCALES: dict[str, float] = {
    "tip_position": 20.0, "tip_velocity": 30.0, "target_position": 20.0, "wire_shape": 20.0,
    "last_action": 1.0, "insertion": 10.0, "rotation": 0.02, "manifold_distance": 10.0,
    "path_ahead": 50.0, "axis_offset": 1.0, "lumen_radius": 500.0,
    "tip_velocity_local": 30.0, "tip_force": 2.0, "wall_force": 0.5, "stall_time": 0.2,
    "tracked_wire": 100.0, "roadmap_offset": 200.0, "roadmap_ahead": 50.0,
    "roadmap_remaining": 10.0, "roadmap_stall": 0.2, "tracking_age": 2.0,
    "proximal_force": 2.0,
}
#: The factors above, and the second image plane's entries scaled as the first's.
OBSERVATION_SCALES: dict[str, float] = {
    **_SCALES, **{f"{name}_b": _SCALES[name] for name in PLANE_OBSERVATIONS}}


def default_observation_scale(env: EnvConfig) -> tuple[float, ...]:
    """One factor per observation number: each entry's :data:`OBSERVATION_SCALES` factor,
    repeated over its size (``[20, 20, 20, 30, 30, 30]`` for the paper's state)."""
    factors: list[float] = []
    for name in env.observation_names():
        size = OBSERVATION_UNITS[name][1]
        if size is None or name not in OBSERVATION_SCALES:
            raise ConfigError(
                f"env observation {name!r} has no default network.observation_scale factor "
                "(its size depends on the task); give network.observation_scale explicitly "
                "(one factor per number) or [] for none."
            )
        factors += [OBSERVATION_SCALES[name]] * size
    return tuple(factors)


@dataclasses.dataclass(frozen=True)
class EnvConfig:
    """Which environment to train on, with the task arguments of its domain.

    The domain-specific fields are ``None`` (not given) unless the domain takes them; the
    suite refuses one the domain does not take, naming the valid ones
    (:func:`sim4endor.suite.load`).

    Attributes:
        domain: suite domain, e.g. ``simplified_phantom``.
        task: task name within the domain, e.g. ``task_a``.
        reward: distance used by the progress reward: geodesic (``manifold``) or ``euclidean``.
        num_envs: environments stepped per collector (>1 uses one worker process each;
            with ``collector.backend=ray``, one Ray actor each).
        observations: the observation set (:data:`sim4endor.tasks.OBSERVATION_SETS`):
            ``paper`` (the paper's state ``[tip_position, tip_velocity]``) or ``generalist``
            (tip-frame entries that name no patient coordinates, for training across
            anatomies).
        extra_observations: with the ``paper`` set, task observation entries appended to it,
            e.g. ``["rotation"]`` (rad): the paper's state cannot see the accumulated wire
            rotation, whose limit ends episodes. Add one ``network.observation_scale`` factor
            per extra entry.
        vessel: domain ``vessel``: a vessel name or the folder ``sim4endor vessel build``
            wrote (stored as an absolute path, so the run can be evaluated from anywhere).
        target: domain ``vessel``: the target label, e.g. ``T1``.
        wire: a guidewire preset of :mod:`sim4endor.models.wires`, or a JSON object of its
            fields with an optional ``preset`` (``'{"preset": "paper", "chain_bodies": 6}'``;
            :func:`sim4endor.models.wires.resolve`); ``None``: the domain's default wire.
        tip: the shape a cardiologist bends into ``wire``'s tip (:func:`sim4endor.models.
            wires.parse_tip`): ``"LENGTH_MM,ANGLE_DEG"``, e.g. ``"3,75"``, or ``"J"``
            (``None``: the preset's own shape). Needs ``wire``.
        fidelity: the numerical settings of the wire (:mod:`sim4endor.models.fidelity`):
            ``converged`` or ``fast`` (``None``: the default, ``converged``).
        pool_seed: generated-tree domains: seed of the first training tree.
        pool_size: generated-tree domains: number of training trees.
        eval_pool_seed: generated-tree domains: seed of the first evaluation tree; a seed at
            least ``pool_size`` away from ``pool_seed`` gives a held-out split (``None``:
            evaluate on the training trees).
        anatomy: domain ``coronary``: ``normal`` or ``wide`` trees
            (:data:`sim4endor.tasks.coronary.Anatomies`; ``None``: normal).
        vary_wire: domain ``coronary``: each tree its own unit of the wire (stiffness,
            friction and tip shape drawn within
            :class:`sim4endor.models.wires.WireVariation`'s ranges; ``None``: the one wire).
        randomise: domain randomisation for sim-to-real, drawn per episode (the tracking,
            the action delay, the driver's backlash and slip; on coronary trees a wire unit
            per tree: :mod:`sim4endor.tasks.randomisation`; ``None``: off).
        motion: coronary trees and vessel folders: a beating and breathing heart moves the
            walls (:mod:`sim4endor.models.motion`; ``None``: a still heart).
        cathlab: the cath lab's sensors of the ``deployable`` entries, as fields of
            :class:`sim4endor.tasks.CathLabConfig` (e.g. ``{frame_rate: 15.0}``; ``None``: its
            defaults). A set that reads the second plane (``deployable_biplane``) makes the
            lab biplane.
        target_weights: domain ``coronary``, training only: relative weights of drawing each
            target label, e.g. ``{AM: 3, RV: 3}`` (others 1), a curriculum that trains more on
            the branches a policy misses; evaluations keep drawing targets uniformly, so
            their figures stay comparable (``None``: uniform).
    """

    domain: str = "simplified_phantom"
    task: str = "task_a"
    reward: Literal["manifold", "euclidean"] = "manifold"
    num_envs: int = 1
    observations: str = "paper"
    extra_observations: tuple[str, ...] = ()
    vessel: str | None = None
    target: str | None = None
    wire: str | None = None
    tip: str | None = None
    fidelity: str | None = None
    pool_seed: int | None = None
    pool_size: int | None = None
    eval_pool_seed: int | None = None
    anatomy: str | None = None
    vary_wire: bool | None = None
    randomise: bool | None = None
    motion: bool | None = None
    cathlab: dict[str, Any] | None = None
    target_weights: dict[str, float] | None = None

    def __post_init__(self) -> None:
        _check(self, "env", positive=("num_envs", "pool_size"),
               non_negative=("pool_seed", "eval_pool_seed", "target_weights"))
        if self.observations not in OBSERVATION_SETS:
            raise ConfigError(f"env.observations must be one of {sorted(OBSERVATION_SETS)}, "
                              f"got {self.observations!r}.")
        if self.observations != "paper" and self.extra_observations:
            raise ConfigError("env.extra_observations extend the 'paper' set only; the "
                              f"{self.observations!r} set is used as it is.")
        if self.tip is not None and self.wire is None:
            raise ConfigError(f"env.tip={self.tip!r} shapes the tip of env.wire: name the "
                              "wire preset too (e.g. workhorse).")
        if self.wire is not None or self.fidelity is not None:
            # Resolved now, so that a bad wire, tip or fidelity is refused before any tree is
            # built; imported here: the wire catalogue loads MuJoCo, which configs and --help
            # do not need.
            from sim4endor.errors import Sim4EndoRError
            from sim4endor.models import wires

            try:
                wires.resolve(self.wire_setting(), self.fidelity)
            except Sim4EndoRError as exc:
                raise ConfigError(f"env.wire / env.tip / env.fidelity: {exc}") from None
        if self.vary_wire is not None and self.domain != "coronary":
            raise ConfigError(f"env.vary_wire draws a wire per coronary tree; domain "
                              f"{self.domain!r} has no pool of them.")
        if self.anatomy is not None and self.domain != "coronary":
            raise ConfigError(f"env.anatomy chooses the coronary domain's trees; domain "
                              f"{self.domain!r} has none.")
        if self.target_weights is not None and self.domain != "coronary":
            raise ConfigError(f"env.target_weights weigh the coronary domain's targets; "
                              f"domain {self.domain!r} draws none.")
        if self.cathlab is not None:
            # Imported here, as the wire catalogue is: the task's settings load MuJoCo.
            from sim4endor.tasks import CathLabConfig, TaskConfigError

            known = [field.name for field in dataclasses.fields(CathLabConfig)]
            unknown = sorted(set(self.cathlab) - set(known))
            if unknown:
                raise ConfigError(f"env.cathlab: unknown fields {unknown}; CathLabConfig has "
                                  f"{known}.")
            try:
                CathLabConfig(**self.cathlab)
            except TaskConfigError as exc:
                raise ConfigError(f"env.cathlab: {exc}") from None
            if self.cathlab.get("biplane") is False and self._biplane():
                raise ConfigError(f"env.observations {self.observations!r} read a biplane "
                                  "lab's second plane; drop env.cathlab.biplane=false.")
        if self.eval_pool_seed is not None and self.pool_size is None:
            raise ConfigError("env.eval_pool_seed needs env.pool_size (the training trees' "
                              "count), so the two splits can be told apart.")

    def wire_setting(self) -> str | dict[str, Any] | None:
        """``wire`` and ``tip`` as :func:`sim4endor.models.wires.resolve` takes them: a preset
        name, or a mapping of fields (a JSON ``wire`` parsed; ``tip`` as plain data, as an
        exported policy's policy.json records it)."""
        wire: str | dict[str, Any] | None = self.wire
        if isinstance(wire, str) and wire.lstrip().startswith("{"):
            try:
                wire = json.loads(wire)
            except json.JSONDecodeError as exc:
                raise ConfigError(f"env.wire is not a JSON object of wire fields: {exc}") from None
            if not isinstance(wire, dict):
                raise ConfigError(f"env.wire must be a preset name or a JSON object, got "
                                  f"{self.wire!r}.")
        if self.tip is None:
            return wire
        from sim4endor.models.wires import WireCatalogueError, parse_tip

        try:
            tip = parse_tip(self.tip)
        except WireCatalogueError as exc:
            raise ConfigError(f"env.tip: {exc}") from None
        shape = tip if isinstance(tip, str) else tip.as_mapping()
        return {**wire, "tip": shape} if isinstance(wire, dict) else {"preset": wire,
                                                                      "tip": shape}

    def observation_names(self) -> tuple[str, ...]:
        """The task's observation entries, in the order the observation vector holds them."""
        names = OBSERVATION_SETS[self.observations] + self.extra_observations
        return tuple(dict.fromkeys(names))

    def task_kwargs(self, seed: int, *, evaluation: bool = False) -> dict[str, Any]:
        """Returns the ``suite.load`` task_kwargs of this environment, seeded with ``seed``.

        Args:
            seed: The task's random seed.
            evaluation: Use the evaluation split of generated trees (``eval_pool_seed``).
        """
        observations = self.extra_observations if self.observations == "paper" \
            else self.observations
        kwargs: dict[str, Any] = {"random": seed, "reward": self.reward,
                                  "observations": observations}
        pool_seed = self.eval_pool_seed if evaluation and self.eval_pool_seed is not None \
            else self.pool_seed
        given = {"vessel": self.vessel, "target": self.target, "wire": self.wire_setting(),
                 "fidelity": self.fidelity, "pool_seed": pool_seed, "pool_size": self.pool_size,
                 "anatomy": self.anatomy, "vary_wire": self.vary_wire,
                 "randomise": self.randomise, "motion": self.motion,
                 "target_weights": None if evaluation else self.target_weights}
        kwargs.update({key: value for key, value in given.items() if value is not None})
        cathlab = dict(self.cathlab or {})
        if self._biplane():
            cathlab["biplane"] = True
        if cathlab:
            kwargs["cathlab"] = cathlab
        return kwargs

    def _biplane(self) -> bool:
        """Whether the observations read the second plane, which only a biplane lab has."""
        return any(name in BIPLANE_OBSERVATIONS for name in self.observation_names())


@dataclasses.dataclass(frozen=True)
class CollectorConfig:
    """Data collection budget.

    Attributes:
        total_frames: environment steps of the whole run (paper: 100k).
        frames_per_batch: steps collected between two rounds of optimisation.
        init_random_frames: uniformly random steps before learning starts (off-policy only).
        backend: ``local``: one environment in the learner's process, or ``env.num_envs``
            worker processes; ``ray``: ``env.num_envs`` Ray actors, one environment and one
            CPU each, on the cluster the run connects to, while this process learns and
            sends them the policy weights after each optimisation phase.
    """

    total_frames: int = 100_000
    frames_per_batch: int = 1_000
    init_random_frames: int = 2_000
    backend: CollectorBackend = "local"

    def __post_init__(self) -> None:
        _check(self, "collector", positive=("total_frames", "frames_per_batch"),
               non_negative=("init_random_frames",))


@dataclasses.dataclass(frozen=True)
class OptimConfig:
    """Optimisation hyper-parameters.

    Attributes:
        lr: Adam learning rate of every network (paper: 1e-4).
        gamma: discount factor (paper: 0.99).
        batch_size: transitions per gradient step (paper: 100).
        updates_per_batch: gradient steps per collected batch (off-policy; 0 = one per frame).
        tau: target smoothing coefficient, applied after every gradient step (paper: 0.005).
        max_grad_norm: gradient clipping threshold.
    """

    lr: float = 1e-4
    gamma: float = 0.99
    batch_size: int = 100
    updates_per_batch: int = 0
    tau: float = 0.005
    max_grad_norm: float = 10.0

    def __post_init__(self) -> None:
        _check(self, "optim", positive=("lr", "batch_size", "max_grad_norm"),
               non_negative=("updates_per_batch",), unit=("gamma", "tau"))


@dataclasses.dataclass(frozen=True)
class ReplayConfig:
    """Replay buffer (off-policy algorithms).

    Attributes:
        size: capacity in transitions (paper: 1e6).
    """

    size: int = 1_000_000

    def __post_init__(self) -> None:
        _check(self, "replay", positive=("size",))


@dataclasses.dataclass(frozen=True)
class NetworkConfig:
    """Actor and critic multilayer perceptrons.

    Attributes:
        hidden_sizes: width of each hidden layer.
        activation: ``relu`` or ``tanh``.
        observation_scale: fixed factors multiplying the observation before the first layer,
            one per number (empty: none; ``None``: each entry's factor of
            :data:`OBSERVATION_SCALES`, see :meth:`TrainConfig.observation_scale`). The tasks' state
            is in SI units, so raw inputs are ~1e-2; the factors bring them to O(1), e.g. the
            tip position (m, phantoms ~0.1 m across) ×20 and the tip velocity (m/s, top
            insertion speed 0.03 m/s) ×30. The scaling lives inside the networks, so an
            exported policy still takes SI inputs.
    """

    hidden_sizes: tuple[int, ...] = (256, 256)
    activation: Literal["relu", "tanh"] = "relu"
    observation_scale: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        _check(self, "network", positive=("hidden_sizes", "observation_scale"))


@dataclasses.dataclass(frozen=True)
class ExplorationConfig:
    """DDPG exploration noise.

    Attributes:
        noise_std: standard deviation of the Gaussian added to the normalised action (paper: 0.1).
    """

    noise_std: float = 0.1

    def __post_init__(self) -> None:
        _check(self, "exploration", non_negative=("noise_std",))


@dataclasses.dataclass(frozen=True)
class SACConfig:
    """SAC-specific settings (ignored by DDPG and PPO).

    Attributes:
        alpha_init: initial entropy temperature, tuned automatically afterwards (target
            entropy −dim(action)). The paper's progress reward is ~0.015 per step (mm / 100),
            so TorchRL's usual 1.0 lets the entropy bonus swamp it for thousands of steps at
            lr 1e-4 (measured: α still 0.7 and no progress after 5k steps); 0.01 matches the
            reward scale.
    """

    alpha_init: float = 0.01

    def __post_init__(self) -> None:
        _check(self, "sac", positive=("alpha_init",))


@dataclasses.dataclass(frozen=True)
class PPOConfig:
    """PPO-specific settings (ignored by DDPG and SAC).

    Attributes:
        clip_epsilon: ratio clipping.
        epochs: passes over each collected batch.
        minibatch_size: transitions per PPO gradient step.
        gae_lambda: GAE λ.
        entropy_coef: entropy bonus weight.
    """

    clip_epsilon: float = 0.2
    epochs: int = 10
    minibatch_size: int = 100
    gae_lambda: float = 0.95
    entropy_coef: float = 1e-3

    def __post_init__(self) -> None:
        _check(self, "ppo", positive=("clip_epsilon", "epochs", "minibatch_size"),
               fraction=("gae_lambda",), non_negative=("entropy_coef",))


@dataclasses.dataclass(frozen=True)
class EvalConfig:
    """Periodic evaluation with the deterministic policy.

    Attributes:
        interval_frames: evaluate every this many collected frames (0 = only at the end).
        trials: episodes per evaluation (paper: 10).
        max_steps: step cap of one evaluation episode (the task's own time limit also applies).
        keep_weights: also keep the weights of every periodic evaluation in
            ``RUN_DIR/evaluated/FRAMES/`` (a run folder each, ~3.4 MB for the generalist's
            networks), not only the best one's: a few evaluation episodes rank checkpoints
            roughly (20 episodes and 100 disagreed by up to 13 points on the generalist,
            docs/results/generalisation), so they can be ranked again on more episodes.
    """

    interval_frames: int = 10_000
    trials: int = 10
    max_steps: int = 1_000
    keep_weights: bool = False

    def __post_init__(self) -> None:
        _check(self, "eval", positive=("trials", "max_steps"), non_negative=("interval_frames",))


@dataclasses.dataclass(frozen=True)
class DemonstrationConfig:
    """Scripted-expert episodes in the replay buffer before training (DDPG and SAC).

    The privileged expert (:class:`~sim4endor.tasks.expert.CenterlineExpert`, the reference
    row of the evaluation tables) drives the training environments for ``episodes``
    episodes before the first collected frame; its transitions, rewards and failures
    included, join the replay buffer like any other (off-policy learning needs no more).
    They cost wall-clock, which the run's training time counts, but no collected frames.

    Attributes:
        episodes: expert episodes (0: none, the default).
    """

    episodes: int = 0

    def __post_init__(self) -> None:
        _check(self, "demonstrations", non_negative=("episodes",))


@dataclasses.dataclass(frozen=True)
class LoggerConfig:
    """TorchRL logger.

    Attributes:
        backend: ``csv`` (default), ``tensorboard`` (needs the ``tensorboard`` extra) or ``none``.
    """

    backend: Literal["csv", "tensorboard", "none"] = "csv"


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """Everything one training run needs; saved as ``config.yaml`` beside its checkpoints.

    Attributes:
        algorithm: ``ddpg``, ``sac`` or ``ppo``.
        seed: seeds torch, the environments and the replay buffer sampler.
        checkpoint_interval_frames: save a resumable checkpoint every this many frames.
        torch_threads: intra-op threads of torch; the networks are small, so one thread is
            fastest and leaves the other cores to the environment workers.
        device: where the learner (networks, losses, replay buffer) runs: ``auto`` (a CUDA
            GPU when torch sees one, else the CPU), ``cpu`` or ``cuda``. The environments
            always step on the CPU with a CPU copy of the policy. A run resumes on any device.
    """

    algorithm: Algorithm = "ddpg"
    seed: int = 0
    torch_threads: int = 1
    device: Literal["auto", "cpu", "cuda"] = "auto"
    checkpoint_interval_frames: int = 10_000
    env: EnvConfig = EnvConfig()
    collector: CollectorConfig = CollectorConfig()
    optim: OptimConfig = OptimConfig()
    replay: ReplayConfig = ReplayConfig()
    network: NetworkConfig = NetworkConfig()
    exploration: ExplorationConfig = ExplorationConfig()
    sac: SACConfig = SACConfig()
    ppo: PPOConfig = PPOConfig()
    eval: EvalConfig = EvalConfig()
    logger: LoggerConfig = LoggerConfig()
    demonstrations: DemonstrationConfig = DemonstrationConfig()

    def __post_init__(self) -> None:
        _check(self, "", positive=("torch_threads",),
               non_negative=("seed", "checkpoint_interval_frames"))
        if self.demonstrations.episodes and self.algorithm == "ppo":
            raise ConfigError(
                "demonstrations.episodes fills the replay buffer of DDPG or SAC; PPO learns "
                "on-policy and has none. Set it to 0 or choose sac."
            )
        if self.seed > MAX_SEED:
            raise ConfigError(f"seed must be at most {MAX_SEED}, got {self.seed}.")
        self.observation_scale()  # an entry without a default factor is named now
        # Ray's collector splits each batch evenly over its actors and refuses a remainder
        # (the local one rounds up), so the mismatch is named here, before a run starts.
        frames, envs = self.collector.frames_per_batch, self.env.num_envs
        if self.collector.backend == "ray" and frames % envs:
            raise ConfigError(
                f"collector.backend=ray splits collector.frames_per_batch={frames} evenly over "
                f"env.num_envs={envs} workers; choose a multiple of {envs}."
            )

    def observation_scale(self) -> tuple[float, ...]:
        """The network's input factors: ``network.observation_scale``, or when it is ``None``
        the default factor of each observation entry (:func:`default_observation_scale`)."""
        given = self.network.observation_scale
        return default_observation_scale(self.env) if given is None else given


def default_config(algorithm: str) -> TrainConfig:
    """Returns the paper's defaults for ``algorithm``.

    PPO is on-policy: it collects 2048-step batches (no random warm-up, no replay) and
    optimises each one for ``ppo.epochs`` passes.
    """
    if algorithm not in ALGORITHMS:
        raise ConfigError(f"Unknown algorithm {algorithm!r}; choose one of {list(ALGORITHMS)}.")
    config = TrainConfig(algorithm=typing.cast(Algorithm, algorithm))
    if algorithm == "ppo":
        config = dataclasses.replace(
            config, collector=CollectorConfig(frames_per_batch=2_048, init_random_frames=0)
        )
    return config


def to_dict(config: TrainConfig) -> dict[str, Any]:
    """Returns ``config`` as plain nested dicts/lists (YAML/JSON friendly)."""
    return _plain(dataclasses.asdict(config))


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    return value


def from_dict(
    data: Mapping[str, Any], *, source: str = "config", algorithm: str = "ddpg"
) -> TrainConfig:
    """Builds a :class:`TrainConfig` from nested dicts; missing fields keep their defaults.

    The algorithm's defaults (:func:`default_config`) are the base, so a file need only list
    what it changes; ``algorithm`` is used when ``data`` names none.

    Raises:
        ConfigError: on an unknown section or field, naming the valid ones.
    """
    algorithm = str(data.get("algorithm", algorithm))
    return merge_fields(default_config(algorithm), data, source)


def merge_fields(obj: Any, data: Mapping[str, Any], where: str) -> Any:
    """Returns the frozen dataclass ``obj`` with the fields ``data`` names replaced, read as
    their annotations say (nested dataclasses from mappings, tuples from lists).

    Raises:
        ConfigError: on an unknown field or a value of the wrong kind, naming it by ``where``.
    """
    fields = {f.name: f for f in dataclasses.fields(obj)}
    hints = typing.get_type_hints(type(obj))
    changes: dict[str, Any] = {}
    for key, value in data.items():
        if key not in fields:
            raise ConfigError(
                f"{where}: unknown field {key!r}; valid fields are {sorted(fields)}."
            )
        current = getattr(obj, key)
        if dataclasses.is_dataclass(current):
            if not isinstance(value, Mapping):
                raise ConfigError(f"{where}: {key!r} must be a mapping of its fields.")
            changes[key] = merge_fields(current, value, f"{where}.{key}")
        else:
            changes[key] = _coerce(value, hints[key], f"{where}.{key}")
    return dataclasses.replace(obj, **changes)


def _coerce(value: Any, hint: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if origin is types.UnionType:  # only `X | None` fields: None, or a value read as X
        (kind,) = [arg for arg in typing.get_args(hint) if arg is not type(None)]
        return None if value is None else _coerce(value, kind, where)
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        if not isinstance(value, Mapping):
            raise ConfigError(f"{where} must be a mapping of {hint.__name__}'s fields.")
        return merge_fields(hint(), value, where)
    if origin is Literal:
        if value not in typing.get_args(hint):
            raise ConfigError(f"{where}={value!r}; choose one of {list(typing.get_args(hint))}.")
        return value
    if origin is dict:
        if not isinstance(value, Mapping):
            raise ConfigError(f"{where} must be a mapping, got {value!r}.")
        key_hint, value_hint = typing.get_args(hint)
        return {_coerce(k, key_hint, f"{where} key"): _coerce(v, value_hint, f"{where}.{k}")
                for k, v in value.items()}
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{where} must be a list, got {value!r}.")
        item = typing.get_args(hint)[0]
        return tuple(_coerce(v, item, f"{where}[{i}]") for i, v in enumerate(value))
    if hint is Any:  # a mapping of another module's fields (env.cathlab), checked there
        return value
    if hint is bool and isinstance(value, bool):
        return value
    if hint in (int, float) and isinstance(value, str):
        # PyYAML reads 3e-4 (no dot) as text.
        try:
            value = float(value)
        except ValueError:
            pass
    # A bool is not a number here: YAML reads "yes" as True.
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if hint is int and number and float(value).is_integer():
        return int(value)
    if hint is float and number:
        return float(value)
    if hint is str and isinstance(value, str | int | float) and not isinstance(value, bool):
        return str(value)
    name = getattr(hint, "__name__", str(hint))
    raise ConfigError(f"{where}: cannot read {value!r} as {name}.")


def load_config(
    path: Path, overrides: Iterable[str] = (), *, algorithm: str = "ddpg"
) -> TrainConfig:
    """Reads a YAML config file and applies ``section.field=value`` overrides.

    ``algorithm`` is the algorithm of a file that names none.
    """
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"Cannot read config file {path}: {exc}") from exc
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path}: expected a mapping of config sections at the top level.")
    return apply_overrides(from_dict(data, source=str(path), algorithm=algorithm), overrides)


def apply_overrides(config: TrainConfig, overrides: Iterable[str]) -> TrainConfig:
    """Applies ``section.field=value`` strings (values parsed as YAML, e.g. ``optim.lr=3e-4``)."""
    return typing.cast(TrainConfig, override_fields(config, overrides))


def override_fields(obj: Any, overrides: Iterable[str]) -> Any:
    """Returns the frozen dataclass ``obj`` with ``section.field=value`` strings applied
    (values parsed as YAML), as :func:`merge_fields` reads them."""
    data: dict[str, Any] = {}
    for item in overrides:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"Override {item!r} is not of the form section.field=value.")
        node = data
        *parents, leaf = key.strip().split(".")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = yaml.safe_load(raw)
    return merge_fields(obj, data, "override")


def save_config(config: TrainConfig, path: Path) -> None:
    """Writes ``config`` as YAML, atomically."""
    from sim4endor._atomic import atomic_write_text

    atomic_write_text(Path(path), yaml.safe_dump(to_dict(config), sort_keys=False))
