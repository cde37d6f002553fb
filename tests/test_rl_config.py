"""Training configuration: the paper's defaults, YAML files, overrides and their errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from sim4endor.rl.config import (
    ALGORITHMS,
    ConfigError,
    apply_overrides,
    default_config,
    load_config,
    save_config,
)

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def test_defaults_are_the_papers_hyper_parameters() -> None:
    config = default_config("ddpg")
    assert config.optim.tau == 0.005
    assert config.optim.lr == 1e-4
    assert config.optim.gamma == 0.99
    assert config.replay.size == 1_000_000
    assert config.optim.batch_size == 100
    assert config.exploration.noise_std == 0.1
    assert config.collector.total_frames == 100_000
    assert config.eval.trials == 10


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_experiment_config_files_match_the_library_defaults(algorithm: str) -> None:
    assert load_config(EXPERIMENTS / algorithm / "config.yaml") == default_config(algorithm)


def test_the_generalist_config_trains_across_held_out_coronary_trees() -> None:
    config = load_config(EXPERIMENTS / "generalist" / "config.yaml")
    assert (config.env.domain, config.env.observations) == ("coronary", "generalist_no_radius")
    assert config.env.eval_pool_seed >= config.env.pool_seed + config.env.pool_size  # held out
    assert len(config.observation_scale()) == 35  # one default factor per number of the set


def test_target_weights_reach_the_training_envs_only() -> None:
    config = apply_overrides(load_config(EXPERIMENTS / "generalist" / "config.yaml"),
                             ["env.target_weights={AM: 3, RV: 3}"])
    assert config.env.target_weights == {"AM": 3.0, "RV": 3.0}
    assert config.env.task_kwargs(0)["target_weights"] == {"AM": 3.0, "RV": 3.0}
    # Evaluations draw uniformly, so their figures compare with runs trained without them.
    assert "target_weights" not in config.env.task_kwargs(0, evaluation=True)
    assert "target_weights" not in default_config("sac").env.task_kwargs(0)


@pytest.mark.parametrize(("override", "message"), [
    ("env.target_weights={A: 1}", "coronary domain's targets; domain 'simplified_phantom'"),
    ("env.target_weights=[AM]", "env.target_weights must be a mapping"),
    ("env.target_weights={AM: -1}", r"env.target_weights must be >= 0, got \{'AM': -1.0\}"),
])
def test_bad_target_weights_name_the_field(override: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        apply_overrides(default_config("sac"), [override])


def test_a_recipe_source_of_wide_trees_reaches_the_coronary_task() -> None:
    from sim4endor.rl.recipe import Source

    policy = load_config(EXPERIMENTS / "generalist" / "config.yaml").env
    env = Source(domain="coronary", pool_seed=300, pool_size=50, anatomy="wide").env(policy)
    assert env.task_kwargs(0)["anatomy"] == "wide"
    # Not named: the policy's own trees (normal ones, which the task draws by default).
    assert "anatomy" not in Source(domain="coronary").env(policy).task_kwargs(0)
    # Another domain drops the run's anatomy, as it drops its tree pool.
    wide = apply_overrides(default_config("sac"), ["env.domain=coronary", "env.anatomy=wide"])
    assert Source(domain="random_coronary").env(wide.env).anatomy is None
    with pytest.raises(ConfigError, match="anatomy chooses the coronary domain's trees"):
        apply_overrides(default_config("sac"), ["env.anatomy=wide"])


def test_overrides_parse_values_as_yaml() -> None:
    config = apply_overrides(
        default_config("sac"),
        ["optim.lr=3e-4", "network.hidden_sizes=[64, 64]", "env.reward=euclidean", "seed=7"],
    )
    assert config.optim.lr == pytest.approx(3e-4)
    assert config.network.hidden_sizes == (64, 64)
    assert config.env.reward == "euclidean"
    assert config.seed == 7
    assert config.optim.gamma == 0.99  # untouched


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("optim.learning_rate=1", "unknown field 'learning_rate'.*'lr'"),
        ("env.reward=cosine", "choose one of"),
        ("collector.total_frames=1.5", "cannot read"),
        ("optim", "section.field=value"),
        ("optim=3", "must be a mapping"),
    ],
)
def test_bad_overrides_name_the_field(override: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        apply_overrides(default_config("ddpg"), [override])


def test_the_ray_backend_needs_batches_that_split_evenly_over_its_workers() -> None:
    assert default_config("sac").collector.backend == "local"
    ray = ["collector.backend=ray", "collector.frames_per_batch=1000"]
    assert apply_overrides(default_config("sac"), [*ray, "env.num_envs=4"]).env.num_envs == 4
    with pytest.raises(ConfigError, match=r"frames_per_batch=1000 evenly over env.num_envs=3"):
        apply_overrides(default_config("sac"), [*ray, "env.num_envs=3"])


def test_unknown_algorithm_lists_the_valid_ones() -> None:
    with pytest.raises(ConfigError, match="ddpg"):
        default_config("td3")


def test_save_and_load_round_trip(tmp_path: Path) -> None:
    config = apply_overrides(default_config("ppo"), ["ppo.epochs=3", "env.task=task_b"])
    save_config(config, tmp_path / "config.yaml")
    assert load_config(tmp_path / "config.yaml") == config


def test_observation_scale_must_match_the_observation() -> None:
    from torchrl.envs import GymEnv

    from sim4endor.rl.algorithms import build_agent

    env = GymEnv("Pendulum-v1")  # 3 observation entries; the default has 6 factors
    with pytest.raises(ConfigError, match=r"observation_scale has 6 factors.*3 entries"):
        build_agent(default_config("ddpg"), env.observation_spec, env.action_spec)


def test_sac_starts_at_the_configured_entropy_temperature() -> None:
    from torchrl.envs import GymEnv

    from sim4endor.rl.algorithms import build_agent

    env = GymEnv("Pendulum-v1")
    config = apply_overrides(default_config("sac"), ["network.observation_scale=[]"])
    agent = build_agent(config, env.observation_spec, env.action_spec)
    assert float(agent.loss.log_alpha.exp()) == pytest.approx(config.sac.alpha_init)


def test_demonstrations_need_a_replay_buffer() -> None:
    with pytest.raises(ConfigError, match="PPO learns on-policy"):
        apply_overrides(default_config("ppo"), ["demonstrations.episodes=3"])


def test_a_recipe_source_of_varied_wires_reaches_the_coronary_task() -> None:
    from sim4endor.rl.recipe import Source

    policy = load_config(EXPERIMENTS / "generalist" / "config.yaml").env
    env = Source(domain="coronary", vary_wire=True).env(policy)
    assert env.task_kwargs(0)["vary_wire"] is True
    assert "vary_wire" not in Source(domain="coronary").env(policy).task_kwargs(0)
    varied = apply_overrides(default_config("sac"), ["env.domain=coronary", "env.vary_wire=true"])
    assert Source(domain="random_coronary").env(varied.env).vary_wire is None
    with pytest.raises(ConfigError, match="vary_wire draws a wire per coronary tree"):
        apply_overrides(default_config("sac"), ["env.vary_wire=true"])
