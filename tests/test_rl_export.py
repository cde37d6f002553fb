"""Policy export: the TorchScript (and ONNX) policy equals the evaluated deterministic actor."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from rl_testing import pendulum_env, tiny_config
from tensordict import TensorDict
from torchrl.envs import ExplorationType, set_exploration_type

from sim4endor.rl.config import ALGORITHMS
from sim4endor.rl.export import export_policy
from sim4endor.rl.runs import load_agent
from sim4endor.rl.trainer import train


def _reference(run_dir: Path, observation: torch.Tensor) -> torch.Tensor:
    _, agent = load_agent(run_dir, pendulum_env)
    td = TensorDict({"observation": observation}, batch_size=observation.shape[:-1])
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        return agent.actor(td)["action"]


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_torchscript_policy_matches_the_actor(algorithm: str, tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    train(tiny_config(algorithm), run_dir, make_env=pendulum_env, progress=False)
    paths = export_policy(run_dir, tmp_path / "export", make_env=pendulum_env)
    policy = torch.jit.load(str(paths[0]))
    observation = torch.randn(16, 3)
    action = policy(observation)
    assert action.shape == (16, 1)
    assert torch.allclose(action, _reference(run_dir, observation), atol=1e-6)
    assert policy(torch.randn(3)).shape == (1,)  # unbatched input
    assert (action.abs() <= 2.0).all()  # Pendulum's action bounds
    contract = json.loads(paths[1].read_text())
    assert contract["algorithm"] == algorithm


def test_onnx_policy_matches_the_actor(tmp_path: Path) -> None:
    pytest.importorskip("onnxscript", reason="ONNX export needs the onnx/onnxscript packages")
    from onnx.reference import ReferenceEvaluator

    run_dir = tmp_path / "run"
    train(tiny_config("sac"), run_dir, make_env=pendulum_env, progress=False)
    paths = export_policy(run_dir, tmp_path / "export", onnx=True, make_env=pendulum_env)
    observation = torch.randn(5, 3)
    (action,) = ReferenceEvaluator(str(paths[-1])).run(None, {"observation": observation.numpy()})
    expected = _reference(run_dir, observation).numpy()
    assert action.shape == expected.shape
    assert abs(action - expected).max() < 1e-5
    # One self-contained file: nothing hidden beside it (a temp-named weights file was, until
    # 2026-12-06), so a plain copy of the folder's files runs on the robot's computer.
    export = tmp_path / "export"
    assert sorted(p.name for p in export.iterdir()) == ["policy.json", "policy.onnx", "policy.pt"]
    robot = tmp_path / "robot"
    robot.mkdir()
    shutil.copy(export / "policy.onnx", robot / "policy.onnx")
    (copied,) = ReferenceEvaluator(str(robot / "policy.onnx")).run(
        None, {"observation": observation.numpy()})
    assert (copied == action).all()


ROBOT_SCRIPT = Path(__file__).resolve().parents[1] / "experiments/export/run_onnx_policy.py"


def _robot_script(args: list[str], cwd: Path, block_onnxruntime: bool
                  ) -> subprocess.CompletedProcess[str]:
    """Runs the robot-side example from ``cwd`` (not the repository), optionally as on a
    machine without onnxruntime."""
    block = "sys.modules['onnxruntime'] = None; " if block_onnxruntime else ""
    code = (f"import runpy, sys; {block}sys.argv = [{str(ROBOT_SCRIPT)!r}, *{args!r}]; "
            f"runpy.run_path({str(ROBOT_SCRIPT)!r}, run_name='__main__')")
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True,
                          text=True, check=False)


def test_the_robot_example_runs_from_anywhere_and_names_what_is_missing(tmp_path: Path) -> None:
    done = _robot_script([str(tmp_path / "export")], tmp_path, block_onnxruntime=True)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "needs onnxruntime: pip install onnxruntime" in done.stderr
    done = _robot_script([str(tmp_path / "export")], tmp_path, block_onnxruntime=False)
    assert done.returncode == 2 and "policy.json" in done.stderr and "--onnx" in done.stderr
