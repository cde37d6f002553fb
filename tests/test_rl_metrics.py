"""Evaluation metrics on scripted episodes: known trajectories give known numbers."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from sim4endor import _json as strict_json
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl.evaluation import EpisodeKeys, episode_from_rollout, success_fraction
from sim4endor.rl.metrics import Episode, describe, path_length, spl_term, summarize
from sim4endor.tasks import FAILURES
from sim4endor.tasks.navigation import failure_code


def _straight(length: float, steps: int) -> np.ndarray:
    """Tip moving along +x from the origin in equal steps."""
    x = np.linspace(0.0, length, steps + 1)
    return np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)


def test_an_unstable_episode_adds_no_force_and_the_json_stays_json() -> None:
    """The task reports a diverged step's forces as infinite; the maxima leave it out, and
    whatever non-finite value reaches the printed JSON is written as null."""
    episodes = [*_scripted_episodes(),
                Episode(_straight(0.05, 20), False, 1.0, np.array([0.4, math.inf]), 0.1,
                        -100.0, "instability", np.array([0.2, math.inf]))]
    metrics = summarize(episodes)
    assert metrics["max_wall_force_n"] == pytest.approx(1.2)
    assert metrics["max_tip_force_n"] == pytest.approx(0.2)
    text = strict_json.dumps({"a": math.inf, "b": [1.5, math.nan, {"c": -math.inf}], "d": "x"})
    assert json.loads(text, parse_constant=lambda token: pytest.fail(token)) == {
        "a": None, "b": [1.5, None, {"c": None}], "d": "x"}


def test_path_length_of_a_3_4_5_polyline() -> None:
    tips = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 4.0, 0.0], [3.0, 4.0, 0.0]])
    assert path_length(tips) == pytest.approx(7.0)


def test_spl_term_rewards_short_successful_paths_only() -> None:
    assert spl_term(True, 0.1, 0.1) == pytest.approx(1.0)
    assert spl_term(True, 0.1, 0.2) == pytest.approx(0.5)
    assert spl_term(True, 0.1, 0.05) == pytest.approx(1.0)  # shorter than shortest: capped
    assert spl_term(False, 0.1, 0.1) == 0.0


def _scripted_episodes() -> list[Episode]:
    """Two successes, a tip-force stop and a timeout, with known lengths, times and forces."""
    return [
        # Success straight to a target 0.1 m away in 5 s.
        Episode(_straight(0.1, 100), True, 5.0, np.array([0.1, 0.3]), 0.1),
        # Success after a detour: travelled 0.2 m for a 0.1 m shortest path, 7 s.
        Episode(_straight(0.2, 140), True, 7.0, np.array([0.2]), 0.1),
        # Failure with the largest wall force.
        Episode(_straight(0.05, 20), False, 1.0, np.array([0.9, 1.2]), 0.1, -100.0, "tip_force"),
        # Neither: the step limit ended it.
        Episode(_straight(0.05, 20), False, 20.0, np.array([0.1]), 0.1),
    ]


def test_summarize_scripted_episodes() -> None:
    metrics = summarize(_scripted_episodes())
    assert metrics["success_rate"] == pytest.approx(2 / 4)
    assert metrics["mean_completion_time_s"] == pytest.approx(6.0)  # failures do not count
    assert metrics["mean_path_length_m"] == pytest.approx((0.1 + 0.2 + 0.05 + 0.05) / 4)
    assert metrics["spl"] == pytest.approx((1.0 + 0.5 + 0.0 + 0.0) / 4)
    assert metrics["max_wall_force_n"] == pytest.approx(1.2)
    assert metrics["mean_return"] == pytest.approx(-100.0 / 4)
    assert metrics["outcomes"] == {"success": 2, "timeout": 1, "tip_force": 1}
    assert metrics["trials"] == 4


def test_describe_gives_successes_other_outcomes_and_time_in_one_line() -> None:
    text = describe(summarize(_scripted_episodes()))
    assert text == "2/4 successes (timeout 1, tip_force 1), 6.00 s"
    all_reached = summarize([Episode(_straight(0.1, 10), True, 3.0, np.zeros(10), 0.1)])
    assert describe(all_reached) == "1/1 successes, 3.00 s"
    none_reached = summarize([Episode(_straight(0.01, 3), False, 20.0, np.zeros(3), 0.1)])
    assert describe(none_reached) == "0/1 successes (timeout 1)"


def test_summarize_without_success_has_no_completion_time() -> None:
    metrics = summarize([Episode(_straight(0.01, 3), False, 20.0, np.zeros(3), 0.1)])
    assert metrics["success_rate"] == 0.0
    assert metrics["mean_completion_time_s"] is None
    assert metrics["spl"] == 0.0


def test_summarize_rejects_no_episodes_and_bad_shapes() -> None:
    with pytest.raises(Sim4EndoRError, match="zero evaluation episodes"):
        summarize([])
    with pytest.raises(Sim4EndoRError, match=r"\(T \+ 1, 3\)"):
        Episode(np.zeros((4, 2)), True, 1.0, np.zeros(3), 0.1)


def test_episode_from_a_scripted_rollout() -> None:
    # Tip moves 1 mm along +x per step for 4 steps, velocity 0.02 m/s; success on the last step.
    steps = 4
    tips = torch.tensor(_straight(4e-3, steps), dtype=torch.float64)
    obs = torch.full((steps + 1, 36), 0.02)  # e.g. the generalist set: no absolute position
    distance = torch.tensor([9e-3, 8e-3, 7e-3, 6e-3], dtype=torch.float64)  # after each step
    rollout = TensorDict(
        {
            "observation": obs[:-1],
            "tip_position": tips[:-1],
            "next": {
                "observation": obs[1:],
                "tip_position": tips[1:],
                "reward": torch.ones(steps, 1),
                "is_success": torch.tensor([False, False, False, True]),
                "wall_force": torch.tensor([0.0, 0.2, 0.5, 0.1], dtype=torch.float64),
                "manifold_distance": distance,
            },
        },
        batch_size=[steps],
    )
    keys = EpisodeKeys(control_timestep_s=0.05)
    episode = episode_from_rollout(rollout, keys)
    assert episode.success
    assert episode.duration_s == pytest.approx(0.2)
    assert path_length(episode.tip_positions) == pytest.approx(4e-3, rel=1e-5)
    assert episode.wall_forces.max() == pytest.approx(0.5)
    # Start distance = distance after the first step + that step's displacement.
    assert episode.shortest_path_m == pytest.approx(9e-3 + 1e-3, rel=1e-5)
    assert episode.episode_return == pytest.approx(4.0)
    assert not math.isnan(summarize([episode])["spl"])
    assert episode.failure == "" and episode.outcome == "success"


def test_episode_failure_reason_from_the_failure_code() -> None:
    steps = 3
    rollout = TensorDict(
        {
            "observation": torch.zeros(steps, 6),
            "next": {
                "observation": torch.zeros(steps, 6),
                "reward": torch.zeros(steps, 1),
                "is_success": torch.zeros(steps, dtype=torch.bool),
                "failure_code": torch.tensor([0, 0, failure_code("outside_lumen")]),
            },
        },
        batch_size=[steps],
    )
    episode = episode_from_rollout(rollout)
    assert episode.failure == "outside_lumen" == FAILURES[failure_code("outside_lumen") - 1]
    assert failure_code("") == 0


def test_success_fraction_of_no_finished_episode_is_none() -> None:
    steps = TensorDict({"is_success": torch.zeros(3, dtype=torch.bool)}, batch_size=[3])
    assert success_fraction(steps[torch.zeros(3, dtype=torch.bool)]) is None
    assert success_fraction(steps[torch.tensor([True, False, True])]) == 0.0
    assert success_fraction(TensorDict({}, batch_size=[2])) is None  # env without success
