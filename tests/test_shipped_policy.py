"""The pretrained generalist policy shipped in the package: found by name, loaded weights-only,
acting on an anatomy it was not trained on."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from sim4endor import assets
from sim4endor.cli import render
from sim4endor.rl.checkpoint import CHECKPOINT_DIR, STATE_FILE
from sim4endor.rl.config import EnvConfig
from sim4endor.rl.runs import evaluation_env, run_config


def test_the_generalist_is_shipped_small_and_loads_weights_only() -> None:
    assert "generalist" in assets.policy_names()
    folder = assets.run_or_policy("generalist")
    state = folder / CHECKPOINT_DIR / STATE_FILE
    assert state.stat().st_size < 5 * 2**20  # a few MB at most
    assert not (folder / CHECKPOINT_DIR / "replay.pt").exists()
    torch.load(state, weights_only=True)  # tensors and plain data only: no pickled code
    assert run_config(folder).env.observations == "generalist_stall"
    assert (folder / "MODEL_CARD.md").is_file()


def test_the_generalist_is_its_recipes_policy() -> None:
    """The shipped weights are `sim4endor train generalist`'s: the policy settings are its
    recipe's, on the seed its model card's command names."""
    from sim4endor.rl.recipe import load_recipe

    folder = assets.run_or_policy("generalist")
    shipped = run_config(folder)
    assert dataclasses.replace(load_recipe("generalist").policy, seed=shipped.seed) == shipped
    card = (folder / "MODEL_CARD.md").read_text()
    assert f"sim4endor train generalist --seed {shipped.seed} --out" in card


def _phantom() -> EnvConfig:
    """The simplified phantom's task A with the shipped policy's observations, wire and tip."""
    run_env = run_config(assets.run_or_policy("generalist")).env
    return evaluation_env(run_env, {"domain": "simplified_phantom", "task": "task_a"})


def test_the_generalist_acts_on_a_phantom_it_never_saw() -> None:
    from sim4endor import suite

    phantom = _phantom()
    env = suite.load(phantom.domain, phantom.task, phantom.task_kwargs(0))
    policy = render.load_policy("generalist", 0, env)
    timestep = env.reset()
    for _ in range(3):
        action = policy(render.state_vector(timestep.observation))
        assert action.shape == (2,) and np.all(np.abs(action) <= 1.0)
        timestep = env.step(action)
    assert env.task.step_info()["insertion_command"] > 0


def test_the_generalist_exports_with_its_shaped_tip_in_the_contract(tmp_path) -> None:
    """policy.json names the wire as plain data the catalogue rebuilds: 3 mm bent 75 deg, a
    secondary curve 5 mm from the end bent 50 deg (the recipe's tip, recipe.yaml)."""
    import json
    import math

    from sim4endor.models import wires
    from sim4endor.rl.envs import env_factory
    from sim4endor.rl.export import export_policy

    # A phantom's specs size the networks as well as a coronary tree's, without building one.
    paths = export_policy(assets.run_or_policy("generalist"), tmp_path,
                          make_env=env_factory(_phantom(), evaluation=True))
    assert [path.name for path in paths] == ["policy.pt", "policy.json"]
    contract = json.loads(paths[1].read_text())
    wire = wires.resolve(contract["environment"]["task_kwargs"]["wire"])
    assert wire.tip_length == pytest.approx(0.003)
    assert wire.tip_angle == pytest.approx(math.radians(75.0))
    assert wire.secondary_distance == pytest.approx(0.005)
    assert wire.secondary_angle == pytest.approx(math.radians(50.0))
    assert contract["observation"]["shape"][-1] == 36  # generalist_no_radius and stall_time
