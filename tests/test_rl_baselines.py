"""Open-loop baselines and the expert, evaluated as trained policies are (tiny budgets)."""

from __future__ import annotations

import pytest
from navigation_helpers import require_vessel

from sim4endor.rl.baselines import (
    CONSTANT_GRID,
    ConstantAction,
    RandomActions,
    ScriptedExpert,
    best_constant,
    evaluate_baseline,
)
from sim4endor.rl.metrics import METRIC_KEYS


@pytest.fixture(autouse=True)
def phantom() -> None:
    require_vessel("simplified_phantom")


def test_constant_push_reports_the_trained_policies_metrics() -> None:
    metrics = evaluate_baseline("simplified_phantom", "task_a", ConstantAction(1.0, 0.0),
                                episodes=1, seed=0)
    assert tuple(metrics) == METRIC_KEYS
    assert metrics["trials"] == 1
    assert metrics["outcomes"] == {"success": 1}  # the paper's task A falls to a push
    assert 0.0 < metrics["spl"] <= 1.0


def test_random_actions_are_seeded() -> None:
    def run(seed: int) -> dict[str, object]:
        return evaluate_baseline("simplified_phantom", "task_a", RandomActions(seed),
                                 episodes=1, seed=0, max_steps=5)

    assert run(1) == run(1)
    assert run(1)["mean_path_length_m"] != run(2)["mean_path_length_m"]
    assert run(1)["outcomes"] == {"timeout": 1}  # cut at max_steps


def test_the_expert_drives_through_the_torchrl_env() -> None:
    metrics = evaluate_baseline("simplified_phantom", "task_b", ScriptedExpert(),
                                episodes=1, seed=0)
    assert metrics["success_rate"] == 1.0


def test_best_constant_ranks_by_success_then_time() -> None:
    assert len(CONSTANT_GRID) == 14 and (1.0, 0.0) in CONSTANT_GRID
    chosen, tried = best_constant("simplified_phantom", "task_a", episodes=1, seed=0,
                                  grid=((0.5, 0.0), (1.0, 0.0)))
    assert chosen == ConstantAction(1.0, 0.0)  # both succeed; the faster push wins
    assert set(tried) == {ConstantAction(0.5, 0.0), ConstantAction(1.0, 0.0)}
    assert chosen.label == "constant [1, 0]"
