"""The cath lab's sensor model: what a robot measures, and nothing it cannot."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from sim4endor import suite
from sim4endor.observations import (
    BIPLANE_OBSERVATIONS,
    CATHLAB_OBSERVATIONS,
    MEASURABLE_OBSERVATIONS,
    OBSERVATION_SETS,
    OBSERVATION_UNITS,
    TRACKED_POINTS,
)
from sim4endor.rl.config import EnvConfig, default_observation_scale
from sim4endor.tasks import CathLabConfig, TaskConfigError
from sim4endor.tasks.cathlab import (
    BIPLANE_SEPARATION,
    CathLab,
    Measurement,
    beam_direction,
    image_basis,
)

#: The physics accessors a cath lab's sensors stand for: the imaged wire (and where the
#: breath has carried it in the lab: ``wall_motion``'s ``lab_offset``), the driver's encoders
#: and load cell, the clock.
_MEASURABLE_PHYSICS = {"time", "wire_points", "wall_motion", "insertion_depth",
                       "rotation_angle", "insertion_force"}
_EXACT = CathLabConfig(views=((0.0, 0.0),), view_jitter=0.0, frame_rate=20.0, latency=0.0,
                       tracking_noise=0.0, dropout=0.0, load_cell_noise=0.0, roadmap_error=0.0)


class _OnlyMeasurable:
    """Stands in for the physics, refusing every accessor a robot has no sensor for."""

    def __init__(self, physics: Any) -> None:
        self._physics = physics

    def __getattr__(self, name: str) -> Any:
        if name not in _MEASURABLE_PHYSICS:
            raise AssertionError(f"the deployable observation read physics.{name}")
        return getattr(self._physics, name)


def _straight(tip_x: float, points: int = 30) -> np.ndarray:
    """A straight wire along +x ending at ``tip_x`` (m), 1 mm per segment."""
    return np.stack([tip_x - 1e-3 * np.arange(points)[::-1], np.zeros(points),
                     np.zeros(points)], axis=1)


def _lab(config: CathLabConfig = _EXACT, seed: int = 0, planes: int = 1) -> CathLab:
    lab = CathLab(config, planes)
    route = np.stack([np.linspace(0.0, 0.1, 201), np.zeros(201), np.zeros(201)], axis=1)
    lab.reset(route, np.random.RandomState(seed))
    return lab


def test_the_deployable_sets_hold_only_what_a_robot_measures() -> None:
    for name in ("deployable", "deployable_biplane"):
        assert set(OBSERVATION_SETS[name]) <= MEASURABLE_OBSERVATIONS
    assert set(OBSERVATION_SETS["deployable_biplane"]) == MEASURABLE_OBSERVATIONS
    privileged = set(OBSERVATION_SETS["generalist_stall"]) - MEASURABLE_OBSERVATIONS
    assert {"path_ahead", "axis_offset", "tip_force", "wall_force"} <= privileged


@pytest.mark.parametrize("observations, cathlab", [
    ("deployable", {}),
    ("deployable_biplane", {"biplane": True}),
])
def test_a_deployable_observation_reads_no_privileged_state(
        observations: str, cathlab: dict[str, Any]) -> None:
    env = suite.load("simplified_phantom", "task_a",
                     {"random": 3, "observations": observations, "cathlab": cathlab})
    env.reset()
    for _ in range(5):
        timestep = env.step([1.0, 0.5])
    spied = env.task.get_observation(_OnlyMeasurable(env.physics))
    assert list(spied) == list(OBSERVATION_SETS[observations])
    for name, value in timestep.observation.items():
        np.testing.assert_array_equal(spied[name], value, err_msg=name)
        assert value.shape == (OBSERVATION_UNITS[name][1],), name


def test_the_image_loses_the_depth_along_the_beam() -> None:
    config = CathLabConfig(view_jitter=0.0)  # noisy, delayed, dropping: every sensor on
    near, far = _lab(config, seed=5), _lab(config, seed=5)
    for step in range(20):
        time = 0.05 * step
        wire = _straight(0.01 + 0.001 * step)
        a = near.observe(Measurement(time, wire, 0.2))
        shift = np.linspace(0.0, 5e-3, len(wire))[:, None] * _beams(far)[0]
        b = far.observe(Measurement(time, wire + shift, 0.2))
        for field in ("tracked_wire", "roadmap_offset", "roadmap_ahead", "tracking_age"):
            np.testing.assert_allclose(getattr(a, field), getattr(b, field), atol=1e-12)


def _beams(lab: CathLab) -> np.ndarray:
    """Each plane's beam direction: the normal of its image axes."""
    bases = lab._bases
    return np.cross(bases[:, 0], bases[:, 1])


def test_the_beam_and_image_axes_follow_the_dicom_angles() -> None:
    np.testing.assert_allclose(beam_direction(0.0, 0.0), [0.0, -1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(beam_direction(90.0, 0.0), [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(beam_direction(0.0, 90.0), [0.0, 0.0, 1.0], atol=1e-12)
    right, up = image_basis(beam_direction(0.0, 0.0))
    np.testing.assert_allclose(right, [1.0, 0.0, 0.0], atol=1e-12)  # patient's left
    np.testing.assert_allclose(up, [0.0, 0.0, 1.0], atol=1e-12)  # head
    np.testing.assert_allclose(_beams(_lab()), [[0.0, -1.0, 0.0]], atol=1e-12)


def test_an_exact_lab_tracks_the_wire_and_the_roadmap() -> None:
    lab = _lab()
    view = lab.observe(Measurement(0.0, _straight(0.03), 0.25))
    expected = -2.5e-3 * np.arange(1, TRACKED_POINTS + 1)
    np.testing.assert_allclose(view.tracked_wire[0, :, 0], expected, atol=1e-12)
    np.testing.assert_allclose(view.tracked_wire[0, :, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(view.roadmap_offset, 0.0, atol=1e-12)
    np.testing.assert_allclose(view.roadmap_ahead[0, 0], [2.5e-3, 0.0], atol=1e-12)
    assert view.roadmap_remaining == pytest.approx(0.07, abs=1e-9)
    assert view.proximal_force == 0.25
    assert view.tracking_age[0] == 0.0


def test_the_track_arrives_after_the_latency() -> None:
    lab = _lab(CathLabConfig(views=((0.0, 0.0),), view_jitter=0.0, frame_rate=20.0,
                             latency=0.1, tracking_noise=0.0, dropout=0.0, roadmap_error=0.0))
    remaining = []
    for step in range(10):
        view = lab.observe(Measurement(0.05 * step, _straight(0.002 * step), 0.0))
        remaining.append(view.roadmap_remaining)
        assert view.tracking_age[0] == pytest.approx(min(0.05 * step, 0.1))
    # At step k the lab shows the tip of step k - 2 (0.1 s at 20 Hz).
    np.testing.assert_allclose(remaining[2:], 0.1 - 0.002 * np.arange(8), atol=1e-9)


def test_pulses_between_control_steps_hold_the_image() -> None:
    lab = _lab(CathLabConfig(views=((0.0, 0.0),), view_jitter=0.0, frame_rate=10.0,
                             latency=0.0, tracking_noise=0.0, dropout=0.0, roadmap_error=0.0))
    ages = [lab.observe(Measurement(0.05 * step, _straight(0.01), 0.0)).tracking_age[0]
            for step in range(6)]
    np.testing.assert_allclose(ages, [0.0, 0.05] * 3, atol=1e-12)


def test_a_lost_track_ages_until_found() -> None:
    lab = _lab(CathLabConfig(views=((0.0, 0.0),), frame_rate=20.0, latency=0.0,
                             dropout=0.99), seed=1)
    first = lab.observe(Measurement(0.0, _straight(0.01), 0.0))
    later = lab.observe(Measurement(0.5, _straight(0.03), 0.0))
    assert first.tracking_age[0] == 0.0
    assert later.tracking_age[0] == pytest.approx(0.5)  # the tip of t = 0 still shown
    np.testing.assert_allclose(later.tracked_wire, first.tracked_wire)


def test_the_match_does_not_jump_along_an_overlapping_route() -> None:
    # A route out along x and back 1 mm below: in the AP image its legs are 1 mm apart. A
    # tracked tip on the outward leg that noise puts nearer the return keeps its match.
    out = np.stack([np.linspace(0.0, 0.05, 101), np.zeros(101), np.zeros(101)], axis=1)
    lab = CathLab(_EXACT, 1)
    back = out[::-1] + np.array([0.0, 0.0, -1e-3])
    lab.reset(np.vstack([out, back]), np.random.RandomState(0))
    length = 0.101
    first = lab.observe(Measurement(0.0, _straight(0.005), 0.0))
    assert first.roadmap_remaining == pytest.approx(length - 0.005, abs=0.15e-3)
    near_return = _straight(0.01) + np.array([0.0, 0.0, -0.8e-3])
    later = lab.observe(Measurement(0.05, near_return, 0.0))
    assert later.roadmap_remaining == pytest.approx(length - 0.01, abs=0.15e-3)


def test_the_same_seed_gives_the_same_views_and_noise() -> None:
    config = CathLabConfig()
    views = [_lab(config, seed=seed).observe(Measurement(0.0, _straight(0.02), 0.1))
             for seed in (7, 7, 8)]
    np.testing.assert_array_equal(views[0].tracked_wire, views[1].tracked_wire)
    assert views[0].proximal_force == views[1].proximal_force
    assert not np.array_equal(views[0].tracked_wire, views[2].tracked_wire)


def test_a_biplane_lab_draws_separated_planes() -> None:
    for seed in range(10):
        beams = _beams(_lab(CathLabConfig(biplane=True), seed=seed, planes=2))
        assert np.dot(beams[0], beams[1]) <= np.cos(np.radians(BIPLANE_SEPARATION)) + 1e-9
    with pytest.raises(TaskConfigError, match="no two views"):
        CathLab(CathLabConfig(views=((0.0, 0.0), (10.0, 0.0))), 2)


@pytest.mark.parametrize("kwargs, match", [
    ({"views": ()}, "views"),
    ({"views": ((120.0, 0.0),)}, "views"),
    ({"dropout": 1.0}, "dropout"),
    ({"latency": -0.1}, "latency"),
    ({"biplane": 1}, "biplane"),
])
def test_bad_cath_lab_settings_are_refused(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(TaskConfigError, match=match):
        CathLabConfig(**kwargs)


def test_views_from_yaml_become_tuples() -> None:
    from_yaml: Any = [[0, 30], [45, 25]]
    assert CathLabConfig(views=from_yaml).views == ((0, 30), (45, 25))


def test_the_second_plane_needs_a_biplane_lab() -> None:
    with pytest.raises(TaskConfigError, match="biplane"):
        suite.load("simplified_phantom", "task_a",
                   {"observations": list(BIPLANE_OBSERVATIONS[:1])})


def test_a_run_config_on_the_biplane_set_loads_a_biplane_lab() -> None:
    """A run config names only its observation set; reading the second plane makes the lab
    biplane, so `sim4endor train` and `evaluate` can run a biplane student."""
    env_config = EnvConfig(domain="simplified_phantom", task="task_a",
                           observations="deployable_biplane")
    env = suite.load(env_config.domain, env_config.task, env_config.task_kwargs(0))
    env.reset()
    assert env.task.cathlab is not None and env.task.cathlab.planes == 2
    assert "cathlab" not in EnvConfig(observations="deployable").task_kwargs(0)


def test_the_deployable_set_has_network_scales() -> None:
    env = EnvConfig(domain="simplified_phantom", task="task_a", observations="deployable")
    sizes = sum(OBSERVATION_UNITS[name][1] or 0 for name in OBSERVATION_SETS["deployable"])
    assert len(default_observation_scale(env)) == sizes
    assert set(CATHLAB_OBSERVATIONS) <= set(OBSERVATION_SETS["deployable"])


def test_a_phantom_lies_face_up_under_the_c_arm() -> None:
    env = suite.load("simplified_phantom", "task_a", {
        "random": 0, "observations": "deployable",
        "cathlab": {"views": ((0.0, 0.0),), "view_jitter": 0.0}})
    env.reset()
    assert env.task.cathlab is not None
    beams = _beams(env.task.cathlab)
    np.testing.assert_allclose(beams, [[0.0, 0.0, 1.0]], atol=1e-12)  # AP: face on


@pytest.mark.parametrize("axes", [((1, 0, 0), (0, 1, 0), (0, 1, 0)),
                                  ((1, 0, 0), (0, 1, 0), (0, 0, -1)), ((1, 0),)])
def test_patient_axes_must_be_a_rotation(axes: Any) -> None:
    with pytest.raises(TaskConfigError, match="patient_axes"):
        CathLabConfig(patient_axes=axes)


def test_a_run_config_sets_the_cath_lab_and_names_a_bad_field() -> None:
    from sim4endor.rl.config import ConfigError, apply_overrides, default_config, from_dict, to_dict

    config = apply_overrides(default_config("sac"), [
        "env.observations=deployable", "env.cathlab={frame_rate: 15.0, views: [[0, 30]]}"])
    assert config.env.task_kwargs(0)["cathlab"] == {"frame_rate": 15.0, "views": [[0, 30]]}
    assert from_dict(to_dict(config)).env == config.env  # as config.yaml saves and reads it
    env = suite.load("simplified_phantom", "task_a", config.env.task_kwargs(0))
    assert env.task.config.cathlab.frame_rate == 15.0
    for bad, message in (("{frame_rate: -1}", "frame_rate must be > 0"),
                         ("{rate: 15}", r"unknown fields \['rate'\]")):
        with pytest.raises(ConfigError, match=message):
            apply_overrides(default_config("sac"), [f"env.cathlab={bad}"])
    with pytest.raises(ConfigError, match="biplane"):
        EnvConfig(observations="deployable_biplane", cathlab={"biplane": False})


def test_the_sensor_benchmark_rows_take_out_only_what_they_name() -> None:
    """experiments/benchmarks/cathlab_sensors.py: every row is a valid cath lab over the
    defaults, and ``exact`` leaves no noise, lost frame, registration error or latency."""
    import dataclasses

    from script_helpers import load_script

    settings = load_script("experiments/benchmarks/cathlab_sensors.py").SETTINGS
    assert settings["own sensors"] == {}
    for changes in settings.values():
        EnvConfig(observations="deployable", cathlab=changes)
    exact = dataclasses.replace(CathLabConfig(), **settings["exact"])
    assert (exact.tracking_noise, exact.dropout, exact.roadmap_error, exact.load_cell_noise,
            exact.latency) == (0.0, 0.0, 0.0, 0.0, 0.0)
    assert exact.frame_rate == 20.0  # a pulse every control step (20 Hz)


def test_the_suite_meets_a_run_with_the_sensors_it_trained_on() -> None:
    from sim4endor.rl.generalisation import SuiteConfig, policy_cases

    run_env = EnvConfig(observations="deployable", cathlab={"frame_rate": 15.0})
    phantoms = SuiteConfig(trees=0, wide_trees=0, implicit_trees=0, steve_dir=None)
    assert {case.env.task_kwargs(0)["cathlab"]["frame_rate"]
            for case in policy_cases(run_env, phantoms)} == {15.0}
    exact = SuiteConfig(trees=0, wide_trees=0, implicit_trees=0, steve_dir=None,
                        cathlab={"latency": 0.0})
    assert {tuple(case.env.task_kwargs(0)["cathlab"].items())
            for case in policy_cases(run_env, exact)} == {(("latency", 0.0),)}
