"""Domain randomisation of the cath lab's sensors and the driver (task_kwargs randomise)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from sim4endor import suite
from sim4endor.tasks import CathLabConfig, TaskConfigError
from sim4endor.tasks.config import RANDOMISATION, Randomisation
from sim4endor.tasks.randomisation import DriverModel, draw_driver, draw_sensors


def test_the_default_driver_passes_commands_through() -> None:
    driver = DriverModel()
    driver.reset(0.002, 0.1)
    assert driver.move(0.001, 0.2) == pytest.approx((0.003, 0.3))


def test_a_delayed_driver_moves_steps_later() -> None:
    driver = DriverModel(delay=2)
    driver.reset(0.0, 0.0)
    moves = [driver.move(0.001, 0.0)[0] for _ in range(4)]
    assert moves == pytest.approx([0.0, 0.0, 0.001, 0.002])


def test_slip_loses_part_of_each_advance_but_not_of_a_pull_back() -> None:
    driver = DriverModel(slip=0.1)
    driver.reset(0.01, 0.0)
    assert driver.move(0.001, 0.0)[0] == pytest.approx(0.0109)
    assert driver.move(-0.001, 0.0)[0] == pytest.approx(0.0099)


def test_backlash_holds_the_roll_until_the_motor_crosses_the_dead_band() -> None:
    band = math.radians(2.0)
    driver = DriverModel(backlash=band)
    driver.reset(0.0, 0.0)
    forward = driver.move(0.0, math.radians(5.0))[1]
    assert forward == pytest.approx(math.radians(5.0) - band / 2)
    # Reversing by less than the band leaves the carriage where it was.
    assert driver.move(0.0, -math.radians(1.5))[1] == pytest.approx(forward)
    assert driver.move(0.0, -math.radians(1.5))[1] == pytest.approx(forward - math.radians(1.0))


def test_each_episode_draws_within_the_ranges() -> None:
    random = np.random.RandomState(0)
    for _ in range(50):
        sensors = draw_sensors(RANDOMISATION, CathLabConfig(), random)
        driver = draw_driver(RANDOMISATION, random)
        for name in ("tracking_noise", "latency", "dropout", "roadmap_error"):
            low, high = getattr(RANDOMISATION, name)
            assert low <= getattr(sensors, name) <= high, name
        assert sensors.frame_rate in RANDOMISATION.frame_rates
        assert RANDOMISATION.action_delay[0] <= driver.delay <= RANDOMISATION.action_delay[1]
        assert 0.0 <= driver.slip <= RANDOMISATION.insertion_slip[1]


@pytest.mark.parametrize("kwargs", [{"latency": (0.2, 0.1)}, {"dropout": (0.0, 1.0)},
                                    {"frame_rates": ()}, {"insertion_slip": (-0.1, 0.1)},
                                    {"latency": (0.1,)}])
def test_bad_ranges_are_refused(kwargs: dict[str, Any]) -> None:
    with pytest.raises(TaskConfigError, match="Randomisation"):
        Randomisation(**kwargs)


def _episode(kwargs: dict[str, Any], steps: int = 8) -> list[np.ndarray]:
    env = suite.load("simplified_phantom", "task_a",
                     {"random": 4, "observations": "deployable", **kwargs})
    env.reset()
    return [np.concatenate(list(env.step([0.8, 0.6]).observation.values()))
            for _ in range(steps)]


def test_randomise_is_seeded_and_changes_the_episode() -> None:
    plain, randomised, again = _episode({}), _episode({"randomise": True}), \
        _episode({"randomise": True})
    np.testing.assert_array_equal(np.stack(randomised), np.stack(again))
    assert not np.array_equal(np.stack(plain), np.stack(randomised))


def test_randomise_off_leaves_the_episode_as_it_was() -> None:
    np.testing.assert_array_equal(np.stack(_episode({})),
                                  np.stack(_episode({"randomise": False})))


def test_a_delayed_driver_holds_the_wire_at_the_start() -> None:
    env = suite.load("simplified_phantom", "task_a", {
        "random": 0, "observations": ["insertion"],
        "randomise": {"action_delay": (2, 2), "insertion_slip": (0.0, 0.0)}})
    env.reset()
    start = env.physics.driver_targets()[0]
    env.step([1.0, 0.0])
    env.step([1.0, 0.0])
    assert env.physics.driver_targets()[0] == pytest.approx(start)
    env.step([1.0, 0.0])
    assert env.physics.driver_targets()[0] > start


@pytest.mark.parametrize("value", ["yes", 1, ["latency"]])
def test_randomise_must_be_a_switch_or_ranges(value: Any) -> None:
    with pytest.raises(TaskConfigError, match="randomise"):
        suite.load("simplified_phantom", "task_a", {"randomise": value})


def test_ranges_from_yaml_become_tuples() -> None:
    from_yaml: Any = [0.1, 0.2]
    assert Randomisation(latency=from_yaml).latency == (0.1, 0.2)


def test_the_switch_is_a_command_line_flag_and_a_config_field() -> None:
    import argparse

    from sim4endor.cli.args import add_task_arguments, task_arguments
    from sim4endor.rl.config import EnvConfig

    parser = argparse.ArgumentParser()
    add_task_arguments(parser)
    assert task_arguments(parser.parse_args(["--randomise"])) == {"randomise": True}
    assert "randomise" not in task_arguments(parser.parse_args([]))
    env = EnvConfig(domain="coronary", task="navigate", randomise=True)
    assert env.task_kwargs(0)["randomise"] is True
    assert "randomise" not in EnvConfig().task_kwargs(0)
