"""`train --backend ray` (Pendulum-v1): Ray env workers and a learner in this process.

The errors come first: they need no Ray instance, and must see this process unconnected.
The rest share one local two-CPU Ray instance (Ray's core is in the dev extra).
"""

from __future__ import annotations

import socket
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import torch
from rl_testing import pendulum_env, tiny_config
from tensordict import TensorDict

from sim4endor.cli import main
from sim4endor.rl import checkpoint
from sim4endor.rl.algorithms import build_agent
from sim4endor.rl.config import apply_overrides
from sim4endor.rl.ray_backend import RayBackendError
from sim4endor.rl.trainer import make_collector, train

RAY = ("collector.backend=ray", "env.num_envs=2")
#: Batches of 200 frames: each of two workers then ends a 200-step Pendulum episode by the
#: second batch, as one local env does, so both runs log the same scalars.
TWO_BATCHES = (
    "collector.total_frames=400",
    "collector.frames_per_batch=200",
    "collector.init_random_frames=200",
)


def test_without_ray_the_error_says_how_to_install_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    with pytest.raises(RayBackendError, match=r"pip install 'sim4endor\[ray\]'"):
        train(tiny_config("sac", *RAY), tmp_path / "run", make_env=pendulum_env)
    assert not (tmp_path / "run").exists()


def _closed_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.mark.parametrize(
    ("address", "message"),
    [(None, "No Ray cluster answers at 127.0.0.1:"), ("head-node", "is not HOST:PORT")],
)
def test_an_unreachable_ray_address_is_one_line_naming_the_fix(
    address: str | None, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    address = address or f"127.0.0.1:{_closed_port()}"
    out = tmp_path / "run"
    argv = ["train", "sac", "--backend", "ray", "--ray-address", address, "--out", str(out)]
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert message in line and "ray start --head" in line and "--ray-address" in line
    assert not out.exists()


def test_a_ray_address_without_the_ray_backend_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["train", "sac", "--ray-address", "10.0.0.5:6379", "--out", str(tmp_path / "run")]
    assert main(argv) == 2
    assert "add --backend ray" in capsys.readouterr().err


@pytest.fixture(scope="module")
def local_ray() -> Iterator[None]:
    import ray

    ray.init(
        num_cpus=2,  # one per env worker
        object_store_memory=100 * 2**20,  # bounded: batches of a few hundred small frames
        include_dashboard=False,
        log_to_driver=False,
        # Ray workers import the env factory from this folder.
        runtime_env={"env_vars": {"PYTHONPATH": str(Path(__file__).resolve().parent)}},
    )
    yield
    ray.shutdown()


def _files(run_dir: Path) -> set[Path]:
    return {path.relative_to(run_dir) for path in run_dir.rglob("*") if path.is_file()}


@pytest.mark.usefixtures("local_ray")
def test_two_ray_workers_train_resume_and_write_the_local_run_folder(tmp_path: Path) -> None:
    config = tiny_config("sac", *TWO_BATCHES, *RAY)
    metrics = train(config, tmp_path / "ray", make_env=pendulum_env, progress=False)
    assert metrics["frames"] == 400
    assert checkpoint.load_progress(tmp_path / "ray").updates == 2 * 20
    local = tiny_config("sac", *TWO_BATCHES)
    train(local, tmp_path / "local", make_env=pendulum_env, progress=False)
    assert _files(tmp_path / "ray") == _files(tmp_path / "local")
    assert "backend: ray" in (tmp_path / "ray" / "config.yaml").read_text()
    # Rerunning with a larger budget resumes from the checkpoint, as the local backend does.
    longer = apply_overrides(config, ["collector.total_frames=600"])
    assert train(longer, tmp_path / "ray", make_env=pendulum_env, progress=False)["frames"] == 600
    assert checkpoint.load_progress(tmp_path / "ray").updates == 3 * 20


@pytest.mark.usefixtures("local_ray")
def test_the_learners_weights_reach_every_ray_worker() -> None:
    config = tiny_config("ddpg", *RAY)
    env = pendulum_env(0)
    agent = build_agent(config, env.observation_spec, env.action_spec)
    collector = make_collector(config, pendulum_env, agent, frames_done=0)
    try:
        with torch.no_grad():
            for parameter in agent.exploration_policy.parameters():
                parameter.fill_(0.25)
        collector.update_policy_weights_()
        expected = TensorDict.from_module(agent.exploration_policy)
        for remote in collector.get_distant_attr("policy"):
            torch.testing.assert_close(TensorDict.from_module(remote), expected)
    finally:
        collector.shutdown()
