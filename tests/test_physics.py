"""GuidewirePhysics: named SI accessors, driver commands, contact force, torque transfer."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from dm_control import mujoco as dm_mujoco
from guidewire_helpers import write_tube_vessel

from sim4endor.benches import validation
from sim4endor.models import constants as names
from sim4endor.models.scene import SceneConfig
from sim4endor.physics import GuidewirePhysics
from sim4endor.vessels import Vessel


@pytest.fixture(scope="module")
def tube(tmp_path_factory: pytest.TempPathFactory) -> Vessel:
    return write_tube_vessel(tmp_path_factory.mktemp("vessels") / "tube")


def _drive(physics: GuidewirePhysics, insertion: float, rotation: float, seconds: float) -> None:
    validation.drive_to(physics, insertion, rotation, settle=seconds)


def test_accessors_have_si_shapes(tube: Vessel) -> None:
    physics = GuidewirePhysics.from_vessel(tube)
    points = physics.wire_points()
    assert points.shape == (physics.num_wire_segments() + 1, 3)
    np.testing.assert_allclose(points[-1], physics.tip_position())
    length = np.linalg.norm(np.diff(points, axis=0), axis=1).sum()
    assert length == pytest.approx(SceneConfig().wire.length, rel=1e-6)
    assert physics.tip_velocity().shape == (3,)
    assert physics.insertion_depth() == 0.0 and physics.rotation_angle() == 0.0
    assert physics.wall_contact_force() == 0.0


def test_insertion_moves_the_tip_and_reports_velocity(tube: Vessel) -> None:
    physics = GuidewirePhysics.from_vessel(tube)
    start = physics.tip_position()
    physics.apply_increments(0.0015, 0.0, 0.05)  # the speed limit: 30 mm/s
    physics.step(10)
    assert physics.tip_velocity()[0] > 0.01
    _drive(physics, 0.03, 0.0, 0.5)
    assert physics.insertion_depth() == pytest.approx(0.03, abs=5e-4)
    assert physics.tip_position()[0] - start[0] == pytest.approx(0.03, abs=1e-3)
    assert physics.is_finite() and not physics.warnings()


def test_increments_are_limited_by_speed_and_range(tube: Vessel) -> None:
    physics = GuidewirePhysics.from_vessel(tube)
    v_ins, v_rot = physics.max_speeds()
    applied = physics.apply_increments(1.0, -1.0, duration=0.05)
    assert applied == pytest.approx((v_ins * 0.05, -v_rot * 0.05))
    applied = physics.apply_increments(-1.0, 0.0, duration=0.05)
    assert applied[0] == pytest.approx(-v_ins * 0.05)
    applied = physics.apply_increments(-1.0, 0.0, duration=0.05)
    assert applied[0] == 0.0  # insertion range starts at 0
    physics.set_driver_targets(1.0, -100.0)
    driver = SceneConfig().driver
    assert physics.driver_targets() == pytest.approx((driver.max_insertion, -driver.max_rotation))
    with pytest.raises(ValueError, match="finite"):
        physics.set_driver_targets(float("nan"), 0.0)


def test_rotation_turns_the_tip_bend_direction(tube: Vessel) -> None:
    physics = GuidewirePhysics.from_vessel(tube)
    _drive(physics, 0.02, 0.0, 1.5)
    before = validation.tip_bend_direction(physics)
    _drive(physics, 0.02, math.pi / 2, 2.0)
    after = validation.tip_bend_direction(physics)
    turned = math.degrees((after - before + math.pi) % (2 * math.pi) - math.pi)
    assert abs(turned) == pytest.approx(90.0, abs=10.0)
    assert physics.rotation_angle() == pytest.approx(math.pi / 2, abs=0.02)


def test_pushing_into_the_capped_end_gives_wall_force_and_no_escape(tube: Vessel) -> None:
    physics = GuidewirePhysics.from_vessel(tube)
    v_ins = physics.max_speeds()[0]
    worst, force = 0.0, 0.0
    while physics.data.time < 4.0:
        physics.apply_increments(v_ins * 0.05, 0.0, 0.05)
        physics.step(10)
        worst = max(worst, validation.escape_depth(physics, tube))
        force = max(force, physics.wall_contact_force())
    assert physics.is_finite() and not physics.warnings()
    assert 0.05 < force < 10.0  # the servo pushes with at most 0.5 N
    assert worst <= SceneConfig().wire.radius
    assert np.all(physics.wall_contact_forces() >= 0.0)


def test_the_mean_tip_force_is_the_mean_over_the_last_step_call(tube: Vessel) -> None:
    """The task's quasi-static safety signal: the tip force averaged over a control step's
    physics steps, not the force at its end (docs/guidewire.md, "Inertia honesty")."""
    one, each, legacy = (GuidewirePhysics.from_vessel(tube) for _ in range(3))
    legacy.legacy_step = True  # the same states, so the same means
    for physics in (one, each, legacy):
        _drive(physics, 0.07, 0.3, 3.0)  # the tip pressed on the cap
    forces = []
    for _ in range(40):
        one.step(10)
        legacy.step(10)
        steps = []
        for _ in range(10):
            each.step()
            steps.append(each.tip_contact_force())
        forces.append((one.mean_tip_contact_force(), float(np.mean(steps)),
                       legacy.mean_tip_contact_force()))
    means = np.array(forces)
    np.testing.assert_allclose(means[:, 0], means[:, 1], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(means[:, 0], means[:, 2], rtol=1e-12, atol=1e-15)
    assert means[:, 0].max() > 0.0
    one.reset()  # a changed state: the force now, not a stale mean
    assert one.mean_tip_contact_force() == one.tip_contact_force() == 0.0


def test_legacy_stepping_reports_the_same_contact_force(tube: Vessel) -> None:
    # The pushed tip chatters on the cap (the total force swings between ~0 and ~1.3 N from
    # one 5 ms step to the next in both modes), so compare the mean over 0.5 s.
    forces = []
    for legacy in (False, True):
        physics = GuidewirePhysics.from_vessel(tube)
        physics.legacy_step = legacy
        _drive(physics, 0.07, 0.0, 3.0)
        samples = []
        for _ in range(100):
            physics.step()
            samples.append(physics.wall_contact_force())
        forces.append(float(np.mean(samples)))
    assert forces[0] > 0.0
    assert forces[1] == pytest.approx(forces[0], rel=0.2)


def test_same_commands_give_identical_trajectories(tube: Vessel) -> None:
    runs = []
    for _ in range(2):
        physics = GuidewirePhysics.from_vessel(tube)
        for k in range(30):
            physics.apply_increments(0.002, 0.1 * math.sin(k), 0.05)
            physics.step(10)
        runs.append(physics.data.qpos.copy())
    np.testing.assert_array_equal(runs[0], runs[1])


def test_a_copy_sharing_the_model_is_dm_controls_copy_without_its_indexing_cost(
        tube: Vessel) -> None:
    """The probing expert's look-ahead copies the physics every control step; the copy that
    reuses the model's named indexing starts in the state dm_control's own copy starts in and
    steps to the same states, bit for bit, while the original stays as it was."""
    physics = GuidewirePhysics.from_vessel(tube)
    _drive(physics, 0.07, 0.3, 1.0)  # the tip pressed on the cap: contacts, warm start
    before = physics.data.qpos.copy()
    ours, theirs = physics.copy(share_model=True), dm_mujoco.Physics.copy(physics, True)
    assert ours.model.ptr is physics.model.ptr and ours.data.ptr is not physics.data.ptr
    for field in ("qpos", "qvel", "qacc_warmstart", "xpos", "sensordata", "efc_force"):
        np.testing.assert_array_equal(getattr(ours.data, field), getattr(theirs.data, field))
    np.testing.assert_array_equal(ours.named.data.qpos, theirs.named.data.qpos)
    assert ours.max_speeds() == theirs.max_speeds()
    for k in range(20):
        for sim in (ours, theirs):
            sim.apply_increments(-0.002, 0.1 * math.sin(k), 0.05)
            sim.step(10)
        assert ours.mean_tip_contact_force() == theirs.mean_tip_contact_force()
    np.testing.assert_array_equal(ours.data.qpos, theirs.data.qpos)
    np.testing.assert_array_equal(ours.wire_points(), theirs.wire_points())
    np.testing.assert_array_equal(physics.data.qpos, before)


def test_vectorised_wall_forces_match_mujoco_contact_force(tube: Vessel) -> None:
    physics = GuidewirePhysics.from_vessel(tube)
    _drive(physics, 0.07, 0.3, 3.0)
    forces = physics.wall_contact_forces()
    assert len(forces) > 0
    model, data = physics.model.ptr, physics.data.ptr
    expected, wrench = [], np.zeros(6)
    walls = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"vessel/wall_{k:03d}")
             for k in range(13)}
    for i in range(data.ncon):
        contact = data.contact[i]
        if {int(contact.geom1), int(contact.geom2)} & walls:
            mujoco.mj_contactForce(model, data, i, wrench)
            expected.append(wrench[0])
    np.testing.assert_allclose(np.sort(forces), np.sort(expected), rtol=1e-9, atol=1e-12)


def test_contact_sensors_match_the_contact_list(tube: Vessel) -> None:
    physics = GuidewirePhysics.from_vessel(tube)
    _drive(physics, 0.07, 0.3, 3.0)
    for _ in range(200):  # the pushed tip chatters on the cap: find a step where it presses
        forces, bodies = physics._wall_contacts()
        indices = physics._indices()
        tip = forces[np.isin(bodies, indices.wire_bodies[indices.tip_start:])].sum()
        if tip > 0.0:
            break
        physics.step()
    assert len(forces) > 0 and tip > 0.0
    assert physics.wall_contact_force() == pytest.approx(forces.sum(), rel=1e-12)
    assert physics.tip_contact_force() == pytest.approx(tip, rel=1e-12)
    # More contacts than a sensor has slots: the totals come from the contact list.
    indices = physics._indices()
    for address in (*indices.wall_sensors, indices.tip_sensor):
        physics.data.ptr.sensordata[address] = names.CONTACT_SENSOR_SLOTS + 1
    assert physics.wall_contact_force() == pytest.approx(forces.sum(), rel=1e-12)
    assert physics.tip_contact_force() == pytest.approx(tip, rel=1e-12)
