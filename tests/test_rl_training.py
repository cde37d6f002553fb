"""The training loop of each algorithm on a tiny budget (Pendulum-v1): outputs, resume,
determinism, checkpoints loadable with weights_only=True."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pytest
import torch
from rl_testing import pendulum_env, tiny_config

from sim4endor.rl import baselines, checkpoint
from sim4endor.rl.config import ALGORITHMS
from sim4endor.rl.envs import sim4endor_env
from sim4endor.rl.runs import evaluate_run, load_agent
from sim4endor.rl.trainer import DEMO_SEED_OFFSET, RunDirError, _Loop, train


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_each_algorithm_trains_end_to_end(
    algorithm: str, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    config = tiny_config(algorithm)
    with caplog.at_level(logging.INFO, logger="sim4endor.rl.trainer"):
        metrics = train(config, tmp_path, make_env=pendulum_env, progress=False)
    assert metrics["frames"] == 200
    assert metrics["trials"] == 2
    assert (tmp_path / "config.yaml").is_file()
    assert json.loads((tmp_path / "evaluation.json").read_text()) == metrics
    evaluations = (tmp_path / "evaluations.jsonl").read_text().splitlines()
    assert [json.loads(line)["frames"] for line in evaluations] == [100, 200]
    # Pendulum has no target: every evaluation episode runs to the step limit.
    assert [r.getMessage() for r in caplog.records if "evaluation at" in r.getMessage()] == [
        f"{tmp_path.name}: evaluation at {frames}/200 frames: 0/2 successes (timeout 2)"
        for frames in (100, 200)
    ]
    scalars = tmp_path / "logs" / "scalars"
    assert (scalars / "eval" / "success_rate.csv").is_file()
    assert (scalars / "train" / "reward.csv").is_file()
    progress = checkpoint.load_progress(tmp_path)
    assert progress.frames == 200
    if algorithm == "ppo":  # two batches of 100 frames, 2 epochs of 2 minibatches each
        assert progress.updates == 2 * 2 * 2
    else:  # learning starts once the 100 random frames are stored: 2 batches × 20 updates
        assert progress.updates == 2 * 20


def test_checkpoint_files_load_with_weights_only(tmp_path: Path) -> None:
    train(tiny_config("sac"), tmp_path, make_env=pendulum_env, progress=False)
    folder = tmp_path / checkpoint.CHECKPOINT_DIR
    state = torch.load(folder / checkpoint.STATE_FILE, weights_only=True)
    assert set(state) == {"agent", "progress", "torch_rng"}
    replay = torch.load(folder / checkpoint.REPLAY_FILE, weights_only=True)
    assert replay["observation"].shape == (200, 3)


def test_ddpg_target_networks_trail_the_online_networks(tmp_path: Path) -> None:
    train(tiny_config("ddpg"), tmp_path, make_env=pendulum_env, progress=False)
    _, agent = load_agent(tmp_path, pendulum_env)
    online = agent.loss.value_network_params.flatten_keys()
    target = agent.loss.target_value_network_params.flatten_keys()
    weights = [key for key in online.keys() if online[key].requires_grad]  # not buffers
    assert weights
    for key in weights:
        assert not torch.equal(online[key], target[key]), key  # soft updates, not copies


def test_same_seed_gives_identical_weights(tmp_path: Path) -> None:
    weights = []
    for name in ("a", "b"):
        train(tiny_config("ddpg"), tmp_path / name, make_env=pendulum_env, progress=False)
        _, agent = load_agent(tmp_path / name, pendulum_env)
        weights.append(torch.cat([p.detach().flatten() for p in agent.loss.parameters()]))
    assert torch.equal(weights[0], weights[1])


def test_resume_continues_from_the_checkpoint(tmp_path: Path) -> None:
    train(tiny_config("ddpg"), tmp_path, make_env=pendulum_env, progress=False)
    first = checkpoint.load_progress(tmp_path)
    longer = tiny_config("ddpg", "collector.total_frames=300")
    metrics = train(longer, tmp_path, make_env=pendulum_env, progress=False)
    resumed = checkpoint.load_progress(tmp_path)
    assert metrics["frames"] == 300
    assert resumed.updates == first.updates + 20
    assert resumed.wall_clock_s > first.wall_clock_s
    replay = torch.load(tmp_path / "checkpoint" / "replay.pt", weights_only=True)
    assert replay["observation"].shape[0] == 300  # the resumed buffer kept the first 200


def _best_line(run_dir: Path) -> dict[str, object]:
    """The periodic evaluation ``best/`` should hold: the first of the highest-ranked."""
    lines = [json.loads(line) for line in (run_dir / "evaluations.jsonl").read_text().splitlines()]
    return max(lines, key=lambda m: (m["success_rate"], m["spl"], m["mean_return"]))


def test_best_keeps_the_weights_of_the_best_evaluation(tmp_path: Path) -> None:
    train(tiny_config("sac"), tmp_path, make_env=pendulum_env, progress=False)
    best = tmp_path / "best"
    expected = _best_line(tmp_path)
    assert json.loads((best / "selection.json").read_text()) == expected
    assert checkpoint.load_progress(best).frames == expected["frames"]
    assert not (best / "checkpoint" / "replay.pt").exists()
    assert not (tmp_path / "evaluated").exists()  # eval.keep_weights is opt-in
    # best/ is a run folder: evaluating it replays the same episodes with the same return.
    again = evaluate_run(best, trials=2, make_env=pendulum_env, record=False)
    assert again["mean_return"] == pytest.approx(expected["mean_return"])


def test_keep_weights_keeps_every_evaluated_checkpoint(tmp_path: Path) -> None:
    train(tiny_config("sac", "eval.keep_weights=true"), tmp_path, make_env=pendulum_env,
          progress=False)
    lines = [json.loads(line) for line in (tmp_path / "evaluations.jsonl").read_text().splitlines()]
    kept = tmp_path / "evaluated"
    assert sorted(p.name for p in kept.iterdir()) == sorted(str(m["frames"]) for m in lines)
    for metrics in lines:
        folder = kept / str(metrics["frames"])
        assert json.loads((folder / "selection.json").read_text()) == metrics
        assert checkpoint.load_progress(folder).frames == metrics["frames"]
        assert not (folder / "checkpoint" / "replay.pt").exists()
        # Each is a run folder whose weights give back the episodes that judged them.
        again = evaluate_run(folder, trials=2, make_env=pendulum_env, record=False)
        assert again["mean_return"] == pytest.approx(metrics["mean_return"])
    best = json.loads((tmp_path / "best" / "selection.json").read_text())
    assert (kept / str(best["frames"]) / "selection.json").read_text() == (
        tmp_path / "best" / "selection.json").read_text()
    # Keeping weights changes no weights: the run resumes with it turned off.
    train(tiny_config("sac", "collector.total_frames=300"), tmp_path, make_env=pendulum_env,
          progress=False)
    assert sorted(p.name for p in kept.iterdir()) == sorted(str(m["frames"]) for m in lines)


def test_a_resumed_run_compares_with_its_earlier_best(tmp_path: Path) -> None:
    train(tiny_config("ddpg"), tmp_path, make_env=pendulum_env, progress=False)
    train(tiny_config("ddpg", "collector.total_frames=400"), tmp_path, make_env=pendulum_env,
          progress=False)
    expected = _best_line(tmp_path)
    assert json.loads((tmp_path / "best" / "selection.json").read_text()) == expected


def test_a_saved_best_without_a_finite_return_ranks_lowest(tmp_path: Path) -> None:
    # A diverged episode's NaN return is saved as null (sim4endor._json).
    train(tiny_config("ddpg"), tmp_path, make_env=pendulum_env, progress=False)
    selection = tmp_path / "best" / "selection.json"
    saved = json.loads(selection.read_text())
    selection.write_text(json.dumps({**saved, "mean_return": None}))
    train(tiny_config("ddpg", "collector.total_frames=300"), tmp_path, make_env=pendulum_env,
          progress=False)
    last = json.loads((tmp_path / "evaluations.jsonl").read_text().splitlines()[-1])
    assert json.loads(selection.read_text()) == last


def test_a_different_config_in_the_run_folder_is_refused(tmp_path: Path) -> None:
    train(tiny_config("ddpg"), tmp_path, make_env=pendulum_env, progress=False)
    with pytest.raises(RunDirError, match="different configuration"):
        train(tiny_config("ddpg", "optim.lr=0.1"), tmp_path, make_env=pendulum_env)


def test_evaluate_run_rewrites_the_evaluation(tmp_path: Path) -> None:
    final = train(tiny_config("ppo"), tmp_path, make_env=pendulum_env, progress=False)
    metrics = evaluate_run(tmp_path, trials=3, make_env=pendulum_env)
    assert metrics["trials"] == 3
    assert json.loads((tmp_path / "evaluation.json").read_text())["trials"] == 3
    # The same keys as the trainer's own final evaluation, training time included.
    assert set(metrics) == set(final)
    assert metrics["train_wall_clock_s"] == final["train_wall_clock_s"] > 0


@pytest.mark.slow  # worker processes start in ~30 s on the shared machine
def test_several_envs_use_a_multi_process_collector(tmp_path: Path) -> None:
    config = tiny_config("sac", "env.num_envs=2")
    metrics = train(config, tmp_path, make_env=pendulum_env, progress=False)
    assert metrics["frames"] == 200


def test_tensorboard_logger_writes_event_files(tmp_path: Path) -> None:
    pytest.importorskip("tensorboard", reason="the tensorboard extra is not installed")
    config = tiny_config("ddpg", "logger.backend=tensorboard", "collector.total_frames=100")
    train(config, tmp_path, make_env=pendulum_env, progress=False)
    assert list((tmp_path / "logs").glob("events.out.tfevents.*"))


def test_demonstrations_put_the_experts_episodes_in_the_replay_first(tmp_path: Path) -> None:
    config = tiny_config("sac", "env.domain=simplified_phantom", "env.task=task_a",
                         "network.observation_scale=null", "demonstrations.episodes=2")
    metrics = train(config, tmp_path, progress=False)
    assert metrics["frames"] == 200  # the expert's steps are not collected frames
    replay = torch.load(tmp_path / "checkpoint" / "replay.pt", weights_only=True)
    # eval.max_steps (20) caps each expert episode, as it caps an evaluation episode.
    assert replay["action"].shape[0] == 2 * 20 + 200
    env = sim4endor_env(config.env, config.seed + DEMO_SEED_OFFSET)
    expert = env.rollout(20, baselines.policy(baselines.ScriptedExpert(), env),
                         break_when_any_done=True)
    env.close()
    assert torch.equal(replay["action"][:20], expert["action"])
    assert torch.equal(replay["next"]["reward"][:20], expert["next", "reward"])


@pytest.mark.parametrize("wrapped", [False, True])
def test_ctrl_c_saves_a_checkpoint_the_same_command_resumes(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, wrapped: bool) -> None:
    # A Ctrl-C after the first batch, as it arrives: plain, or turned by a library into another
    # error raised while the interrupt unwound (TorchRL's collector: a RuntimeError).
    learn = _Loop._learn
    calls = []

    def interrupted(self: _Loop, batch: object, state: checkpoint.Progress, frames: int
                    ) -> checkpoint.Progress:
        calls.append(frames)
        if len(calls) == 2:
            if not wrapped:
                raise KeyboardInterrupt
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt:
                # Implicitly chained, as the library does: the interrupt is its __context__.
                raise RuntimeError(  # noqa: B904
                    "Converting a tensordict to boolean value is not permitted")
        return learn(self, batch, state, frames)  # type: ignore[arg-type]

    monkeypatch.setattr(_Loop, "_learn", interrupted)
    config = tiny_config("ddpg", "collector.total_frames=300")
    with pytest.raises(KeyboardInterrupt):
        train(config, tmp_path, make_env=pendulum_env, progress=False)
    saved = checkpoint.load_progress(tmp_path)
    assert saved.frames == calls[0] > 0  # the last whole batch, before any periodic checkpoint
    monkeypatch.setattr(_Loop, "_learn", learn)
    metrics = train(config, tmp_path, make_env=pendulum_env, progress=False)
    assert metrics["frames"] == 300


def test_out_refuses_a_folder_that_is_not_a_run(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("a user's own file")
    with pytest.raises(RunDirError, match=r"not empty and not a run folder.*notes\.txt"):
        train(tiny_config("ddpg"), tmp_path, make_env=pendulum_env, progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]  # nothing added
