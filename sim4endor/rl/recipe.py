"""A shipped policy's training recipe: ``sim4endor train generalist --out DIR``.

A recipe (``recipe.yaml`` beside a shipped policy, read into :class:`RecipeConfig`) trains a
policy by imitation of the privileged expert (:mod:`sim4endor.rl.imitation`), in stages:

``demonstrations``
    the plain expert drives ``episodes`` episodes on each source (a domain's tree pool);
``clone``
    behaviour cloning of them into a fresh actor;
``takeover_K``, ``finetune_K`` (K = 1 .. ``rounds``)
    the last stage's policy drives each takeover source, the probing expert taking over
    where it stalls; then the last policy is cloned on every label so far (HG-DAgger).

With a ``teacher`` (a trained policy, e.g. the shipped ``generalist``) the recipe distils it
into a student that reads ``policy.env.observations`` (e.g. ``deployable``): the teacher
drives the demonstrations, and in each round the student drives while the teacher labels
every state it visits (DAgger; :class:`~sim4endor.rl.imitation.Teaching`).

Episodes are collected in chunks of ``chunk_episodes`` by ``envs`` worker processes or by
Ray tasks on a cluster (``--backend ray``), and saved by this process (one ``.npz`` each under
``DIR/data``, written atomically); every learnt stage is a run folder under ``DIR/stages`` and
a line of ``DIR/log.jsonl``. Rerunning the same command after Ctrl-C or a lost machine
resumes: finished stages and chunks are kept, a cloning stage that was cut short is redone
(it takes seconds). The last stage is copied to ``DIR/policy``, a run
folder every command that takes a policy loads (``sim4endor evaluate DIR/policy``).
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import shutil
import signal
import time
from collections.abc import Callable, Iterable, Iterator
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import torch
import yaml
from torchrl.data import Bounded, Composite, TensorSpec, Unbounded
from torchrl.envs import EnvBase
from tqdm.auto import tqdm

from sim4endor._atomic import atomic_directory, atomic_write_text, exclusive_output
from sim4endor._checks import require
from sim4endor.assets import RECIPE_FILE, policies_dir, policy_names, recipe_names, run_or_policy
from sim4endor.errors import Sim4EndoRError
from sim4endor.observations import OBSERVATION_UNITS
from sim4endor.rl import checkpoint, imitation
from sim4endor.rl.algorithms import Agent, build_agent
from sim4endor.rl.config import (
    ConfigError,
    EnvConfig,
    TrainConfig,
    default_config,
    load_config,
    merge_fields,
    override_fields,
    save_config,
    to_dict,
)
from sim4endor.rl.envs import sim4endor_env
from sim4endor.rl.runs import evaluation_env, load_agent_for
from sim4endor.rl.trainer import CONFIG_FILE

#: One line per finished stage, in a recipe run's folder.
LOG_FILE = "log.jsonl"
#: The final policy's run folder inside a recipe run's folder.
POLICY_DIR = "policy"


#: Recipe fields that change how fast a run goes, not what it trains: a run resumes under
#: other values (every chunk's episodes depend on its own seed only).
_SCHEDULING = ("envs",)


class RecipeError(Sim4EndoRError):
    """A recipe cannot run as asked: an unknown name, or an output folder it cannot use."""


@dataclasses.dataclass(frozen=True)
class Source:
    """Where episodes are collected: a domain's tree pool.

    Attributes:
        domain: suite domain, e.g. ``coronary`` (the policy's own, with its training trees)
            or ``random_coronary``.
        episodes: episodes collected there per stage.
        pool_seed: seed of the first tree (``None``: the policy's own training trees).
        pool_size: number of trees (``None``: the policy's own).
        anatomy: domain ``coronary``: ``normal`` or ``wide`` trees (``EnvConfig.anatomy``;
            ``None``: the policy's own).
        vary_wire: domain ``coronary``: each tree its own unit of the wire
            (``EnvConfig.vary_wire``; ``None``: the policy's own).
    """

    domain: str = "coronary"
    episodes: int = 60
    pool_seed: int | None = None
    pool_size: int | None = None
    anatomy: str | None = None
    vary_wire: bool | None = None

    def __post_init__(self) -> None:
        require(self, "source", ConfigError, positive=("episodes",))

    def env(self, policy: EnvConfig) -> EnvConfig:
        """The environment of this source, for a policy trained with ``policy``'s settings."""
        fields: dict[str, Any] = {"domain": self.domain}
        fields.update({k: v for k, v in (("pool_seed", self.pool_seed),
                                          ("pool_size", self.pool_size),
                                          ("anatomy", self.anatomy),
                                          ("vary_wire", self.vary_wire)) if v is not None})
        return dataclasses.replace(evaluation_env(policy, fields), num_envs=1)


@dataclasses.dataclass(frozen=True)
class CloneSettings:
    """Behaviour cloning (:func:`sim4endor.rl.imitation.clone`): Adam on random batches.

    Attributes:
        steps: gradient steps per cloning stage.
        batch: labelled steps per batch.
        lr: Adam's learning rate.
        successful_only: clone only the demonstrations that reached their target (why: the
            generalist's recipe.yaml).
    """

    steps: int = 4000
    batch: int = 256
    lr: float = 3e-4
    successful_only: bool = False

    def __post_init__(self) -> None:
        require(self, "clone", ConfigError, positive=("steps", "batch", "lr"))


@dataclasses.dataclass(frozen=True)
class RecipeConfig:
    """Everything a recipe run needs; saved as ``recipe.yaml`` in its folder.

    Attributes:
        seed: seeds torch and every chunk's environment.
        envs: worker processes collecting episodes (1: in this process).
        policy: the trained policy's run config (observation set, network, wire and tip,
            training trees); the SAC settings are what ``sim4endor train sac --config``
            would use to train it further.
        demonstrations: where the plain expert's episodes are collected.
        clone: behaviour cloning settings, of the clone and of every finetune.
        rounds: takeover rounds after the clone.
        takeovers: where each round's takeover episodes are collected.
        stall_steps: control steps without ``imitation.MIN_GAIN`` of progress before the
            probing expert takes over.
        max_steps: control-step cap of an episode (the task's time limit also applies).
        chunk_episodes: episodes per saved chunk: what Ctrl-C can lose at most, per worker.
        teacher: a trained policy (a shipped name or a run folder) that labels the states
            instead of the scripted experts (``None``: the experts). It must run the
            student's wire, tip and fidelity.
    """

    seed: int = 1
    envs: int = 2
    policy: TrainConfig = dataclasses.field(default_factory=lambda: default_config("sac"))
    demonstrations: tuple[Source, ...] = (Source(),)
    clone: CloneSettings = CloneSettings()
    rounds: int = 1
    takeovers: tuple[Source, ...] = (Source(),)
    stall_steps: int = 40
    max_steps: int = 800
    chunk_episodes: int = 10
    teacher: str | None = None

    def __post_init__(self) -> None:
        require(self, "", ConfigError,
                positive=("envs", "stall_steps", "max_steps", "chunk_episodes"),
                non_negative=("seed", "rounds"))
        if not self.demonstrations:
            raise ConfigError("demonstrations: name at least one source of expert episodes.")
        if self.rounds and not self.takeovers:
            raise ConfigError(f"rounds={self.rounds} needs at least one takeovers source.")


#: A recipe file's key naming the shipped recipe it starts from (its other fields override).
BASE_KEY = "base"


def load_recipe(name: str, overrides: Iterable[str] = ()) -> RecipeConfig:
    """The recipe of the shipped policy ``name``, with ``field=value`` overrides applied
    (e.g. ``seed=2``, ``clone.steps=100``, ``policy.env.tip='3,75'``). A recipe file that
    names a ``base`` recipe is that recipe with the file's fields replaced (the student's is
    the generalist's, distilled onto what a cath lab measures)."""
    return override_fields(_read_recipe(name, ()), overrides)


def _read_recipe(name: str, within: tuple[str, ...]) -> RecipeConfig:
    """The shipped recipe ``name``; ``within``, the recipes whose ``base`` led here."""
    if name not in recipe_names():
        raise RecipeError(f"No recipe named {name!r}; the shipped recipes are "
                          f"{list(recipe_names())}.")
    if name in within:
        raise RecipeError(f"Recipe {within[0]!r} is based on itself: "
                          f"{' -> '.join((*within, name))}.")
    path = policies_dir() / name / RECIPE_FILE
    data = yaml.safe_load(path.read_text()) or {}
    base = data.pop(BASE_KEY, None)
    start = RecipeConfig() if base is None else _read_recipe(str(base), (*within, name))
    return merge_fields(start, data, str(path))


def recipe_dict(recipe: RecipeConfig) -> dict[str, Any]:
    """``recipe`` as plain nested dicts and lists (YAML friendly)."""
    data = dataclasses.asdict(recipe)
    data["policy"] = to_dict(recipe.policy)
    return json.loads(json.dumps(data))  # tuples to lists


@dataclasses.dataclass(frozen=True)
class _Driver:
    """The policy that drives a takeover chunk, sent whole (a Ray node has no copy of the run
    folder)."""

    config: TrainConfig
    weights: dict[str, torch.Tensor]


@dataclasses.dataclass(frozen=True)
class _Chunk:
    """Episodes one worker collects."""

    env: EnvConfig
    seed: int
    episodes: int
    driver: _Driver | None  # takeovers: the last stage's policy; demonstrations: the expert
    stall_steps: int
    max_steps: int
    out: Path  # where the calling process saves them
    teacher: _Driver | None = None  # labels every step instead of the scripted experts


def _collect_chunk(chunk: _Chunk) -> tuple[Path, imitation.Episodes]:
    """Collects one chunk's episodes (in a worker process or a Ray task); returns them with
    where they belong."""
    torch.set_num_threads(1)
    env = sim4endor_env(chunk.env, chunk.seed)
    try:
        actor = None
        if chunk.driver is not None:
            agent = build_agent(chunk.driver.config, env.observation_spec, env.action_spec)
            agent.env_actor.load_state_dict(chunk.driver.weights)
            actor = agent.env_actor
        teacher = None if chunk.teacher is None else _teacher(chunk.teacher, env)
        return chunk.out, imitation.collect(env, actor, episodes=chunk.episodes,
                                            max_steps=chunk.max_steps,
                                            stall_steps=chunk.stall_steps, teacher=teacher)
    finally:
        env.close()


def _teacher(driver: _Driver, env: EnvBase) -> imitation.Teacher:
    """The teacher whose config and weights ``driver`` holds, on ``env``'s actions."""
    agent = _teacher_agent(driver.config, env.action_spec)
    agent.env_actor.load_state_dict(driver.weights)
    return imitation.Teacher(agent.env_actor, driver.config.env.observation_names())


def _teacher_agent(config: TrainConfig, action_spec: TensorSpec) -> Agent:
    """A fresh agent of a teacher's config, its networks sized by its own observation set
    (the student's environment observes another)."""
    width = sum(OBSERVATION_UNITS[name][1] or 0 for name in config.env.observation_names())
    spec = Composite(observation=Unbounded(shape=(width,), dtype=torch.float32))
    return build_agent(config, spec, action_spec)


def _ignore_interrupt() -> None:
    # Ctrl-C reaches every process of the terminal's group: the workers leave it to the main
    # process, which terminates them; only the main process writes chunks.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _in_processes(chunks: list[_Chunk],
                  workers: int) -> Iterator[tuple[Path, imitation.Episodes]]:
    """Each chunk's episodes as they finish, collected by ``workers`` processes."""
    if workers == 1 or len(chunks) <= 1:
        yield from map(_collect_chunk, chunks)
        return
    context = multiprocessing.get_context("spawn")  # CoACD's OpenMP: never fork
    with context.Pool(min(workers, len(chunks)), initializer=_ignore_interrupt) as pool:
        yield from pool.imap_unordered(_collect_chunk, chunks)


def _on_ray(chunks: list[_Chunk],
            address: str | None) -> Iterator[tuple[Path, imitation.Episodes]]:
    """Each chunk's episodes as they finish, collected by Ray tasks (one CPU each) on the
    cluster at ``address`` (:func:`sim4endor.rl.ray_backend.connected`)."""
    from sim4endor.rl.ray_backend import connected

    with connected(address) as ray:
        task = ray.remote(num_cpus=1)(_collect_chunk)
        pending = [task.remote(chunk) for chunk in chunks]
        try:
            while pending:
                (ready,), pending = ray.wait(pending, num_returns=1)
                yield ray.get(ready)
        finally:
            for ref in pending:  # Ctrl-C or a failed task: stop the rest
                ray.cancel(ref, force=True)


class RecipeRun:
    """One recipe run in ``out``: its stages, resumed from what the folder already holds."""

    def __init__(self, recipe: RecipeConfig, out: Path, *, progress: bool = True,
                 backend: str = "local", ray_address: str | None = None) -> None:
        """
        Args:
            recipe: what to run.
            out: the run's folder: new, empty, or a run of the same recipe (resumed).
            progress: show progress bars.
            backend: who collects episodes: ``local``, ``recipe.envs`` worker processes;
                ``ray``, one Ray task per chunk on the cluster at ``ray_address``
                (:func:`sim4endor.rl.ray_backend.connected`), as many at once as it has CPUs.
            ray_address: the cluster's head node, ``HOST:PORT``.
        """
        if backend not in ("local", "ray"):
            raise RecipeError(f"backend {backend!r}: choose local or ray.")
        self.recipe = recipe
        self.out = Path(out)
        self.progress = progress
        self.backend = backend
        self.ray_address = ray_address
        with exclusive_output(self.out):
            self._claim_folder()

    def _claim_folder(self) -> None:
        """Refuses a folder that is not this recipe's run; writes ``recipe.yaml``."""
        path = self.out / RECIPE_FILE
        wanted = recipe_dict(self.recipe)
        if path.is_file():
            # Through the dataclass: a field added since the folder was made reads its default.
            saved = recipe_dict(merge_fields(RecipeConfig(), yaml.safe_load(path.read_text()),
                                             str(path)))
            changed = sorted(k for k in wanted
                             if k not in _SCHEDULING and saved[k] != wanted[k])
            if changed:
                raise RecipeError(
                    f"{self.out} holds a run of another recipe (differs in {changed}); resume "
                    "it with the same settings or choose a new --out folder.")
        elif self.out.exists() and any(self.out.iterdir()):
            raise RecipeError(f"{self.out} is not empty and holds no {RECIPE_FILE}; choose a "
                              "new or empty --out folder (a recipe run writes many files).")
        else:
            atomic_write_text(path, yaml.safe_dump(wanted, sort_keys=False))

    def _done(self) -> dict[str, dict[str, Any]]:
        log = self.out / LOG_FILE
        lines = log.read_text().splitlines() if log.is_file() else []
        return {record["stage"]: record for record in map(json.loads, lines)}

    def _stages(self) -> Iterator[tuple[str, Callable[[], dict[str, Any]]]]:
        recipe = self.recipe
        yield "demonstrations", partial(self._collect, "demonstrations", 0,
                                        recipe.demonstrations, None)
        yield "clone", partial(self._clone, "clone", None)
        last = "clone"
        for k in range(1, recipe.rounds + 1):
            yield f"takeover_{k}", partial(self._collect, f"takeover_{k}", k, recipe.takeovers,
                                           last)
            yield f"finetune_{k}", partial(self._clone, f"finetune_{k}", last)
            last = f"finetune_{k}"

    def run(self) -> dict[str, Any]:
        """Runs the stages not yet done; returns the run's summary (stage records, total
        seconds, the policy folder). A second run of the same folder at once is refused."""
        with exclusive_output(self.out):
            return self._run()

    def _run(self) -> dict[str, Any]:
        # The networks are small: one thread clones fastest, and several in each of a few
        # processes sharing the cores slow each other twentyfold (measured).
        torch.set_num_threads(self.recipe.policy.torch_threads)
        done = self._done()
        stages = list(self._stages())
        for name, stage in stages:
            if name in done:
                continue
            start = time.monotonic()
            record = {"stage": name, **stage()}
            record["seconds"] = round(time.monotonic() - start, 1)
            with (self.out / LOG_FILE).open("a") as log:
                log.write(json.dumps(record) + "\n")
            done[name] = record
            if self.progress:
                tqdm.write(json.dumps(record))
        last = self.out / "stages" / stages[-1][0]
        policy = self.out / POLICY_DIR
        if not (policy / CONFIG_FILE).is_file():
            with atomic_directory(policy) as staging:
                shutil.copytree(last, staging, dirs_exist_ok=True)
        return {"policy": str(policy),
                "seconds": round(sum(r["seconds"] for r in done.values()), 1),
                "stages": list(done.values())}

    def _collect(self, stage: str, index: int, sources: tuple[Source, ...],
                 driver: str | None) -> dict[str, Any]:
        """Collects every source's episodes in chunks, skipping the chunks already saved;
        ``driver``, a stage whose policy drives (None: the plain expert)."""
        recipe = self.recipe
        chunks: list[_Chunk] = []
        for s, source in enumerate(sources):
            env = source.env(recipe.policy.env)
            for c, first in enumerate(range(0, source.episodes, recipe.chunk_episodes)):
                chunks.append(_Chunk(
                    env=env,
                    # Apart for every seed, stage, source and chunk.
                    seed=recipe.seed * 1_000_000 + index * 10_000 + s * 1_000 + c,
                    episodes=min(recipe.chunk_episodes, source.episodes - first),
                    driver=None, stall_steps=recipe.stall_steps,
                    max_steps=recipe.max_steps,
                    out=self.out / "data" / f"{stage}_{s}_{source.domain}_{c:03d}.npz"))
        todo = [chunk for chunk in chunks if not chunk.out.is_file()]
        if driver is not None and todo:
            agent = self._agent(driver)
            todo = [dataclasses.replace(chunk, driver=_Driver(
                self._config, agent.env_actor.state_dict())) for chunk in todo]
        if recipe.teacher is not None and todo:
            teacher = self._teacher()
            todo = [dataclasses.replace(chunk, teacher=teacher) for chunk in todo]
        total = sum(chunk.episodes for chunk in chunks)
        finished = (_on_ray(todo, self.ray_address) if self.backend == "ray"
                    else _in_processes(todo, recipe.envs))
        with tqdm(total=total, initial=total - sum(c.episodes for c in todo), unit="episodes",
                  desc=stage, disable=not self.progress) as bar:
            for path, episodes in finished:
                episodes.save(path)
                bar.update(len(episodes.success))
        data = [imitation.Episodes.load(chunk.out) for chunk in chunks]
        return {"episodes": int(sum(len(d.success) for d in data)),
                "successes": int(sum(d.success.sum() for d in data)),
                "labels": int(sum(d.expert.sum() for d in data))}

    def _clone(self, stage: str, start: str | None) -> dict[str, Any]:
        """Clones every label collected so far into ``start``'s policy (None: a fresh one);
        writes the stage's run folder."""
        began = time.monotonic()
        recipe = self.recipe
        torch.manual_seed(recipe.seed)
        groups = [self._labels("demonstrations", successful_only=recipe.clone.successful_only)]
        if start is not None:  # a finetune: the takeovers of every round so far, as a group
            groups.append(self._labels("takeover_"))
        agent = self._agent(start)
        error = imitation.clone(agent.actor, groups, steps=recipe.clone.steps,
                                batch=recipe.clone.batch, lr=recipe.clone.lr,
                                seed=recipe.seed, progress=self.progress, desc=stage)
        with atomic_directory(self.out / "stages" / stage) as staging:
            save_config(self._config, staging / CONFIG_FILE)
            checkpoint.save_checkpoint(staging, agent,
                                       self._progress(time.monotonic() - began), None)
        return {"labels": [len(label) for _, label in groups], "squared_error": round(error, 4)}

    def _progress(self, seconds: float) -> checkpoint.Progress:
        """The run's counters at the end of a cloning stage that took ``seconds``, saved in its
        checkpoint so that evaluations and tables report a recipe policy's cost as they do a
        SAC run's: every step and episode collected so far, every cloning step so far, and the
        seconds of every stage so far."""
        done = self._done()
        data = [imitation.Episodes.load(path) for path in (self.out / "data").glob("*.npz")]
        clones = 1 + sum(name == "clone" or name.startswith("finetune_") for name in done)
        return checkpoint.Progress(
            frames=sum(len(chunk.episode) for chunk in data),
            episodes=sum(len(chunk.success) for chunk in data),
            updates=clones * self.recipe.clone.steps,
            wall_clock_s=sum(record["seconds"] for record in done.values()) + seconds)

    def _teacher(self) -> _Driver:
        """The recipe's teacher, whole: its config and its actor's weights."""
        assert self.recipe.teacher is not None
        folder = run_or_policy(self.recipe.teacher)
        if not (folder / CONFIG_FILE).is_file():
            raise RecipeError(f"teacher {self.recipe.teacher!r} is neither a shipped policy "
                              f"({list(policy_names())}) nor a run folder with {CONFIG_FILE}.")
        config = load_config(folder / CONFIG_FILE)
        student = self.recipe.policy.env
        differs = [name for name in ("wire", "tip", "fidelity")
                   if getattr(config.env, name) != getattr(student, name)]
        if differs:
            raise RecipeError(f"teacher {self.recipe.teacher!r} ran another {differs} than "
                              f"the student's policy.env; give the student the teacher's.")
        # The suite's action: [insertion, rotation] increments in [-1, 1].
        agent = _teacher_agent(config, Bounded(-1.0, 1.0, shape=(2,), dtype=torch.float32))
        checkpoint.load_checkpoint(folder, agent)
        return _Driver(config, agent.env_actor.state_dict())

    @property
    def _config(self) -> TrainConfig:
        """Every stage's run config: the recipe's policy, on the recipe's seed."""
        return dataclasses.replace(self.recipe.policy, seed=self.recipe.seed)

    def _agent(self, stage: str | None) -> Agent:
        """The policy of a finished ``stage`` (None: a fresh one)."""
        env = sim4endor_env(self.recipe.demonstrations[0].env(self._config.env),
                            self.recipe.seed)
        try:
            if stage is None:
                return build_agent(self._config, env.observation_spec, env.action_spec)
            return load_agent_for(self.out / "stages" / stage, self._config, env)
        finally:
            env.close()

    def _labels(self, prefix: str, *, successful_only: bool = False
                ) -> tuple[np.ndarray, np.ndarray]:
        """The expert's steps of every chunk saved by the stages named ``prefix...`` (of its
        successful episodes only, if asked)."""
        chunks = map(imitation.Episodes.load, sorted((self.out / "data").glob(f"{prefix}*.npz")))
        labels = [(chunk.successful() if successful_only else chunk).labels for chunk in chunks]
        if successful_only and not sum(len(action) for _, action in labels):
            raise RecipeError(
                f"{self.out}: no {prefix} episode reached its target, so there is nothing to "
                "clone with clone.successful_only; collect more (or longer) episodes, or set "
                "clone.successful_only=false.")
        return (np.concatenate([obs for obs, _ in labels]),
                np.concatenate([action for _, action in labels]))
