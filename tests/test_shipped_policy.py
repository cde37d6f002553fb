"""The pretrained generalist policy shipped in the package: found by name, loaded weights-only,
acting on an anatomy it was not trained on."""

from __future__ import annotations

import numpy as np
import torch

from sim4endor import assets
from sim4endor.cli import render
from sim4endor.rl.checkpoint import CHECKPOINT_DIR, STATE_FILE
from sim4endor.rl.runs import run_config


def test_the_generalist_is_shipped_small_and_loads_weights_only() -> None:
    assert "generalist" in assets.policy_names()
    folder = assets.run_or_policy("generalist")
    state = folder / CHECKPOINT_DIR / STATE_FILE
    assert state.stat().st_size < 5 * 2**20  # a few MB at most
    assert not (folder / CHECKPOINT_DIR / "replay.pt").exists()
    torch.load(state, weights_only=True)  # tensors and plain data only: no pickled code
    assert run_config(folder).env.observations == "generalist"
    assert (folder / "MODEL_CARD.md").is_file()


def test_the_generalist_acts_on_a_phantom_it_never_saw() -> None:
    from sim4endor import suite

    env = suite.load("simplified_phantom", "task_a",
                     {"observations": "generalist", "wire": "workhorse", "random": 0})
    policy = render.load_policy("generalist", 0, env)
    timestep = env.reset()
    for _ in range(3):
        action = policy(render.state_vector(timestep.observation))
        assert action.shape == (2,) and np.all(np.abs(action) <= 1.0)
        timestep = env.step(action)
    assert env.task.step_info()["insertion_command"] > 0
