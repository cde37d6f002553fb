"""The recipe-scaling benchmark (experiments/benchmarks/recipe_scaling.py) times a real
demonstrations stage; here with two short episodes, so only that it runs is checked."""

from __future__ import annotations

from script_helpers import load_script

scaling = load_script("experiments/benchmarks/recipe_scaling.py")


def test_the_stage_is_timed_in_two_worker_processes() -> None:
    seconds = scaling.stage_seconds(2, 1, 2, "local", None, ["max_steps=10"])
    assert 0.0 < seconds < 600.0
