"""Reading a finished (or interrupted) run folder back: its config, agent and evaluation."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from torchrl.envs import EnvBase

from sim4endor.rl import checkpoint
from sim4endor.rl.algorithms import Agent, build_agent
from sim4endor.rl.config import EnvConfig, TrainConfig, load_config
from sim4endor.rl.envs import EnvFactory, env_factory
from sim4endor.rl.evaluation import rollout_episodes
from sim4endor.rl.trainer import (
    CONFIG_FILE,
    EVAL_SEED_OFFSET,
    EVALUATION_FILE,
    RunDirError,
    evaluation_record,
    write_final_evaluation,
)


def run_config(run_dir: Path) -> TrainConfig:
    """Returns the config saved in ``run_dir``.

    Raises:
        RunDirError: when ``run_dir`` is not a run folder.
    """
    path = Path(run_dir) / CONFIG_FILE
    if not path.is_file():
        raise RunDirError(
            f"{run_dir} is not a training run folder (no {CONFIG_FILE}); pass the --out folder "
            "of `sim4endor train`."
        )
    return load_config(path)


def load_agent(run_dir: Path, make_env: EnvFactory | None = None) -> tuple[TrainConfig, Agent]:
    """Rebuilds the agent of ``run_dir`` from its config and latest checkpoint."""
    config = run_config(run_dir)
    env = (make_env or env_factory(config.env, evaluation=True))(
        config.seed + EVAL_SEED_OFFSET
    )
    try:
        return config, load_agent_for(run_dir, config, env)
    finally:
        env.close()


def load_agent_for(run_dir: Path, config: TrainConfig, env: EnvBase) -> Agent:
    """The run's latest agent, its networks sized by ``env``'s specs."""
    agent = build_agent(config, env.observation_spec, env.action_spec)
    checkpoint.load_checkpoint(run_dir, agent)
    return agent


def evaluate_run(
    run_dir: Path,
    *,
    trials: int = 10,
    seed: int | None = None,
    max_steps: int | None = None,
    make_env: EnvFactory | None = None,
    task_arguments: Mapping[str, Any] | None = None,
    progress: bool = False,
    record: bool = True,
) -> dict[str, Any]:
    """Evaluates the latest policy of ``run_dir`` and writes ``evaluation.json`` there.

    With ``task_arguments`` (e.g. another vessel, wire or tree pool: a generalisation test)
    the metrics are only returned: ``evaluation.json`` stays the run's own task's.

    Args:
        run_dir: a folder written by :func:`sim4endor.rl.trainer.train`.
        trials: episodes to run.
        seed: evaluation seed; defaults to the run's seed + ``EVAL_SEED_OFFSET`` (the seed
            of the periodic evaluations during training).
        max_steps: step cap per episode; defaults to the run's ``eval.max_steps``.
        make_env: ``seed -> env`` factory; defaults to the run's sim4endor task (its
            evaluation split).
        task_arguments: :class:`~sim4endor.rl.config.EnvConfig` fields replacing the run's
            (``domain``, ``task``, ``vessel``, ``target``, ``wire``, ``pool_seed``, ...).
        progress: show a progress bar over the episodes.
        record: write ``evaluation.json`` (never for a shipped policy: its folder is part of
            the installed package).

    Returns:
        The metrics of :func:`sim4endor.rl.metrics.summarize` plus ``frames`` and
        ``train_wall_clock_s`` (from the checkpoint).
    """
    config = run_config(run_dir)
    seed = config.seed + EVAL_SEED_OFFSET if seed is None else seed
    env_config = evaluation_env(config.env, task_arguments or {})
    env = (make_env or env_factory(env_config, evaluation=True))(seed)
    try:
        agent = load_agent_for(run_dir, config, env)
        episodes = rollout_episodes(
            env,
            agent.env_actor,
            trials=trials,
            max_steps=max_steps or config.eval.max_steps,
            seed=seed,
            progress=progress,
        )
    finally:
        env.close()
    # The trainer's own record, so a re-evaluation keeps the run's training time in the tables.
    metrics = evaluation_record(checkpoint.load_progress(run_dir), episodes)
    if record and not task_arguments:
        write_final_evaluation(run_dir, metrics)
    return metrics


def read_evaluation(run_dir: Path) -> dict[str, Any] | None:
    """Returns the saved final evaluation of ``run_dir``, or None if it has none yet."""
    path = Path(run_dir) / EVALUATION_FILE
    return json.loads(path.read_text()) if path.is_file() else None


#: The run's anatomy settings: they name trees or a vessel of the run's own domain.
_ANATOMY_FIELDS = ("vessel", "target", "pool_seed", "pool_size", "eval_pool_seed", "anatomy",
                   "vary_wire")


def evaluation_env(run_env: EnvConfig, task_arguments: Mapping[str, Any]) -> EnvConfig:
    """The environment a run is evaluated in: ``task_arguments`` (``EnvConfig`` fields) on top
    of the run's own ``run_env``.

    The run's anatomy settings carry over only where they still name something: on another
    domain none do (a coronary run's tree pool means nothing to a phantom), and trees named
    with ``pool_seed`` are the trees evaluated, not the run's held-out split
    (``eval_pool_seed``), unless that is named too.
    """
    fields = dict(task_arguments)
    if fields.get("domain", run_env.domain) != run_env.domain:
        for name in _ANATOMY_FIELDS:
            fields.setdefault(name, None)
    if "pool_seed" in fields:
        fields.setdefault("eval_pool_seed", None)
    return dataclasses.replace(run_env, **fields)
