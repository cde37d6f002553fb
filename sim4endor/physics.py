"""``GuidewirePhysics``: dm_control Physics of a guidewire scene with named SI accessors.

Example (one 50 ms control step of 1 mm forward, then read the state)::

    from sim4endor import vessels
    from sim4endor.models.scene import config_for_vessel
    from sim4endor.physics import GuidewirePhysics

    vessel = vessels.load("simplified_phantom")
    physics = GuidewirePhysics.from_vessel(vessel, config_for_vessel(vessel))
    physics.apply_increments(0.001, 0.0, duration=0.05)
    physics.step(10)                      # 10 x 5 ms
    physics.tip_position(), physics.wall_contact_force()

Every element is addressed by its name from :mod:`sim4endor.models.constants`.
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco import engine, wrapper
from dm_control.mujoco import index as named_index
from dm_control.rl import control
from numpy.typing import NDArray

from sim4endor.models import constants as names
from sim4endor.models.motion import WallMotion
from sim4endor.models.scene import SceneConfig, build_model
from sim4endor.vessels import Vessel

FloatArray = NDArray[np.float64]
_LOG = logging.getLogger(__name__)


def _scalar(value: object) -> float:
    # Named indexing returns a 0-d or a (1,) array depending on the field.
    return float(np.ravel(np.asarray(value))[0])


@dataclass(frozen=True, eq=False)
class _Indices:
    model: mujoco.MjModel
    wire_bodies: NDArray[np.int64]
    tip_site: int
    geom_class: NDArray[np.int8]  # 1: wire segment, 2: vessel wall, 0: anything else
    wall_sensors: tuple[int, ...]  # sensordata addresses of each chain's wall contact sensor
    tip_sensor: int  # sensordata address of the tip section's wall contact sensor
    tip_start: int  # index in wire_bodies of the first segment of the pre-bent tip
    shape_start: int  # the same of the shaped part: the tip and any secondary curve behind it
    # Per chain after the first: the body its free root copies, the root's qpos and dof
    # addresses (see GuidewireConfig.chain_bodies).
    chain_roots: tuple[tuple[int, int, int], ...]
    actuators: tuple[int, int]  # insertion, rotation
    joint_qpos: tuple[int, int]  # qpos addresses of the insertion and rotation joints


def _geom_classes(
    model: mujoco.MjModel, wire_bodies: NDArray[np.int64], sheath: int
) -> NDArray[np.int8]:
    """Returns 1 for colliding wire geoms, 2 for vessel-wall geoms, 0 for the rest."""
    wire = np.isin(model.geom_bodyid, wire_bodies) & (model.geom_contype > 0)
    wall = (model.geom_contype & 2).astype(bool) & (model.geom_bodyid != sheath)
    return np.where(wire, 1, np.where(wall, 2, 0)).astype(np.int8)


class GuidewirePhysics(dm_mujoco.Physics):
    """Physics of a wire on a robot driver, optionally inside a vessel.

    Both stepping modes give consistent readings:

    * ``legacy_step = False`` (this class's default): :meth:`step` is a plain ``mj_step``.
      Afterwards all accessors (positions, velocities, contacts, forces) describe the state at
      the start of the last physics step, one time step (5 ms) behind ``qpos``.
    * ``legacy_step = True`` (what dm_control's ``control.Environment`` sets unless given
      ``legacy_step=False``): positions and contacts are current; the contact forces are then
      recomputed for the current contacts on demand (measured: the force query costs about 7 %
      of a 10-substep control step instead of 3 %).
    """

    legacy_step = False
    #: (data.time after the last :meth:`step` call, the tip's mean wall force over it).
    _tip_force_mean: tuple[float, float] = (math.nan, 0.0)
    #: The heart's motion that places the wall's chunks before every physics step (a scene
    #: built with ``moving_walls``); None: the wall stands still.
    _wall_motion: WallMotion | None = None

    @classmethod
    def from_vessel(
        cls, vessel: Vessel | None, config: SceneConfig | None = None
    ) -> GuidewirePhysics:
        """Builds (or reuses the cached compiled) scene for ``vessel`` and wraps it.

        Args:
            vessel: The anatomy, or ``None`` for the wire and driver alone.
            config: Wire, driver and timestep; ``None`` uses the defaults.
        """
        return cls.from_model(wrapper.MjModel(build_model(vessel, config)))

    @classmethod
    def from_model(cls, model: wrapper.MjModel) -> GuidewirePhysics:
        """Wraps ``model`` with fresh data in the scene's start state: the driver at its
        start, and a tip flagged too wide for the inlet's bore
        (:data:`~sim4endor.models.constants.TIP_STRAIGHT_AT_START`) straightened in it, as
        :meth:`place_driver` starts every episode. A tip that fits keeps the compiled start
        state as it is."""
        physics = super().from_model(model)
        if _scalar(physics.named.model.numeric_data[names.TIP_STRAIGHT_AT_START]):
            physics.place_driver(0.0, 0.0)
        return physics

    def copy(self, share_model: bool = False) -> GuidewirePhysics:
        """A copy of this physics, as dm_control's ``copy`` makes it; with ``share_model``
        it reuses this physics' named indexing of the model.

        dm_control rebuilds that indexing from the model for every copy: 3.5 of the 5.8 ms
        of CPU time a copy took on a coronary folder of 2,000 hull geoms, a third of a
        control step of its physics, and the probing expert copies the physics at every
        control step to screen its action (docs/performance.md, "The probing expert: where
        the time goes").
        """
        if not share_model:
            copied = super().copy()
            copied._wall_motion = self._wall_motion
            return copied
        # dm_control's copy and _reload_from_data, with the model's indexers reused: they
        # read the model's arrays, which the copy shares.
        new = type(self).__new__(type(self))
        new._warnings_cause_exception = True
        new._data = self.data._make_copy(share_model=True)
        new._warnings = new.data.warning.number
        new._warnings_before = np.empty_like(new._warnings)
        new._new_warnings = np.empty(dtype=bool, shape=(len(new._warnings),))
        try:
            new.after_reset()
        except control.PhysicsError as exc:
            _LOG.warning(exc)
        new._axis_indexers = self._model_axis_indexers()
        new._named = engine.NamedIndexStructs(
            model=self.named.model,
            data=named_index.struct_indexer(new.data, "mjdata", new._axis_indexers[1]))
        new._index_cache = self._indices()
        new._wall_motion = self._wall_motion
        return new

    def _model_axis_indexers(self) -> tuple[mujoco.MjModel, dict[str, Any]]:
        """dm_control's named axes of the model (``index.make_axis_indexers``), built once
        per model (reloads change it)."""
        cached = getattr(self, "_axis_indexers", None)
        if cached is None or cached[0] is not self.model.ptr:
            cached = (self.model.ptr, named_index.make_axis_indexers(self.model))
            self._axis_indexers = cached
        return cached

    # ------------------------------------------------------------------------ wire state
    def _indices(self) -> _Indices:
        # Name lookups cost microseconds each; do them once per model (reloads change it).
        model = self.model.ptr
        cached = getattr(self, "_index_cache", None)
        if cached is not None and cached.model is model:
            return cached
        body = mujoco.mjtObj.mjOBJ_BODY
        ids: list[int] = []
        while (found := mujoco.mj_name2id(model, body, names.wire_body(len(ids)))) >= 0:
            ids.append(found)
        bodies = np.array(ids)  # not consecutive ids once the wire is split into chains
        starts, roots = [0], []
        for index in range(1, len(ids)):
            root = mujoco.mj_name2id(model, body, names.wire_chain_root(index))
            if root >= 0:
                joint = int(model.body_jntadr[root])
                starts.append(index)
                roots.append((ids[index - 1], int(model.jnt_qposadr[joint]),
                              int(model.jnt_dofadr[joint])))
        sheath = mujoco.mj_name2id(model, body, names.SHEATH_BODY)
        sensor = mujoco.mjtObj.mjOBJ_SENSOR
        tip_sensor = mujoco.mj_name2id(model, sensor, names.TIP_CONTACT_SENSOR)
        tip_start = int(np.flatnonzero(bodies == model.sensor_objid[tip_sensor])[0])
        # A body's rest turn from the one before it is the wire's pre-bend there: the shaped
        # part starts at the first body that turns (a chain root copies its segment's pose, so
        # the body after it turns relative to that copy, as in one chain).
        turned = np.flatnonzero(np.abs(model.body_quat[bodies[1:], 0]) < 1.0 - 1e-12) + 1
        indices = _Indices(
            model=model,
            wire_bodies=bodies,
            tip_site=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, names.WIRE_TIP_SITE),
            geom_class=_geom_classes(model, bodies, sheath),
            wall_sensors=tuple(
                int(model.sensor_adr[mujoco.mj_name2id(model, sensor,
                                                       names.wall_contact_sensor(first))])
                for first in starts
            ),
            tip_sensor=int(model.sensor_adr[tip_sensor]),
            tip_start=tip_start,
            shape_start=min(tip_start, int(turned[0])) if turned.size else tip_start,
            chain_roots=tuple(roots),
            actuators=(
                mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, names.INSERTION_ACTUATOR),
                mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, names.ROTATION_ACTUATOR),
            ),
            joint_qpos=tuple(  # type: ignore[arg-type]
                int(model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)])
                for j in (names.INSERTION_JOINT, names.ROTATION_JOINT)
            ),
        )
        self._index_cache = indices
        return indices

    def num_wire_segments(self) -> int:
        """Number of rigid segments of the wire."""
        return len(self._indices().wire_bodies)

    def wire_body_ids(self) -> NDArray[np.int64]:
        """MuJoCo body ids of the wire's segments, proximal first (segment ``i`` runs from
        :meth:`wire_points` vertex ``i`` to ``i + 1``; each body's x axis runs along it)."""
        return self._indices().wire_bodies.copy()

    def tip_position(self) -> FloatArray:
        """World position of the wire's distal end (m), shape (3,)."""
        return self.data.ptr.site_xpos[self._indices().tip_site].copy()

    def tip_velocity(self) -> FloatArray:
        """World linear velocity of the wire's distal end (m/s), shape (3,)."""
        site = self._indices().tip_site
        velocity = np.zeros(6)
        mujoco.mj_objectVelocity(
            self.model.ptr, self.data.ptr, mujoco.mjtObj.mjOBJ_SITE, site, velocity, 0
        )
        return velocity[3:].copy()

    def tip_frame(self) -> FloatArray:
        """Rotation of the wire's distal segment (3, 3): columns are its axes in world
        coordinates, so the frame turns with the tip's heading and roll."""
        return self.data.ptr.xmat[self._indices().wire_bodies[-1]].reshape(3, 3).copy()

    def wire_points(self) -> FloatArray:
        """Wire centreline vertices, proximal first, tip last (m), shape (N+1, 3)."""
        return np.vstack([self.data.xpos[self._indices().wire_bodies], self.tip_position()[None]])

    def tip_start_index(self) -> int:
        """Index in :meth:`wire_points` of the vertex where the pre-bent tip starts."""
        return self._indices().tip_start

    def shape_start_index(self) -> int:
        """Index in :meth:`wire_points` of the vertex where the shaped part starts: the
        secondary curve's proximal end, or the tip's start without one
        (:attr:`~sim4endor.models.guidewire.GuidewireConfig.secondary_angle`)."""
        return self._indices().shape_start

    def insertion_depth(self) -> float:
        """Carriage insertion (m) from its start; the tip has advanced about as much."""
        return float(self.data.qpos[self._indices().joint_qpos[0]])

    def rotation_angle(self) -> float:
        """Carriage rotation about the insertion axis (rad), 0 = tip bent 'up'."""
        return float(self.data.qpos[self._indices().joint_qpos[1]])

    # ------------------------------------------------------------------------- contacts
    def wall_contact_forces(self) -> FloatArray:
        """Normal force (N) of every wire–vessel-wall contact now active (sheath excluded)."""
        return self._wall_contacts()[0]

    def _wall_contacts(self) -> tuple[FloatArray, NDArray[np.int32]]:
        """Returns the normal force (N) and the wire body id of every wire–wall contact."""
        data, model = self.data.ptr, self.model.ptr
        if data.ncon == 0:
            return np.zeros(0), np.zeros(0, dtype=np.int32)
        if self.legacy_step:
            # mj_step2 + mj_step1 leave efc_force from the previous state's contacts.
            mujoco.mj_fwdActuation(model, data)
            mujoco.mj_fwdAcceleration(model, data)
            mujoco.mj_fwdConstraint(model, data)
        contacts = data.contact
        # Geom classes 1 (wire) and 2 (wall): a wire–wall pair is the only product equal to 2.
        geom_class = self._indices().geom_class
        geom1, geom2 = contacts.geom1, contacts.geom2
        hits = np.flatnonzero(geom_class[geom1] * geom_class[geom2] == 2)
        address = contacts.efc_address[hits]
        hits, address = hits[address >= 0], address[address >= 0]
        wire_geom = np.where(geom_class[geom1[hits]] == 1, geom1[hits], geom2[hits])
        bodies = model.geom_bodyid[wire_geom]
        if model.opt.cone != mujoco.mjtCone.mjCONE_PYRAMIDAL:
            return data.efc_force[address].copy(), bodies
        # A pyramidal contact's normal force is the sum of its 2(dim-1) consecutive edge forces
        # (as in mj_contactForce); a frictionless contact has one row. Vectorised through a
        # cumulative sum over the constraint rows.
        rows = np.maximum(2 * (contacts.dim[hits] - 1), 1)
        cumulative = np.concatenate(([0.0], np.cumsum(data.efc_force)))
        return cumulative[address + rows] - cumulative[address], bodies

    def wall_contact_distances(self) -> FloatArray:
        """Signed distance (m) of every wire–vessel-wall contact now detected (sheath
        excluded): MuJoCo's ``contact.dist`` between the wire capsule and the collision hull
        itself, negative when they overlap (a penetration)."""
        contacts = self.data.ptr.contact
        geom_class = self._indices().geom_class
        hits = geom_class[contacts.geom1] * geom_class[contacts.geom2] == 2
        return contacts.dist[hits].copy()

    def wall_contact_force(self) -> float:
        """Total normal force of all wire–vessel-wall contacts (N)."""
        return self._contact_sensor_total(self._indices().wall_sensors, 0)

    def tip_contact_force(self) -> float:
        """Normal force of the pre-bent tip's segments on the vessel wall now (N).

        The tip is what can perforate a vessel, while the shaft of a wire lying in tortuous
        vessels presses on every bend (measured on the vascular phantom: over 2.5 N in total
        on the shaft for about 0.4 N on the tip). The task's safety signal is this force's
        mean over a control step (:meth:`mean_tip_contact_force`).
        """
        indices = self._indices()
        return self._contact_sensor_total((indices.tip_sensor,), indices.tip_start)

    # ---------------------------------------------------------------------- moving walls
    def wall_chunk_centroids(self) -> FloatArray:
        """(K, 3) each moving wall chunk's centre at rest (m), in mocap order; (0, 3) for a
        static wall."""
        model = self.model.ptr
        bodies = np.flatnonzero(model.body_mocapid >= 0)
        bodies = bodies[np.argsort(model.body_mocapid[bodies])]
        return np.array([model.geom_pos[model.geom_bodyid == b].mean(axis=0) for b in bodies]
                        ).reshape(-1, 3)

    def set_wall_motion(self, motion: WallMotion | None) -> None:
        """Moves the wall's chunks with ``motion`` from now on (None: leaves them at rest)."""
        if motion is not None and len(motion.centroids) != self.model.nmocap:
            raise ValueError(f"The wall motion moves {len(motion.centroids)} chunks; this "
                             f"scene has {self.model.nmocap} (built with moving_walls?).")
        self._wall_motion = motion
        self._place_walls()

    @property
    def wall_motion(self) -> WallMotion | None:
        """The heart's motion that moves the wall, if any."""
        return self._wall_motion

    def _place_walls(self) -> None:
        data = self.data.ptr
        if self._wall_motion is None:
            data.mocap_pos[:] = 0.0
            data.mocap_quat[:] = (1.0, 0.0, 0.0, 0.0)
            return
        positions, rotation = self._wall_motion.pose(float(data.time))
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rotation.ravel())
        data.mocap_pos[:] = positions
        data.mocap_quat[:] = quat

    def step(self, nstep: int = 1) -> None:
        """Advances ``nstep`` physics steps and keeps the tip's mean wall force over them
        (:meth:`mean_tip_contact_force`)."""
        if nstep < 1:  # e.g. a settle time shorter than one step: nothing to advance
            return
        indices = self._indices()
        # In either stepping mode the sensors then hold the state each step started from, so
        # the mean covers the same states in both and costs no recomputation of the forces.
        sensed_tip_force = functools.partial(self._contact_sensor_total, (indices.tip_sensor,),
                                             indices.tip_start, sensed=True)
        total = 0.0
        if self.legacy_step:
            for _ in range(nstep):
                if self._wall_motion is not None:
                    self._place_walls()
                super().step()
                total += sensed_tip_force()
        else:
            # One state check for all steps, as dm_control's own step(nstep) does.
            model, data = self.model.ptr, self.data.ptr
            moving = self._wall_motion is not None
            with self.check_invalid_state():
                for _ in range(nstep):
                    if moving:
                        self._place_walls()
                    mujoco.mj_step(model, data)
                    total += sensed_tip_force()
        self._tip_force_mean = (float(self.data.time), total / nstep)

    def mean_tip_contact_force(self) -> float:
        """Mean of :meth:`tip_contact_force` over the physics steps of the last :meth:`step`
        call (a task's control step), N; the force now when the state has changed since.

        The quasi-static force, the one to compare with a puncture force measured by a slow
        push. The instantaneous force of a mass-scaled wire (``GuidewireConfig.mass_scale``)
        is not: where the tip strikes the wall, MuJoCo's soft contact stops the scaled mass
        within a few milliseconds, and the force of that stop grows with the mass
        (docs/guidewire.md, "Inertia honesty").
        """
        time, mean = self._tip_force_mean
        return mean if time == float(self.data.time) else self.tip_contact_force()

    def _contact_sensor_total(self, addresses: tuple[int, ...], first_index: int,
                              sensed: bool = False) -> float:
        """Sums wall contact sensors: the wall force on the wire from its body
        ``first_index`` (0: proximal) on. ``sensed``: what the sensors hold even with legacy
        stepping (the state the last physics step started from, as without it)."""
        # The sensors count the world body's hulls: a moving wall's chunks are other bodies.
        if (sensed or not self.legacy_step) and not self.model.nmocap:
            # Filled by mj_step for the same contacts and forces that _wall_contacts() reads:
            # slots of [count, normal, tangent, tangent].
            total = 0.0
            for address in addresses:
                slots = self.data.ptr.sensordata[address : address + 4 * names.CONTACT_SENSOR_SLOTS]
                found = int(slots[0])
                if found > names.CONTACT_SENSOR_SLOTS:
                    break
                total += float(slots[1 : 4 * found : 4].sum())
            else:
                return total
        # Legacy stepping (the sensor describes the previous state), a moving wall or more
        # contacts than slots.
        forces, bodies = self._wall_contacts()
        return float(forces[np.isin(bodies, self._indices().wire_bodies[first_index:])].sum())

    # -------------------------------------------------------------------------- driving
    def driver_targets(self) -> tuple[float, float]:
        """Current servo targets (insertion m, rotation rad)."""
        insertion, rotation = self._indices().actuators
        return float(self.data.ctrl[insertion]), float(self.data.ctrl[rotation])

    def set_driver_targets(self, insertion: float, rotation: float) -> None:
        """Sets the servo targets, clipped to the driver's ranges (m, rad).

        Targets should move no faster than :meth:`max_speeds` (use :meth:`apply_increments`).
        Measured: jumping the insertion target by 70 mm into a dead end, so that the servo
        shoves the (mass-scaled, ~1 kg) wire at its force limit from rest, broke the wire out
        of a 2 mm tube in 6–8 of 8 tries, while increments at up to 45 mm/s never did.
        """
        # Raw MuJoCo arrays and plain floats: this runs every control step, and the wrapper's
        # attribute views cost more than the arithmetic.
        model, ctrl = self.model.ptr, self.data.ptr.ctrl
        for actuator, value in zip(self._indices().actuators, (insertion, rotation), strict=True):
            if not math.isfinite(value):
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator)
                raise ValueError(f"Driver target for {name} must be finite, got {value}.")
            low, high = model.actuator_ctrlrange[actuator].tolist()
            ctrl[actuator] = min(max(float(value), low), high)

    def place_driver(self, insertion: float, rotation: float) -> None:
        """Moves the carriage (and the wire with it, rigidly) to a pose and holds it there.

        For episode starts only: it sets the joint positions directly, which is safe for the
        small offsets of an initial state but would teleport a wire that is in contact.
        Positions (:meth:`tip_position`, :meth:`wire_points`) are current on return.
        """
        self.set_driver_targets(insertion, rotation)
        for address, value in zip(self._indices().joint_qpos, self.driver_targets(), strict=True):
            self.data.qpos[address] = value
        if _scalar(self.named.model.numeric_data[names.TIP_STRAIGHT_AT_START]):
            self._straighten_wire()
        # Body and site positions follow at once, so the tip can be read inside dm_control's
        # reset_context (whose forward pass only runs when the block exits).
        model, data = self.model.ptr, self.data.ptr
        mujoco.mj_kinematics(model, data)
        # Each later chain's free root onto the segment it copies, chain after chain: a root's
        # pose follows from the chains before it.
        for copied, qpos, dof in self._indices().chain_roots:
            data.qpos[qpos:qpos + 3] = data.xpos[copied]
            data.qpos[qpos + 3:qpos + 7] = data.xquat[copied]
            data.qvel[dof:dof + 6] = 0.0
            mujoco.mj_kinematics(model, data)

    def _straighten_wire(self) -> None:
        """Turns every wire joint against its body's rest turn: the wire, pre-bent tip
        included, lies straight along the driver axis, and the rod's elasticity, whose rest
        shape is the model's, bends the tip back as the lumen lets it."""
        model = self.model
        for body in self._indices().wire_bodies[1:]:
            # A ball joint's rotation follows its body's frame: undoing the frame's turn
            # (a unit quaternion's inverse is its conjugate) aligns the body with its parent.
            address = model.jnt_qposadr[model.body_jntadr[body]]
            mujoco.mju_negQuat(self.data.qpos[address:address + 4], model.body_quat[body])

    def insertion_force(self) -> float:
        """Force (N) the insertion servo applies to the carriage now; positive pushes the wire
        in. It is clipped to the driver's ``insertion_force_limit``."""
        return float(self.data.ptr.actuator_force[self._indices().actuators[0]])

    def max_speeds(self) -> tuple[float, float]:
        """The driver's speed limits (m/s, rad/s)."""
        numeric = self.named.model.numeric_data
        return (
            _scalar(numeric[names.MAX_INSERTION_SPEED]),
            _scalar(numeric[names.MAX_ROTATION_SPEED]),
        )

    def apply_increments(
        self, delta_insertion: float, delta_rotation: float, duration: float
    ) -> tuple[float, float]:
        """Moves the servo targets by [Δd (m), Δθ (rad)] for a control step of ``duration`` s.

        Increments are clipped to the speed limits times ``duration``, and targets to the
        ranges. Returns the increments actually applied.
        """
        v_ins, v_rot = self.max_speeds()
        d_ins = float(np.clip(delta_insertion, -v_ins * duration, v_ins * duration))
        d_rot = float(np.clip(delta_rotation, -v_rot * duration, v_rot * duration))
        before = self.driver_targets()
        self.set_driver_targets(before[0] + d_ins, before[1] + d_rot)
        after = self.driver_targets()
        return after[0] - before[0], after[1] - before[1]

    # ------------------------------------------------------------------------- health
    def warnings(self) -> dict[str, int]:
        """MuJoCo warnings raised so far in this episode, by name (empty when healthy)."""
        return {
            mujoco.mjtWarning(i).name: int(w.number)
            for i, w in enumerate(self.data.ptr.warning)
            if w.number > 0
        }

    def is_finite(self) -> bool:
        """Whether positions and velocities are all finite."""
        # A NaN or inf anywhere makes the sum non-finite: one reduction per array.
        data = self.data.ptr
        return math.isfinite(float(data.qpos.sum())) and math.isfinite(float(data.qvel.sum()))
