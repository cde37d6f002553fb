"""`sim4endor train generalist`: the shipped recipe's stages, resumed after Ctrl-C, refusing
folders it cannot use; and the imitation pieces it is made of. Tiny budgets throughout."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from sim4endor import assets
from sim4endor.cli import main
from sim4endor.observations import OBSERVATION_SETS, OBSERVATION_UNITS
from sim4endor.rl import checkpoint, imitation, recipe
from sim4endor.rl.config import ConfigError, default_config
from sim4endor.rl.runs import load_agent

# Two demonstrations on the training trees and one on the wide ones, one takeover round;
# short episodes and a few gradient steps. Episodes this short never reach a target, so the
# clone takes every demonstration, failed ones included.
TINY = [
    "--set", "demonstrations=[{domain: coronary, episodes: 2}, "
             "{domain: random_coronary, episodes: 1, pool_seed: 200, pool_size: 40}]",
    "--set", "takeovers=[{domain: coronary, episodes: 1}]",
    "--set", "rounds=1", "--set", "max_steps=40", "--set", "stall_steps=5",
    "--set", "clone.steps=10", "--set", "clone.successful_only=false",
    "--set", "chunk_episodes=1", "--envs", "1", "--no-progress",
]
STAGES = ["demonstrations", "clone", "takeover_1", "finetune_1"]


def _train(out: Path, *extra: str) -> int:
    return main(["train", "generalist", "--out", str(out), *TINY, *extra])


def _actor_weights(run: Path) -> list[torch.Tensor]:
    _, agent = load_agent(run)
    return [p.detach().clone() for p in agent.actor.parameters()]


def _log(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / recipe.LOG_FILE).read_text().splitlines()]


def test_recipe_runs_every_stage_and_writes_a_loadable_policy(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    assert _train(out) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    records = _log(out)
    assert [r["stage"] for r in records] == STAGES
    demos = records[0]
    assert demos["episodes"] == 3 and demos["labels"] == 3 * 40  # every step is the expert's
    assert records[1]["labels"] == [demos["labels"]]
    # The finetune learns from the demonstrations and the round's takeovers, as two groups.
    assert records[3]["labels"] == [demos["labels"], records[2]["labels"]]
    assert summary["policy"] == str(out / recipe.POLICY_DIR)
    assert summary["seconds"] == pytest.approx(sum(r["seconds"] for r in records), abs=0.2)
    config, _ = load_agent(out / recipe.POLICY_DIR)
    assert config.env.tip == "3,75,5,50" and config.env.observations == "generalist_stall"
    for policy, last in zip(_actor_weights(out / recipe.POLICY_DIR),
                            _actor_weights(out / "stages" / "finetune_1"), strict=True):
        assert torch.equal(policy, last)
    # The policy's counters are the whole recipe's, as a SAC run's are its training's: every
    # step of the episodes (the takeover's driven by the policy too), both cloning stages.
    progress = checkpoint.load_progress(out / recipe.POLICY_DIR)
    assert progress.episodes == demos["episodes"] + records[2]["episodes"]
    assert demos["labels"] + records[2]["labels"] <= progress.frames <= 4 * 40
    assert progress.updates == 2 * 10
    assert progress.wall_clock_s == pytest.approx(summary["seconds"], rel=0.05, abs=0.5)
    assert checkpoint.load_progress(out / "stages" / "clone").updates == 10
    # Rerunning a finished run does nothing more.
    assert _train(out) == 0
    assert len(_log(out)) == len(STAGES)


def test_ctrl_c_ends_with_130_and_the_same_command_resumes(tmp_path: Path, monkeypatch,
                                                           capsys) -> None:
    out = tmp_path / "run"
    collect_chunk = recipe._collect_chunk
    calls = []

    def interrupted_after_two(chunk):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(chunk.out)
        return collect_chunk(chunk)

    monkeypatch.setattr(recipe, "_collect_chunk", interrupted_after_two)
    assert _train(out) == 130
    assert "interrupted" in capsys.readouterr().err
    saved = sorted((out / "data").glob("*.npz"))
    assert saved == sorted(calls) and len(saved) == 2
    assert not (out / recipe.LOG_FILE).exists()
    stamps = {path: path.stat().st_mtime_ns for path in saved}

    monkeypatch.setattr(recipe, "_collect_chunk", collect_chunk)
    assert _train(out) == 0
    assert [r["stage"] for r in _log(out)] == STAGES
    # The chunks saved before Ctrl-C were kept, not collected again.
    assert {path: path.stat().st_mtime_ns for path in saved} == stamps
    # The resumed run is the uninterrupted one: the same data, the same weights.
    whole = tmp_path / "whole"
    assert _train(whole) == 0
    for resumed, uninterrupted in zip(_actor_weights(out / recipe.POLICY_DIR),
                                      _actor_weights(whole / recipe.POLICY_DIR), strict=True):
        assert torch.equal(resumed, uninterrupted)


def test_recipe_refuses_a_folder_it_cannot_use(tmp_path: Path, capsys) -> None:
    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("mine")
    assert _train(user) == 2
    assert "is not empty and holds no recipe.yaml" in capsys.readouterr().err
    assert sorted(p.name for p in user.iterdir()) == ["notes.txt"]

    run = tmp_path / "run"
    recipe.RecipeRun(recipe.load_recipe("generalist", ["seed=1"]), run)
    with pytest.raises(recipe.RecipeError, match=r"another recipe \(differs in \['seed'\]\)"):
        recipe.RecipeRun(recipe.load_recipe("generalist", ["seed=2"]), run)
    # The number of workers changes only the speed: a run resumes on a bigger machine.
    recipe.RecipeRun(recipe.load_recipe("generalist", ["seed=1", "envs=16"]), run)


def test_a_folder_from_before_a_new_recipe_field_resumes(tmp_path: Path) -> None:
    """A field the folder's recipe.yaml lacks reads its default; one it differs in refuses."""
    every = recipe.load_recipe("generalist", ["clone.successful_only=false"])  # the field's default
    saved = recipe.recipe_dict(every)
    del saved["clone"]["successful_only"]
    tmp_path.joinpath(recipe.RECIPE_FILE).write_text(yaml.safe_dump(saved))
    recipe.RecipeRun(every, tmp_path, progress=False)
    with pytest.raises(recipe.RecipeError, match=r"differs in \['clone'\]"):
        recipe.RecipeRun(recipe.load_recipe("generalist"), tmp_path, progress=False)


def test_recipe_refuses_flags_it_sets_itself(tmp_path: Path, capsys) -> None:
    assert main(["train", "generalist", "--out", str(tmp_path / "r"), "--tip", "3,75",
                 "--frames", "10"]) == 2
    err = capsys.readouterr().err
    assert "--frames --tip: the generalist recipe sets these itself" in err
    assert main(["train", "generalist", "--out", str(tmp_path / "r"), "--ray-address",
                 "10.0.0.5:6379"]) == 2
    assert "add --backend ray" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


@pytest.fixture
def local_ray() -> Iterator[None]:
    import ray

    ray.init(num_cpus=2, object_store_memory=100 * 2**20, include_dashboard=False,
             log_to_driver=False)
    yield
    ray.shutdown()


@pytest.mark.usefixtures("local_ray")
def test_ray_tasks_collect_what_local_workers_do(tmp_path: Path) -> None:
    """Every chunk a Ray task (the takeover's driver sent with it, not read from a folder the
    task's node may not have): the same data and the same policy as worker processes."""
    assert _train(tmp_path / "ray", "--backend", "ray") == 0
    assert _train(tmp_path / "local") == 0
    assert _log(tmp_path / "ray")[2]["labels"] == _log(tmp_path / "local")[2]["labels"]
    for on_ray, local in zip(_actor_weights(tmp_path / "ray" / recipe.POLICY_DIR),
                             _actor_weights(tmp_path / "local" / recipe.POLICY_DIR),
                             strict=True):
        assert torch.equal(on_ray, local)


def test_shipped_recipe_reads_and_names_bad_fields() -> None:
    shipped = recipe.load_recipe("generalist")
    assert "generalist" in assets.recipe_names()
    assert shipped.policy.algorithm == "sac" and shipped.rounds >= 1
    assert {s.domain for s in shipped.demonstrations} == {"coronary", "random_coronary"}
    assert recipe.load_recipe("generalist", ["seed=7", "clone.steps=3"]).clone.steps == 3
    with pytest.raises(ConfigError, match="unknown field 'stepz'"):
        recipe.load_recipe("generalist", ["clone.stepz=3"])
    with pytest.raises(ConfigError, match="episodes"):
        recipe.load_recipe("generalist", ["demonstrations=[{domain: coronary, episodes: 0}]"])
    with pytest.raises(recipe.RecipeError, match="No recipe named 'nope'"):
        recipe.load_recipe("nope")


def test_the_students_recipe_is_the_generalists_distilled_onto_the_cath_lab() -> None:
    """``base: generalist``: every field the student's recipe file does not name is the
    generalist's; a recipe that leads back to itself is refused by name."""
    student = recipe.load_recipe("student")
    assert student == recipe.load_recipe("generalist", [
        "teacher=generalist", "policy.env.observations=deployable",
        "policy.env.randomise=true"])
    assert recipe.load_recipe("student", ["seed=3"]).seed == 3


def test_a_recipe_based_on_itself_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                             ) -> None:
    for name, base in (("a", "b"), ("b", "a")):
        (tmp_path / name).mkdir()
        (tmp_path / name / assets.RECIPE_FILE).write_text(f"base: {base}\n")
    monkeypatch.setattr(recipe, "policies_dir", lambda: tmp_path)
    monkeypatch.setattr(recipe, "recipe_names", lambda: ("a", "b"))
    with pytest.raises(recipe.RecipeError, match="'a' is based on itself: a -> b -> a"):
        recipe.load_recipe("a")


def test_successful_keeps_the_episodes_that_reached_their_target() -> None:
    episodes = imitation.Episodes(
        observation=np.arange(7.0)[:, None], action=np.arange(14.0).reshape(7, 2),
        expert=np.array([1, 1, 0, 1, 1, 1, 0], bool), episode=np.array([0, 0, 1, 1, 2, 2, 2]),
        success=np.array([False, True, True]))
    kept = episodes.successful()
    np.testing.assert_array_equal(kept.observation[:, 0], [2, 3, 4, 5, 6])
    np.testing.assert_array_equal(kept.episode, [0, 0, 1, 1, 1])
    np.testing.assert_array_equal(kept.success, [True, True])
    np.testing.assert_array_equal(kept.labels[0][:, 0], [3, 4, 5])
    nothing = dataclasses.replace(episodes, success=np.zeros(3, bool)).successful()
    assert len(nothing.observation) == len(nothing.success) == 0


def test_recipe_clones_only_successful_demonstrations_when_asked(tmp_path: Path,
                                                                 capsys) -> None:
    """TINY's 40-step demonstrations never reach a target: with ``successful_only`` the clone
    has nothing to learn from, and says so instead of cloning the failures."""
    out = tmp_path / "run"
    assert _train(out, "--set", "clone.successful_only=true") == 2
    assert "no demonstrations episode reached its target" in capsys.readouterr().err
    assert [r["stage"] for r in _log(out)] == ["demonstrations"]
    assert _log(out)[0]["successes"] == 0


def test_clone_fits_each_group_of_labels() -> None:
    from torchrl.data import Bounded, Composite, Unbounded

    from sim4endor.rl.algorithms import build_agent
    from sim4endor.rl.config import apply_overrides

    config = apply_overrides(default_config("sac"), ["network.observation_scale=[1, 1, 1]"])
    observation_spec = Composite(observation=Unbounded(shape=(3,)))
    agent = build_agent(config, observation_spec, Bounded(-1.0, 1.0, shape=(2,)))
    rng = np.random.default_rng(0)
    # Two groups of very different sizes, each with its own constant label: equal shares of
    # every batch make the small group's label learnt as well as the large one's.
    large = (rng.normal(size=(5000, 3)), np.tile([0.5, -0.5], (5000, 1)))
    small = (rng.normal(size=(50, 3)) + 4.0, np.tile([-0.8, 0.3], (50, 1)))
    error = imitation.clone(agent.actor, [large, small], steps=400, batch=64, lr=3e-3, seed=0)
    assert error < 0.01
    with pytest.raises(ValueError, match="no labelled steps"):
        imitation.clone(agent.actor, [(np.zeros((0, 3)), np.zeros((0, 2)))], steps=1, batch=4,
                        lr=1e-3, seed=0)


def test_the_expert_takes_over_where_the_policy_is_stuck(tmp_path: Path) -> None:
    """A policy that never moves (its actor's output layer zeroed) is stuck from the start, so
    the probing expert takes over after ``stall_steps`` steps and its plan drives; only its
    steps are labels. With no actor the plain expert drives, every step a label."""
    from sim4endor import vessels
    from sim4endor.rl.algorithms import build_agent
    from sim4endor.rl.config import apply_overrides
    from sim4endor.rl.envs import sim4endor_env

    if "simplified_phantom" not in vessels.names():
        pytest.skip("vessels/simplified_phantom is not built (sim4endor vessel generate ...)")
    config = apply_overrides(default_config("sac"), ["env.domain=simplified_phantom",
                                                     "env.task=task_b",
                                                     "network.hidden_sizes=[16]"])
    stall = 4
    env = sim4endor_env(config.env, 0)
    try:
        agent = build_agent(config, env.observation_spec, env.action_spec)
        with torch.no_grad():
            output = agent.actor.module[0].module[0].net[-1]
            output.weight.zero_()
            output.bias.zero_()  # loc 0: the mode is [0, 0], the wire stands still
        taken = imitation.collect(env, agent.env_actor, episodes=1, max_steps=stall + 12,
                                  stall_steps=stall)
        shown = imitation.collect(env, None, episodes=1, max_steps=12)
    finally:
        env.close()
    expert, action = taken.expert, taken.action
    assert len(expert) == stall + 12 and list(taken.episode) == [0] * (stall + 12)
    assert not expert[:stall].any() and expert[stall]  # the policy's first steps, then
    np.testing.assert_array_equal(action[~expert], 0.0)  # the expert's
    assert action[expert][:, 0].max() > 0.0  # it pushes
    observation, label = taken.labels
    assert len(label) == int(expert.sum()) and observation.shape[0] == len(label)
    assert shown.expert.all() and len(shown.expert) == 12 and shown.action[:, 0].max() > 0.0

    path = tmp_path / "chunk.npz"
    taken.save(path)
    loaded = imitation.Episodes.load(path)
    for name in ("observation", "action", "expert", "episode", "success"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(taken, name))


def test_a_teacher_distils_into_a_student_that_sees_what_a_robot_measures(
        tmp_path: Path) -> None:
    """With ``teacher``: the shipped generalist drives the demonstrations and labels every
    state the student drives to in the round; the student reads the deployable set."""
    out = tmp_path / "student"
    assert _train(out, "--set", "teacher=generalist",
                  "--set", "policy.env.observations=deployable") == 0
    records = _log(out)
    assert [r["stage"] for r in records] == STAGES
    assert records[0]["labels"] == 3 * 40 and records[2]["labels"] == 40  # every step
    config, _ = load_agent(out / recipe.POLICY_DIR)
    assert config.env.observations == "deployable"
    demos = imitation.Episodes.load(next((out / "data").glob("demonstrations_0_*.npz")))
    np.testing.assert_array_equal(demos.label, demos.action)  # the teacher drove
    rounds = imitation.Episodes.load(next((out / "data").glob("takeover_1_*.npz")))
    assert rounds.expert.all()
    assert not np.allclose(rounds.label, rounds.action)  # the student drove, the teacher labels
    assert rounds.observation.shape[1] == sum(
        OBSERVATION_UNITS[name][1] for name in OBSERVATION_SETS["deployable"])


def test_a_teacher_must_run_the_students_wire(tmp_path: Path) -> None:
    with pytest.raises(recipe.RecipeError, match=r"another \['tip'\]"):
        recipe.RecipeRun(recipe.load_recipe("generalist", [
            "teacher=generalist", "policy.env.tip=2,45", "rounds=0"]), tmp_path,
            progress=False)._teacher()
    with pytest.raises(recipe.RecipeError, match="neither a shipped policy"):
        recipe.RecipeRun(recipe.load_recipe("generalist", [
            f"teacher={tmp_path / 'nothing'}"]), tmp_path / "run", progress=False)._teacher()
