"""A beating and breathing heart: kinematic motion of the vessel wall.

The wall's hulls are grouped into chunks of at most :data:`CHUNK_SIZE` (each a MuJoCo mocap
body, :func:`sim4endor.models.scene.build_spec` with ``moving_walls``), and every chunk moves
rigidly with the displacement of its centroid:

* **Respiration** (Lujan et al., Med Phys 26(5):715-720, 1999: ``z(t) = z0 - b cos^4(pi t /
  tau - phi)``, most of a breath near end-expiration): at full inspiration the heart has
  moved ``caudal`` towards the feet, ``anterior`` forwards and turned ``rotation`` about the
  patient's left-right axis (Shechter et al., IEEE TMI 23(8):1046-1056, 2004: 4.9 +- 1.9 mm
  caudal, range 2.4-8.0; 1.3 +- 1.8 mm anterior; 1.5 +- 0.9 deg, range 0.2-3.5).
* **The heartbeat**: in systole the tree contracts towards the heart's centre (the
  centroid of its wall) by ``cardiac_strain``, a uniform strain, so its vessels shorten by
  as much; in early diastole it returns, and rests until the next beat. 4-8 % gives a point
  80 mm along the tree 3.2-6.4 mm of end-diastolic to end-systolic displacement relative to
  the ostium (the coronaries move 2.8-6.6 mm per axis, Tan et al. 2013; the rest period
  shrinks as the rate rises, Otton et al. 2013).

The guide catheter is seated in the ostium, so the wire's proximal end moves with it: the
physics runs in the catheter's frame, where the tree turns about the ostium and contracts
towards it (a contraction about the centre is one about the ostium plus the ostium's own
translation). The translations that carry catheter and tree together, the breath's and the
ostium's in systole, are what the fluoroscope sees besides (:meth:`WallMotion.lab_offset`),
so a roadmap drawn on the still image drifts off the moving one.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from sim4endor._checks import require_ranges
from sim4endor.errors import Sim4EndoRError

FloatArray = NDArray[np.float64]

#: Largest extent (m) of a chunk of hulls that moves rigidly: neighbouring chunks then part
#: by at most the strain times this (0.24 mm at a systole's 8 % over 3 mm, about a coronary
#: wire's 0.18 mm radius; overlapping hulls leave a ridge, not a gap). Measured on a coronary
#: tree: 50-200 mocap bodies cost 1.15-1.25 times a static wall on identical trajectories,
#: one body per hull (1,846) 2.5 times.
CHUNK_SIZE = 0.003
#: Mechanical systole (s) and the rapid filling after it (s); diastasis rests until the next
#: beat: at 60 bpm 0.55 s of rest, at 100 bpm 0.15 s.
SYSTOLE = 0.30
RAPID_FILLING = 0.15


class MotionError(Sim4EndoRError, ValueError):
    """Raised for a range of the heart's motion that cannot be drawn from; names it."""


@dataclass(frozen=True)
class HeartMotion:
    """One episode's motion.

    Attributes:
        heart_rate: Beats per minute.
        breathing_rate: Breaths per minute.
        cardiac_phase: Where in its beat the heart starts (fraction of a beat).
        respiratory_phase: Where in its breath it starts (fraction of a breath).
        cardiac_strain: The tree's systolic contraction (a fraction of its size).
        caudal: Respiratory displacement towards the feet at full inspiration (m).
        anterior: Respiratory displacement forwards at full inspiration (m).
        rotation: Respiratory turn about the left-right axis at full inspiration (rad).
    """

    heart_rate: float
    breathing_rate: float
    cardiac_phase: float
    respiratory_phase: float
    cardiac_strain: float
    caudal: float
    anterior: float
    rotation: float

    def later(self, seconds: float) -> HeartMotion:
        """The same motion with its clock ``seconds`` ahead: its time 0 is this one's
        ``seconds`` (an episode whose clock restarts after the wall has moved)."""
        return dataclasses.replace(
            self, cardiac_phase=(self.cardiac_phase + seconds * self.heart_rate / 60.0) % 1.0,
            respiratory_phase=(self.respiratory_phase
                               + seconds * self.breathing_rate / 60.0) % 1.0)

    def cardiac(self, time: float) -> float:
        """The heartbeat's displacement at ``time`` (s) as a fraction of its amplitude."""
        period = 60.0 / self.heart_rate
        t = ((time / period + self.cardiac_phase) % 1.0) * period
        if t < SYSTOLE:
            return 0.5 * (1.0 - math.cos(math.pi * t / SYSTOLE))
        if t < SYSTOLE + RAPID_FILLING:
            return 0.5 * (1.0 + math.cos(math.pi * (t - SYSTOLE) / RAPID_FILLING))
        return 0.0

    def respiratory(self, time: float) -> float:
        """The breath's displacement at ``time`` (s) as a fraction of full inspiration."""
        return math.cos(math.pi * (time * self.breathing_rate / 60.0
                                   + self.respiratory_phase)) ** 4


@dataclass(frozen=True)
class MotionRanges:
    """The ranges each episode's :class:`HeartMotion` is drawn from, uniformly (sources in
    the module's docstring and docs/tasks/cathlab.md)."""

    heart_rate: tuple[float, float] = (60.0, 100.0)
    breathing_rate: tuple[float, float] = (12.0, 20.0)
    cardiac_strain: tuple[float, float] = (0.04, 0.08)
    caudal: tuple[float, float] = (2.4e-3, 8.0e-3)
    anterior: tuple[float, float] = (0.0, 3.0e-3)
    rotation: tuple[float, float] = (math.radians(0.2), math.radians(3.5))

    def __post_init__(self) -> None:
        require_ranges(self, "motion", MotionError,
                       tuple(field.name for field in dataclasses.fields(self)))

    def draw(self, random: np.random.RandomState) -> HeartMotion:
        """One episode's motion, its phases uniform over a beat and a breath."""
        return HeartMotion(
            heart_rate=random.uniform(*self.heart_rate),
            breathing_rate=random.uniform(*self.breathing_rate),
            cardiac_phase=random.uniform(),
            respiratory_phase=random.uniform(),
            cardiac_strain=random.uniform(*self.cardiac_strain),
            caudal=random.uniform(*self.caudal),
            anterior=random.uniform(*self.anterior),
            rotation=random.uniform(*self.rotation),
        )


def _rotation(axis: FloatArray, angle: float) -> FloatArray:
    """The rotation matrix of ``angle`` (rad) about the unit ``axis``."""
    quat, matrix = np.zeros(4), np.zeros(9)
    mujoco.mju_axisAngle2Quat(quat, axis, angle)
    mujoco.mju_quat2Mat(matrix, quat)
    return matrix.reshape(3, 3)


class WallMotion:
    """Where each chunk of the wall is at a time, in the guide catheter's frame."""

    def __init__(self, motion: HeartMotion, centroids: FloatArray, ostium: FloatArray,
                 patient_axes: FloatArray) -> None:
        """
        Args:
            motion: The episode's motion.
            centroids: (K, 3) every chunk's centroid at rest (m, vessel frame).
            ostium: The inlet (m, vessel frame), where the catheter sits.
            patient_axes: (3, 3) the vessel frame's axes in the patient's (rows; LPS).
        """
        self.motion = motion
        self.centroids, self.ostium = centroids, ostium
        self.patient_axes = patient_axes
        self._centre = centroids.mean(axis=0)
        # The patient's axes in the vessel frame: columns of patient_axes' transpose.
        lps = np.asarray(patient_axes, dtype=np.float64).T
        self._left, self._posterior, self._superior = lps[0], lps[1], lps[2]

    def pose(self, time: float) -> tuple[FloatArray, FloatArray]:
        """The chunks' mocap positions (K, 3) and the rotation (3, 3) they share at ``time``:
        a chunk's geoms, placed at rest with its body at the origin, move to
        ``position + rotation @ rest``."""
        motion = self.motion
        rotation = self._turn(time)
        scale = 1.0 - motion.cardiac_strain * motion.cardiac(time)
        moved = self.ostium + scale * (self.centroids - self.ostium) @ rotation.T
        return moved - self.centroids @ rotation.T, rotation

    def _turn(self, time: float) -> FloatArray:
        """The breath's turn (3, 3) about the left-right axis through the ostium."""
        return _rotation(self._left, -self.motion.rotation * self.motion.respiratory(time))

    def lab_offset(self, time: float) -> FloatArray:
        """How far the catheter's frame (ostium, wire, tree) has moved in the lab at
        ``time``: the respiratory translation, which the fluoroscope sees (m)."""
        motion = self.motion
        breath = motion.respiratory(time)
        systole = motion.cardiac_strain * motion.cardiac(time)
        return (breath * (-motion.caudal * self._superior - motion.anterior * self._posterior)
                + systole * (self._centre - self.ostium))

    def later(self, seconds: float) -> WallMotion:
        """This wall's motion with its clock ``seconds`` ahead (:meth:`HeartMotion.later`)."""
        return WallMotion(self.motion.later(seconds), self.centroids, self.ostium,
                          self.patient_axes)

    def to_rest(self, point: FloatArray, time: float) -> FloatArray:
        """``point`` (m, catheter frame) carried back to the still tree by the rigid motion
        of the chunk nearest it."""
        positions, rotation = self.pose(time)
        moved = positions + self.centroids @ rotation.T
        k = int(np.argmin(((moved - point) ** 2).sum(axis=1)))
        return self.centroids[k] + rotation.T @ (point - moved[k])

    def from_rest(self, point: FloatArray, time: float) -> FloatArray:
        """A point of the still tree (m) where the chunk nearest it has carried it at
        ``time`` (a target's marker in a video)."""
        positions, rotation = self.pose(time)
        k = int(np.argmin(((self.centroids - point) ** 2).sum(axis=1)))
        return positions[k] + rotation @ point

    def rest_rotation(self, time: float) -> FloatArray:
        """The rotation (3, 3) that carries directions back to the still tree."""
        return self._turn(time).T
