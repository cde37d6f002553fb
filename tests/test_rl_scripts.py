"""Each algorithm's experiments/ script, the `train`/`evaluate` commands and the notebook run
end to end on the simplified phantom with tiny budgets (a real smoke test of the stack)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from script_helpers import load_script

from sim4endor.rl.config import ALGORITHMS, TrainConfig

REPO = Path(__file__).resolve().parents[1]
# Enough frames for a random warm-up, a few updates, an evaluation and a checkpoint.
TINY = [
    "collector.total_frames=40",
    "collector.frames_per_batch=20",
    "collector.init_random_frames=20",
    "optim.updates_per_batch=5",
    "ppo.epochs=1",
    "ppo.minibatch_size=20",
    "network.hidden_sizes=[16]",
    "replay.size=100",
    "eval.trials=1",
    "eval.max_steps=10",
    "eval.interval_frames=0",
]


@pytest.fixture(scope="module")
def phantom() -> str:
    """The shipped simplified phantom; skips when its vessel folder has not been built."""
    from sim4endor import vessels

    if "simplified_phantom" not in vessels.names():
        pytest.skip("vessels/simplified_phantom is not built (sim4endor vessel generate ...)")
    return "simplified_phantom"


def _small_sac(phantom: str) -> TrainConfig:
    """SAC on ``phantom`` with a 16-unit network: quick to build and to train in a test."""
    from sim4endor.rl.config import apply_overrides, default_config

    return apply_overrides(default_config("sac"), [f"env.domain={phantom}",
                                                   "network.hidden_sizes=[16]"])


def _run(args: list[str], **kwargs) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *args], cwd=REPO, capture_output=True, text=True, check=False, **kwargs
    )


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_experiment_script_runs(algorithm: str, phantom: str, tmp_path: Path) -> None:
    result = _run([f"experiments/{algorithm}/train.py", "--out", str(tmp_path), *TINY])
    assert result.returncode == 0, result.stderr[-3000:]
    metrics = json.loads(result.stdout.strip().splitlines()[-1])
    assert metrics["frames"] == 40 and metrics["trials"] == 1
    assert (tmp_path / "checkpoint" / "state.pt").is_file()


def test_train_then_evaluate_commands(phantom: str, tmp_path: Path) -> None:
    sets = [arg for item in TINY for arg in ("--set", item)]
    train = _run(
        ["-m", "sim4endor", "train", "ddpg", "--domain", phantom, "--task", "task_b",
         "--reward", "euclidean", "--seed", "3", "--no-progress", "--out", str(tmp_path), *sets]
    )
    assert train.returncode == 0, train.stderr[-3000:]
    evaluate = _run(["-m", "sim4endor", "evaluate", str(tmp_path), "--trials", "2", "--json"])
    assert evaluate.returncode == 0, evaluate.stderr[-3000:]
    metrics = json.loads(evaluate.stdout)
    for key in ("success_rate", "mean_completion_time_s", "mean_path_length_m", "spl",
                "max_wall_force_n"):
        assert key in metrics
    assert metrics["trials"] == 2
    assert metrics["mean_path_length_m"] > 0.0  # the tip moved
    saved = (tmp_path / "config.yaml").read_text()
    assert "task: task_b" in saved and "reward: euclidean" in saved and "seed: 3" in saved


def test_notebook_executes(phantom: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import nbformat
    from nbclient import NotebookClient

    notebook = nbformat.read(REPO / "experiments/notebooks/train_sac_task_a.ipynb", as_version=4)
    # The kernel inherits these: a tiny budget and a temporary output folder.
    monkeypatch.setenv("SIM4ENDOR_NOTEBOOK_FRAMES", "40")
    monkeypatch.setenv("SIM4ENDOR_NOTEBOOK_TRIALS", "1")
    monkeypatch.setenv("SIM4ENDOR_NOTEBOOK_OUT", str(tmp_path))
    NotebookClient(notebook, timeout=600, resources={"metadata": {"path": str(REPO)}}).execute()
    assert (tmp_path / "policy.pt").is_file()
    assert (tmp_path / "learning_curves.png").is_file()
    assert (tmp_path / "episode.mp4").stat().st_size > 0


def test_extra_observations_reach_the_environment(phantom: str) -> None:
    from sim4endor.rl.config import EnvConfig
    from sim4endor.rl.envs import env_factory

    env = env_factory(EnvConfig(domain=phantom, extra_observations=("rotation",)))(0)
    try:
        assert env.observation_spec["observation"].shape == (7,)
    finally:
        env.close()


def test_a_widened_checkpoint_acts_and_values_as_before_whatever_the_new_entry(
        tmp_path: Path) -> None:
    """experiments/generalist/widen_checkpoint.py appends zero-weight input columns: the
    widened SAC actor and critics compute what the old ones did, for any value of the
    appended ``stall_time``, and the result loads into a run of the wider set."""
    import torch
    from tensordict import TensorDict
    from torchrl.data import Bounded, Composite, Unbounded

    from sim4endor.rl.algorithms import build_agent
    from sim4endor.rl.checkpoint import Progress, load_checkpoint, save_checkpoint
    from sim4endor.rl.config import apply_overrides, default_config

    script = load_script("experiments/generalist/widen_checkpoint.py")

    action_spec = Bounded(-1.0, 1.0, shape=(2,))

    def agent(observations: str):
        config = apply_overrides(default_config("sac"), [f"env.observations={observations}",
                                                         "network.hidden_sizes=[16]"])
        dim = len(config.observation_scale())
        built = build_agent(config, Composite(observation=Unbounded(shape=(dim,))),
                            action_spec)
        return built, dim

    old, old_dim = agent("generalist_no_radius")
    save_checkpoint(tmp_path / "old", old, Progress(frames=7), None)
    state = torch.load(tmp_path / "old/checkpoint/state.pt", weights_only=True)
    (tmp_path / "new/checkpoint").mkdir(parents=True)
    torch.save(script.widen_state(state, [0.2]), tmp_path / "new/checkpoint/state.pt")
    new, new_dim = agent("generalist_stall")
    assert new_dim == old_dim + 1
    assert load_checkpoint(tmp_path / "new", new) == Progress(frames=7)

    torch.manual_seed(0)
    observation = torch.randn(5, old_dim)
    action = torch.rand(5, 2) * 2 - 1

    def outputs(built, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        loss = built.loss
        actor = TensorDict({"observation": obs}, batch_size=[5])
        with loss.actor_network_params.to_module(loss.actor_network):
            loc = loss.actor_network(actor)["loc"]
        critic = TensorDict({"observation": obs, "action": action}, batch_size=[5])
        with loss.qvalue_network_params[1].to_module(loss.qvalue_network):
            value = loss.qvalue_network(critic)["state_action_value"]
        return loc, value

    before = outputs(old, observation)
    for stall in (0.0, 1.5, 5.0):
        wider = torch.cat([observation, torch.full((5, 1), stall)], dim=-1)
        for was, now in zip(before, outputs(new, wider), strict=True):
            torch.testing.assert_close(now, was)
