"""The training loop shared by DDPG, SAC and PPO.

Collect a batch with a TorchRL collector, then optimise: off-policy algorithms (DDPG, SAC)
store every transition in a replay buffer and take one gradient step per collected frame
(unless ``optim.updates_per_batch`` says otherwise), updating the target networks after each;
PPO computes GAE advantages on the batch and runs ``ppo.epochs`` passes of minibatch steps.
Periodically the deterministic policy is evaluated and a resumable checkpoint is written.
With ``demonstrations.episodes``, a new off-policy run first fills its replay buffer with the
scripted expert's episodes (:func:`add_demonstrations`).

Run folder layout::

    RUN_DIR/config.yaml           the full TrainConfig
    RUN_DIR/checkpoint/           resumable state (see sim4endor.rl.checkpoint)
    RUN_DIR/logs/scalars/...csv   TorchRL CSV logger (train/*, eval/*) vs frames
    RUN_DIR/evaluations.jsonl     one line of metrics per periodic evaluation
    RUN_DIR/evaluation.json       the final evaluation (what `sim4endor table` reads)
    RUN_DIR/best/                 the weights of the best evaluation so far, itself a run folder
                                  (config.yaml, checkpoint/ without a replay, selection.json)
    RUN_DIR/evaluated/FRAMES/     with ``eval.keep_weights``: every periodic evaluation's
                                  weights, laid out as ``best/``

SAC and DDPG runs can end far below their best periodic evaluation, so ``best/`` keeps the
policy of the best one (most successes, then SPL, then mean return; the first of equals), to
evaluate or ship with ``sim4endor evaluate RUN_DIR/best``. Every periodic evaluation runs the
same episodes (same seed), so the comparison is paired. The evaluation environment is the
config's evaluation split: choosing weights on it makes it a validation split, so keep it apart
from the trees a result is reported on.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import math
import time
from pathlib import Path
from typing import Any

import torch
from tensordict import TensorDictBase
from torchrl.collectors import BaseCollector, Collector, MultiSyncCollector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs import EnvBase
from torchrl.record.loggers import Logger
from tqdm.auto import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

from sim4endor import _json as strict_json
from sim4endor._atomic import atomic_directory, atomic_write_text, holds_output
from sim4endor.errors import Sim4EndoRError, caused_by_interrupt
from sim4endor.rl import baselines, checkpoint, ray_backend
from sim4endor.rl.algorithms import Agent, build_agent, learner_device
from sim4endor.rl.config import TrainConfig, load_config, save_config, to_dict
from sim4endor.rl.envs import EnvFactory, env_factory
from sim4endor.rl.evaluation import (
    EpisodeKeys,
    reached,
    rollout_episodes,
    rollouts,
    success_fraction,
)
from sim4endor.rl.metrics import Episode, describe, summarize

_LOG = logging.getLogger(__name__)

CONFIG_FILE = "config.yaml"
EVALUATIONS_FILE = "evaluations.jsonl"
EVALUATION_FILE = "evaluation.json"
BEST_DIR = "best"
#: In ``best/``: the periodic evaluation that chose its weights (what later ones must beat);
#: in each ``evaluated/FRAMES/``: the evaluation of those weights.
SELECTION_FILE = "selection.json"
#: With ``eval.keep_weights``: one folder per periodic evaluation, named by its frames.
EVALUATED_DIR = "evaluated"
#: Offset between the training and evaluation seeds, so evaluation starts are never trained on.
EVAL_SEED_OFFSET = 10_000
#: Seed offset of the demonstration environment, apart from the collectors' (seed + frames).
DEMO_SEED_OFFSET = 20_000


def evaluation_record(progress: checkpoint.Progress, episodes: list[Episode]) -> dict[str, Any]:
    """One evaluation's metrics with the run's counters (a line of ``evaluations.jsonl``)."""
    return {
        "frames": progress.frames,
        "train_wall_clock_s": round(progress.wall_clock_s, 1),
        **summarize(episodes),
    }


def write_final_evaluation(run_dir: Path, metrics: dict[str, Any]) -> None:
    """Writes ``run_dir/evaluation.json``, what the tables read."""
    _write_metrics(Path(run_dir) / EVALUATION_FILE, metrics)


def _write_metrics(path: Path, metrics: dict[str, Any]) -> None:
    atomic_write_text(path, strict_json.dumps(metrics, indent=2) + "\n")


def _rank(metrics: dict[str, Any]) -> tuple[float, ...]:
    """How evaluations compare for ``best/``: successes, then SPL, then mean return.

    A value that is not a finite number ranks lowest: a diverged episode's NaN return, which
    the saved file holds as ``null`` (sim4endor._json), must neither win nor fail the
    comparison.
    """
    keys = ("success_rate", "spl", "mean_return")
    return tuple(float(v) if isinstance(v, int | float) and math.isfinite(v) else -math.inf
                 for v in map(metrics.get, keys))


class RunDirError(Sim4EndoRError):
    """A run folder holds a different run, or is not a run folder at all."""


@holds_output("run_dir")
def train(
    config: TrainConfig,
    run_dir: Path,
    *,
    make_env: EnvFactory | None = None,
    progress: bool = True,
    ray_address: str | None = None,
) -> dict[str, Any]:
    """Trains ``config`` into ``run_dir``, resuming from its checkpoint if it has one.

    Args:
        config: the run's configuration.
        run_dir: output folder (created); an existing checkpoint there is resumed when its
            config matches ``config`` (``collector.total_frames`` may grow).
        make_env: ``seed -> env`` factory of the training and evaluation environments;
            defaults to the sim4endor task of ``config.env`` (evaluated on its evaluation
            split, :attr:`~sim4endor.rl.config.EnvConfig.eval_pool_seed`).
        progress: show a tqdm progress bar.
        ray_address: ``collector.backend=ray``: the cluster to join (see
            :func:`sim4endor.rl.ray_backend.connected`; ``None``: ``RAY_ADDRESS``, else Ray
            on this machine).

    Returns:
        The final evaluation metrics (also written to ``run_dir/evaluation.json``).
    """
    # Joined before anything is built or written: a missing Ray or an unreachable cluster
    # must fail at once and leave no run folder behind.
    with _collector_backend(config, ray_address):
        return _train(config, Path(run_dir), make_env, progress)


def _collector_backend(
    config: TrainConfig, ray_address: str | None
) -> contextlib.AbstractContextManager[Any]:
    if config.collector.backend == "ray":
        return ray_backend.connected(ray_address)
    if ray_address is not None:
        raise Sim4EndoRError(
            f"A Ray address ({ray_address}) is given but collector.backend is local; "
            "add --backend ray (collector.backend=ray) or drop the address."
        )
    return contextlib.nullcontext()


def _train(
    config: TrainConfig, run_dir: Path, make_env: EnvFactory | None, progress: bool
) -> dict[str, Any]:
    make_eval_env = make_env or env_factory(config.env, evaluation=True)
    make_env = make_env or env_factory(config.env)
    _check_resumable(run_dir, config)
    device = learner_device(config.device)
    torch.set_num_threads(config.torch_threads)
    torch.manual_seed(config.seed)
    # Built before anything is written: a task argument the domain refuses (or a missing
    # vessel folder) must not leave a run folder behind.
    eval_env = make_eval_env(config.seed + EVAL_SEED_OFFSET)
    save_config(config, run_dir / CONFIG_FILE)
    agent = build_agent(config, eval_env.observation_spec, eval_env.action_spec, device)
    replay = _replay_buffer(config, device)
    state = checkpoint.Progress()
    if checkpoint.has_checkpoint(run_dir):
        state = checkpoint.load_checkpoint(run_dir, agent, replay)
        _LOG.info("resuming %s at %d frames", run_dir, state.frames)
    elif replay is not None and config.demonstrations.episodes:
        start = time.monotonic()
        add_demonstrations(make_env(config.seed + DEMO_SEED_OFFSET), agent, replay,
                           episodes=config.demonstrations.episodes,
                           max_steps=config.eval.max_steps, progress=progress)
        state = dataclasses.replace(state, wall_clock_s=time.monotonic() - start)
    _LOG.info("learner on %s", device)
    logger = _logger(config, run_dir)
    loop = _Loop(config, run_dir, agent, replay, logger, eval_env)
    try:
        state = loop.run(make_env, state, progress)
        return loop.final_evaluation(state, progress)
    finally:
        eval_env.close()


def train_from_file(path: Path, run_dir: Path, overrides: tuple[str, ...] = ()) -> dict[str, Any]:
    """Trains the config in YAML file ``path`` (with ``section.field=value`` overrides)."""
    return train(load_config(path, overrides), run_dir)


def _check_resumable(run_dir: Path, config: TrainConfig) -> None:
    """Refuses ``run_dir`` unless it is new, empty, or a run of ``config`` to resume: a run's
    files would otherwise land beside a user's own."""
    saved_path = run_dir / CONFIG_FILE
    if run_dir.is_dir() and any(run_dir.iterdir()) and not saved_path.is_file():
        held = sorted(p.name for p in run_dir.iterdir())
        shown = ", ".join(held[:3]) + (f" and {len(held) - 3} more" if len(held) > 3 else "")
        raise RunDirError(
            f"{run_dir} is not empty and not a run folder (it holds {shown}); choose a new or "
            "empty --out folder."
        )
    if run_dir.exists() and not run_dir.is_dir():
        raise RunDirError(f"{run_dir} exists and is not a folder; choose another --out folder.")
    if not checkpoint.has_checkpoint(run_dir) or not saved_path.is_file():
        return
    saved = load_config(saved_path)
    # More frames extend a run; the device is where it happens to run now; keeping the
    # evaluated weights changes no weights.
    ignore = {"total_frames", "device", "keep_weights"}
    if _without(to_dict(saved), ignore) != _without(to_dict(config), ignore):
        raise RunDirError(
            f"{run_dir} holds a checkpoint of a different configuration ({saved_path}); "
            "choose a new --out folder or delete that run."
        )


def _without(data: dict[str, Any], ignore: set[str]) -> dict[str, Any]:
    return {
        k: _without(v, ignore) if isinstance(v, dict) else v
        for k, v in data.items()
        if k not in ignore
    }


def _replay_buffer(
    config: TrainConfig, device: torch.device | str = "cpu"
) -> TensorDictReplayBuffer | None:
    if config.algorithm == "ppo":
        return None
    # On the learner's device: a batch is drawn there with no copy per gradient step.
    return TensorDictReplayBuffer(
        storage=LazyTensorStorage(config.replay.size, device=device),
        batch_size=config.optim.batch_size,
    )


def add_demonstrations(
    env: EnvBase, agent: Agent, replay: TensorDictReplayBuffer, *, episodes: int, max_steps: int,
    progress: bool = True,
) -> int:
    """Runs ``episodes`` episodes of the scripted expert in ``env`` (closed after) and adds
    their transitions to ``replay``; returns how many it added."""
    actor = baselines.policy(baselines.ScriptedExpert(), env)
    added = successes = 0
    try:
        with torch.no_grad():
            for rollout in rollouts(env, actor, trials=episodes, max_steps=max_steps,
                                    progress=progress, desc="demonstrations"):
                replay.extend(agent.transitions(rollout.reshape(-1)))
                added += rollout.numel()
                successes += reached(rollout)
    finally:
        env.close()
    _LOG.info("demonstrations: %d expert episodes (%d reached), %d transitions", episodes,
              successes, added)
    return added


def _logger(config: TrainConfig, run_dir: Path) -> Logger | None:
    backend = config.logger.backend
    if backend == "none":
        return None
    if backend == "tensorboard":
        try:
            import tensorboard  # noqa: F401
        except ImportError as exc:
            raise Sim4EndoRError(
                "logger.backend=tensorboard needs TensorBoard: pip install 'sim4endor[tensorboard]'"
                " (or use logger.backend=csv)."
            ) from exc
        from torchrl.record.loggers.tensorboard import TensorboardLogger

        return TensorboardLogger(exp_name="logs", log_dir=str(run_dir))
    from torchrl.record.loggers.csv import CSVLogger

    return CSVLogger(exp_name="logs", log_dir=str(run_dir))


def make_collector(
    config: TrainConfig, make_env: EnvFactory, agent: Agent, frames_done: int
) -> BaseCollector:
    """Returns the collector of the frames still to collect: one env, K worker processes, or
    (``collector.backend=ray``) K Ray actors."""
    collector_cfg = config.collector
    remaining = max(collector_cfg.total_frames - frames_done, 0)
    budget = {
        "frames_per_batch": collector_cfg.frames_per_batch,
        "total_frames": remaining,
        "init_random_frames": max(collector_cfg.init_random_frames - frames_done, 0),
    }
    # Offsetting the seed by the frames already done keeps a resumed run deterministic.
    seed = config.seed + frames_done
    create = [_SeededEnv(make_env, seed + i) for i in range(config.env.num_envs)]
    # Our policies need no env transforms (e.g. InitTracker); say so, silencing a warning.
    local: dict[str, Any] = {**budget, "auto_register_policy_transforms": False}
    collector: BaseCollector
    if collector_cfg.backend == "ray":
        collector = ray_backend.ray_collector(create, agent.exploration_policy, **budget)
    elif config.env.num_envs == 1:
        collector = Collector(create[0], agent.exploration_policy, **local)
    else:
        # num_threads: torchrl would give the learner max(1, threads - workers) instead.
        collector = MultiSyncCollector(
            create, agent.exploration_policy, num_threads=config.torch_threads, **local
        )
    collector.set_seed(seed)
    return collector


@dataclasses.dataclass(frozen=True)
class _SeededEnv:
    """Picklable ``() -> env`` for collector workers."""

    make_env: EnvFactory
    seed: int

    def __call__(self) -> Any:
        return self.make_env(self.seed)


class _Loop:
    """State of one training run between batches."""

    def __init__(
        self,
        config: TrainConfig,
        run_dir: Path,
        agent: Agent,
        replay: TensorDictReplayBuffer | None,
        logger: Logger | None,
        eval_env: Any,
    ) -> None:
        self.config = config
        self.run_dir = run_dir
        self.agent = agent
        self.replay = replay
        self.logger = logger
        self.eval_env = eval_env
        self.keys = EpisodeKeys()
        # The latest deterministic evaluation's success, shown on the progress bar.
        self.last_eval: str | None = None
        # Wall-clock time already added to Progress.wall_clock_s ends here.
        self.clock = time.monotonic()

    def run(
        self, make_env: EnvFactory, state: checkpoint.Progress, progress: bool
    ) -> checkpoint.Progress:
        cfg = self.config
        if state.frames >= cfg.collector.total_frames:
            return state
        collector = make_collector(cfg, make_env, self.agent, state.frames)
        bar = tqdm(
            total=cfg.collector.total_frames,
            initial=state.frames,
            disable=not progress,
            unit="frames",
            desc=f"{cfg.algorithm} {cfg.env.domain}/{cfg.env.task}",
        )
        # Log lines (each periodic evaluation) go through the bar, so they do not tear it.
        interrupted = False
        try:
            with logging_redirect_tqdm(tqdm_class=tqdm):
                self.clock = time.monotonic()
                for batch in collector:
                    frames = state.frames + batch.numel()
                    state = self._learn(batch, state, frames)
                    self.agent.sync_env_policy()
                    collector.update_policy_weights_()
                    stats = self._log_batch(batch, state)
                    bar.update(batch.numel())
                    bar.set_postfix(stats)
                    self._periodic(state, frames - batch.numel())
        except Exception as exc:
            if not caused_by_interrupt(exc):
                raise
            interrupted = True
        except KeyboardInterrupt:
            interrupted = True
        finally:
            collector.shutdown()
            # A multi-process collector's shutdown hands its workers' threads to this process.
            torch.set_num_threads(cfg.torch_threads)
            bar.close()
        # Also on Ctrl-C: the progress of the last whole batch, so the run resumes from there
        # rather than from its last periodic checkpoint (or from nothing before the first).
        checkpoint.save_checkpoint(self.run_dir, self.agent, state, self.replay)
        if interrupted:
            _LOG.warning("interrupted at %d frames; the same command resumes the run",
                         state.frames)
            raise KeyboardInterrupt
        return state

    def _learn(
        self, batch: TensorDictBase, state: checkpoint.Progress, frames: int
    ) -> checkpoint.Progress:
        cfg = self.config
        flat = batch.reshape(-1)
        if cfg.algorithm == "ppo":
            losses = self._ppo_update(batch)
        else:
            assert self.replay is not None
            self.replay.extend(self.agent.transitions(flat))
            losses = []
            if frames >= cfg.collector.init_random_frames:
                count = cfg.optim.updates_per_batch or flat.numel()
                for _ in range(count):
                    losses.append(self.agent.update(self.replay.sample(), cfg.optim.max_grad_norm))
        if losses and self.logger is not None:
            for key in losses[-1]:
                mean = sum(item[key] for item in losses) / len(losses)
                self.logger.log_scalar(f"train/{key}", mean, step=frames)
        done = int(flat["next", "done"].sum())
        now = time.monotonic()
        elapsed, self.clock = now - self.clock, now
        return checkpoint.Progress(
            frames, state.episodes + done, state.updates + len(losses), state.wall_clock_s + elapsed
        )

    def _ppo_update(self, batch: TensorDictBase) -> list[dict[str, float]]:
        ppo = self.config.ppo
        assert self.agent.advantage is not None
        # GAE runs along time (the last batch dim) before several envs' batches are flattened.
        with torch.no_grad():
            batch = self.agent.advantage(batch.to(self.agent.device))
        flat = self.agent.transitions(batch.reshape(-1))
        losses = []
        for _ in range(ppo.epochs):
            for index in torch.randperm(flat.numel()).split(ppo.minibatch_size):
                losses.append(self.agent.update(flat[index], self.config.optim.max_grad_norm))
        return losses

    def _log_batch(self, batch: TensorDictBase, state: checkpoint.Progress) -> dict[str, Any]:
        nxt = batch["next"].reshape(-1)
        done = nxt["done"].reshape(-1)
        finished = nxt[done]
        stats: dict[str, Any] = {"episodes": state.episodes}
        scalars: dict[str, float] = {"train/reward": float(nxt["reward"].mean())}
        for key in nxt.keys():
            if isinstance(key, str) and key.startswith("reward_"):
                scalars[f"train/{key}"] = float(nxt[key].float().mean())
        if len(finished):  # not numel(): an empty TensorDict reports numel() == 1
            scalars["train/episode_reward"] = float(finished["episode_reward"].mean())
            success = success_fraction(finished, self.keys)
            if success is not None:
                scalars["train/success_rate"] = success
                # Exploring policy, this batch's finished episodes only: not the evaluation.
                stats["batch_success"] = f"{success:.0%}"
        if self.last_eval is not None:
            stats["eval_success"] = self.last_eval
        if self.logger is not None:
            for name, value in scalars.items():
                self.logger.log_scalar(name, value, step=state.frames)
        return stats

    def _periodic(self, state: checkpoint.Progress, frames_before: int) -> None:
        cfg = self.config

        def crossed(interval: int) -> bool:
            return interval > 0 and state.frames // interval > frames_before // interval

        if crossed(cfg.eval.interval_frames) and state.frames < cfg.collector.total_frames:
            self.evaluate(state)
        if crossed(cfg.checkpoint_interval_frames):
            checkpoint.save_checkpoint(self.run_dir, self.agent, state, self.replay)

    def evaluate(self, state: checkpoint.Progress, progress: bool = False) -> dict[str, Any]:
        """Evaluates the deterministic policy, logs and appends the metrics; returns them.
        ``progress``: a bar of its own (the periodic ones show on the training bar)."""
        cfg = self.config
        episodes = rollout_episodes(
            self.eval_env,
            self.agent.env_actor,
            trials=cfg.eval.trials,
            max_steps=cfg.eval.max_steps,
            seed=cfg.seed + EVAL_SEED_OFFSET,
            keys=self.keys,
            progress=progress,
        )
        metrics = evaluation_record(state, episodes)
        self.last_eval = f"{round(metrics['success_rate'] * len(episodes))}/{len(episodes)}"
        # A headless job's log gets a readable line per evaluation beside the progress bar.
        _LOG.info(
            "%s: evaluation at %d/%d frames: %s",
            self.run_dir.name,
            state.frames,
            cfg.collector.total_frames,
            describe(metrics),
        )
        if self.logger is not None:
            for key, value in metrics.items():
                if key == "outcomes":  # counts per outcome: one curve each
                    for outcome, count in value.items():
                        self.logger.log_scalar(f"eval/outcome_{outcome}", count, step=state.frames)
                elif key != "frames" and value is not None:
                    self.logger.log_scalar(f"eval/{key}", float(value), step=state.frames)
        path = self.run_dir / EVALUATIONS_FILE
        previous = path.read_text() if path.is_file() else ""
        atomic_write_text(path, previous + strict_json.dumps(metrics) + "\n")
        if cfg.eval.keep_weights:
            self._save_weights(self.run_dir / EVALUATED_DIR / str(state.frames), state, metrics)
        self._keep_if_best(state, metrics)
        return metrics

    def _save_weights(self, folder: Path, state: checkpoint.Progress,
                      metrics: dict[str, Any]) -> None:
        """Writes the current weights as a run folder of their own (no replay), with the
        evaluation ``metrics`` that judged them; replaces ``folder`` atomically."""
        with atomic_directory(folder) as staging:
            save_config(self.config, staging / CONFIG_FILE)
            checkpoint.save_checkpoint(staging, self.agent, state, None)
            _write_metrics(staging / SELECTION_FILE, metrics)

    def _keep_if_best(self, state: checkpoint.Progress, metrics: dict[str, Any]) -> None:
        """Replaces ``best/`` with the current weights if ``metrics`` beat its evaluation."""
        best = self.run_dir / BEST_DIR
        # Read back from the folder, so a resumed run compares with its earlier best; not its
        # evaluation.json, which `sim4endor evaluate RUN/best` rewrites with other episodes.
        saved = best / SELECTION_FILE
        if saved.is_file() and _rank(json.loads(saved.read_text())) >= _rank(metrics):
            return
        self._save_weights(best, state, metrics)
        _LOG.info("%s: the best evaluation so far; its weights are in %s", self.run_dir.name, best)

    def final_evaluation(self, state: checkpoint.Progress, progress: bool) -> dict[str, Any]:
        # Minutes on a coronary task: shown as evaluate shows it, not as a silent pause.
        metrics = self.evaluate(state, progress)
        write_final_evaluation(self.run_dir, metrics)
        return metrics
