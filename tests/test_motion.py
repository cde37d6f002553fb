"""A beating and breathing heart: the wall's kinematic motion and what the wire feels of it."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from sim4endor import suite
from sim4endor.models.motion import (
    CHUNK_SIZE,
    RAPID_FILLING,
    SYSTOLE,
    HeartMotion,
    MotionError,
    MotionRanges,
    WallMotion,
)
from sim4endor.tasks import TaskConfigError

_STILL = {"cardiac_strain": (0.0, 0.0), "caudal": (0.0, 0.0), "anterior": (0.0, 0.0),
          "rotation": (0.0, 0.0)}


def _heart(**changes: float) -> HeartMotion:
    fields = {"heart_rate": 60.0, "breathing_rate": 15.0, "cardiac_phase": 0.0,
              "respiratory_phase": 0.0, "cardiac_strain": 0.05, "caudal": 5e-3,
              "anterior": 1e-3, "rotation": math.radians(2.0), **changes}
    return HeartMotion(**fields)


def test_a_beat_contracts_in_systole_returns_and_rests() -> None:
    heart = _heart()
    assert heart.cardiac(0.0) == 0.0
    assert heart.cardiac(SYSTOLE) == pytest.approx(1.0)
    assert heart.cardiac(SYSTOLE + RAPID_FILLING) == pytest.approx(0.0, abs=1e-12)
    assert heart.cardiac(0.8) == 0.0  # diastasis
    assert heart.cardiac(1.0 + SYSTOLE) == pytest.approx(1.0)  # the next beat
    samples = [heart.cardiac(t) for t in np.linspace(0.0, 3.0, 301)]
    assert min(samples) >= 0.0 and max(samples) <= 1.0


def test_a_breath_spends_most_of_its_time_near_expiration() -> None:
    heart = _heart()
    assert heart.respiratory(0.0) == pytest.approx(1.0)  # full inspiration
    breath = np.array([heart.respiratory(t) for t in np.linspace(0.0, 4.0, 401)])  # 4 s
    assert np.mean(breath < 0.1) > 1 / 3 and np.mean(breath > 0.9) < 0.15


def test_later_moves_the_clock() -> None:
    heart = _heart(heart_rate=75.0, breathing_rate=14.0, cardiac_phase=0.3,
                   respiratory_phase=0.6)
    later = heart.later(1.7)
    for t in (0.0, 0.4, 2.1):
        assert later.cardiac(t) == pytest.approx(heart.cardiac(t + 1.7))
        assert later.respiratory(t) == pytest.approx(heart.respiratory(t + 1.7))


def _wall(heart: HeartMotion) -> WallMotion:
    centroids = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0], [0.05, 0.01, 0.0],
                          [0.04, -0.02, 0.01]])
    return WallMotion(heart, centroids, np.zeros(3), np.eye(3))


def test_the_ostium_stays_and_the_tree_returns_to_rest() -> None:
    wall = _wall(_heart())
    positions, rotation = wall.pose(0.0)  # full inspiration, no beat: turned about the ostium
    assert not np.allclose(rotation, np.eye(3))
    moved = positions + wall.centroids @ rotation.T
    np.testing.assert_allclose(moved[0], 0.0, atol=1e-12)  # the ostium, where the catheter is
    rest = _wall(_heart(respiratory_phase=0.5))  # end-expiration, no beat
    positions, rotation = rest.pose(0.0)
    np.testing.assert_allclose(rotation, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(positions, 0.0, atol=1e-9)


def test_systole_contracts_the_tree_towards_its_ostium() -> None:
    wall = _wall(_heart(respiratory_phase=0.5, caudal=0.0, anterior=0.0))
    positions, _ = wall.pose(SYSTOLE)  # the beat's peak, the breath near expiration
    np.testing.assert_allclose(positions, -0.05 * wall.centroids, atol=1e-6)
    # What moves the ostium in the lab (the contraction about the centre) is the view's.
    np.testing.assert_allclose(wall.lab_offset(SYSTOLE), 0.05 * wall.centroids.mean(axis=0),
                               atol=1e-6)


def test_to_rest_undoes_a_chunks_motion() -> None:
    wall = _wall(_heart(cardiac_phase=0.1))
    for t in (0.0, 0.2, 1.3):
        for point in wall.centroids[1:] + 1e-4:
            moved = wall.from_rest(point, t)
            np.testing.assert_allclose(wall.to_rest(moved, t), point, atol=1e-12)


def test_the_breath_moves_the_lab_view_caudally() -> None:
    wall = _wall(_heart(cardiac_phase=0.5))  # diastasis
    np.testing.assert_allclose(wall.lab_offset(0.0), [0.0, -1e-3, -5e-3], atol=1e-12)


def test_ranges_draw_within_themselves() -> None:
    ranges, random = MotionRanges(), np.random.RandomState(0)
    for _ in range(20):
        heart = ranges.draw(random)
        assert 60.0 <= heart.heart_rate <= 100.0 and 12.0 <= heart.breathing_rate <= 20.0
        assert 0.0 <= heart.cardiac_phase < 1.0


def _env(motion: Any, seed: int = 3) -> Any:
    return suite.load("coronary", "navigate", {"random": seed, "pool_size": 1,
                                               "motion": motion})


def test_a_moving_wall_is_chunks_of_mocap_hulls() -> None:
    env = _env(True)
    env.reset()
    physics = env.physics
    centroids = physics.wall_chunk_centroids()
    assert len(centroids) == physics.model.nmocap > 10
    model = physics.model.ptr
    for body in np.flatnonzero(model.body_mocapid >= 0)[:20]:
        centres = model.geom_pos[model.geom_bodyid == body]
        assert np.ptp(centres, axis=0).max() <= CHUNK_SIZE


def test_a_still_heart_is_the_static_wall_step_for_step() -> None:
    """Zero amplitudes: the chunks stay put and the forces are read from the contacts, not
    the sensors; the wire does what it does in the static scene."""
    runs = []
    for motion in (False, _STILL):
        env = _env(motion)
        env.reset()
        tips, forces = [], []
        for _ in range(40):
            env.step([0.8, 0.2])
            tips.append(env.physics.tip_position())
            forces.append(env.task.step_info()["wall_force"])
        runs.append((np.array(tips), np.array(forces)))
    np.testing.assert_allclose(runs[0][0], runs[1][0], atol=1e-9)
    np.testing.assert_allclose(runs[0][1], runs[1][1], atol=1e-6)
    assert runs[0][1].max() > 0.0  # the wire met the wall


def test_the_wire_feels_the_heart() -> None:
    env = _env(True)
    env.reset()
    start = env.physics.data.mocap_pos.copy()
    tips = []
    for _ in range(30):
        env.step([0.0, 0.0])  # the driver holds still
        tips.append(env.physics.tip_position())
    assert np.abs(env.physics.data.mocap_pos - start).max() > 1e-4
    assert np.ptp(np.array(tips), axis=0).max() > 1e-5


def test_the_episodes_are_the_same_with_the_heart_on_or_off() -> None:
    still, moving = _env(False, seed=11), _env(True, seed=11)
    for _ in range(3):
        still.reset()
        moving.reset()
        assert still.task.target == moving.task.target
        np.testing.assert_allclose(still.physics.driver_targets(),
                                   moving.physics.driver_targets())


def test_the_same_seed_beats_the_same_way() -> None:
    hearts = []
    for _ in range(2):
        env = _env(True, seed=5)
        env.reset()
        hearts.append(env.physics.wall_motion.motion)
    assert hearts[0] == hearts[1]


def test_a_phantom_has_no_heart() -> None:
    with pytest.raises(TaskConfigError, match="motion"):
        suite.load("simplified_phantom", "task_a", {"motion": True})


@pytest.mark.parametrize("value", ["yes", 1])
def test_motion_must_be_a_switch_or_ranges(value: Any) -> None:
    with pytest.raises(TaskConfigError, match="motion"):
        suite.load("coronary", "navigate", {"pool_size": 1, "motion": value})


@pytest.mark.parametrize("ranges", [{"heart_rate": (100.0, 60.0)}, {"caudal": (-1e-3, 0.0)},
                                    {"rotation": (0.1,)}])
def test_bad_ranges_are_refused(ranges: dict[str, Any]) -> None:
    with pytest.raises(MotionError, match=f"motion.{next(iter(ranges))}"):
        MotionRanges(**ranges)


def test_ranges_from_yaml_become_tuples() -> None:
    from_yaml: Any = [60, 80]
    assert MotionRanges(heart_rate=from_yaml).heart_rate == (60, 80)
