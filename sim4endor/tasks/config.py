"""Typed configuration of the navigation MDP: action scaling, observations, termination."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim4endor._checks import is_number, require, require_ranges
from sim4endor.errors import Sim4EndoRError
from sim4endor.models.motion import MotionRanges
from sim4endor.observations import (  # noqa: F401  (re-exported: the task's vocabulary)
    BIPLANE_OBSERVATIONS,
    DEFAULT_OBSERVATIONS,
    OBSERVATION_SETS,
    OBSERVATION_UNITS,
    OPTIONAL_OBSERVATIONS,
)
from sim4endor.rewards import RewardConfig


class TaskConfigError(Sim4EndoRError, ValueError):
    """Raised for an invalid task setting; the message names it and the valid choices."""


@dataclass(frozen=True)
class ActionConfig:
    """How a normalised action ``a in [-1, 1]^2`` becomes a robot command.

    ``a[0] * max_insertion_step`` is the insertion increment Δd (m, positive inserts) and
    ``a[1] * max_rotation_step`` the rotation increment Δθ (rad, about the wire axis) applied
    per control step. The defaults at 20 Hz give at most 30 mm/s and 180 °/s, enough for the
    paper's 5–8 s completion times on the ~100 mm paths of the simplified phantom.

    Attributes:
        control_timestep: Seconds of simulated time per control step (20 Hz).
        max_insertion_step: Largest |Δd| per control step (m).
        max_rotation_step: Largest |Δθ| per control step (rad).
    """

    control_timestep: float = 0.05
    max_insertion_step: float = 1.5e-3
    max_rotation_step: float = math.radians(9.0)

    def __post_init__(self) -> None:
        require(self, "ActionConfig", TaskConfigError,
                positive=("control_timestep", "max_insertion_step", "max_rotation_step"))

    def physics_steps(self, timestep: float) -> int:
        """Physics steps of ``timestep`` (s) in one control step (at least one)."""
        return max(1, round(self.control_timestep / timestep))


@dataclass(frozen=True)
class TerminationConfig:
    """When an episode ends early (time limit: ``time_limit``; success: the reward's threshold).

    Failure states (paper: "exceeding operational limits and colliding with vessel walls"),
    each ending the episode with the -100 penalty and discount 0:

    * ``tip_force``: normal force of the pre-bent tip's segments on the vessel wall above
      ``max_tip_force`` (N); with ``tip_force_mean`` its mean over the control step, the
      quasi-static force as a puncture force is measured, not the mass-scaled wire's impact
      transient (:meth:`~sim4endor.physics.GuidewirePhysics.mean_tip_contact_force`). The
      tip is what can perforate a vessel; the shaft of a wire in a tortuous vessel presses on
      every bend without harm (on the vascular phantom a straight insertion puts over 2.5 N
      in total on the wall for about 0.4 N at the tip), so the total wall force is reported
      (``wall_force``) but does not end the episode;
    * ``outside_lumen``: the tip further than ``lumen_margin`` (m) outside the lumen surface
      (:func:`~sim4endor.tasks.navigation.lumen_excess`: the centerline's tubes where they
      hold the tip, the surface itself elsewhere);
    * ``insertion_limit``: the commanded insertion beyond ``max_insertion`` (m; default: the
      end of the driver's travel). Retracting to the home position (insertion 0) is a hard
      stop of the carriage, not a failure;
    * ``rotation_limit``: the commanded rotation beyond ±``max_rotation`` (rad; default: the
      driver's rotation range);
    * ``instability``: a non-finite state or a MuJoCo warning during the step;
    * ``push_force``: the driver pushing the wire in harder than ``max_push_force`` (N), the
      largest push the model is validated to hold. The default driver's force limit is 0.5 N,
      so this ends an episode only on a driver configured to push harder. Measured
      (``guidewire_validation.py``, key ``push_robustness``): pushed into a dead end without
      this check, a 5 N driver blew the simulation up (NaN) and a 2 N one pressed the wall
      with tens of newtons; with it, the episode ends with this failure first.

    Attributes:
        time_limit: Simulated seconds per episode (truncation, discount 1).
        max_tip_force: Tip force threshold (N).
        lumen_margin: Allowed tip excursion beyond the lumen radius (m).
        max_insertion: Largest commanded insertion (m) before the episode fails; ``None``
            uses the driver's insertion range.
        max_rotation: Largest |commanded rotation| (rad) before the episode fails; ``None``
            uses the driver's rotation range.
        max_push_force: Largest insertion force of the driver (N) before the episode fails.
        tip_force_mean: The tip force (failure, step info and ``tip_force`` observation) is
            its mean over the control step; ``False``: the force at the step's end, as the
            paper's tasks were published.
    """

    time_limit: float = 20.0
    max_tip_force: float = 1.0
    lumen_margin: float = 0.5e-3
    max_insertion: float | None = None
    max_rotation: float | None = None
    max_push_force: float = 1.0
    tip_force_mean: bool = False

    def __post_init__(self) -> None:
        require(self, "TerminationConfig", TaskConfigError,
                positive=("time_limit", "max_tip_force", "lumen_margin", "max_insertion",
                          "max_rotation", "max_push_force"))


@dataclass(frozen=True)
class InitialStateConfig:
    """How each episode's start is drawn from the task's random generator.

    The wire starts homed in the inlet, rolled by an angle drawn uniformly from
    ``±rotation_range`` and advanced by a depth drawn uniformly from ``[0, insertion_range]``.
    Without it every episode of a fixed anatomy starts identically, so a deterministic
    policy's evaluation trials would all be the same episode. The roll is observable through
    the tip position: the pre-bent tip sits off the vessel axis in its bend direction.

    With ``off_path_depth`` set (the ``*_redirect`` tasks) the episode starts where a wrong
    turn left the wire: from that start, the scripted expert's steering
    (:class:`~sim4endor.tasks.steering.CenterlineSteering`) drives it towards another labelled
    target of the vessel, drawn per episode, until the tip lies a depth drawn uniformly from
    ``off_path_depth`` off the path to the task's target, i.e. that far down the branch where
    the two paths part; then the drawn roll is turned in at the carriage's top speed. Reaching
    the target then takes a pull-back, a turn and a push that depend on where the tip is, which
    no constant action gives.

    Attributes:
        rotation_range: Half-width of the initial roll interval (rad).
        insertion_range: Largest initial insertion (m).
        off_path_depth: ``(lowest, highest)`` depth (m) of a wrong-branch start; ``None``
            starts at the inlet.
    """

    rotation_range: float = math.radians(30.0)
    insertion_range: float = 1.0e-3
    off_path_depth: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if isinstance(self.off_path_depth, list):  # as read from YAML or JSON
            object.__setattr__(self, "off_path_depth", tuple(self.off_path_depth))
        require(self, "InitialStateConfig", TaskConfigError,
                non_negative=("rotation_range", "insertion_range"),
                positive=("off_path_depth",))
        depth = self.off_path_depth
        if depth is not None and (len(depth) != 2 or depth[0] > depth[1]):
            raise TaskConfigError(
                f"InitialStateConfig.off_path_depth must be (lowest, highest) in m with "
                f"lowest <= highest, e.g. (0.005, 0.02), got {depth!r}."
            )


#: The ``*_redirect`` tasks' start: 5-20 mm down another target's branch, rolled anywhere on the
#: circle. Deeper starts on the vascular phantom leave the tip in a tight bend that the expert
#: cannot always back out of under the 1 N tip-force limit (docs/tasks/index.md).
WRONG_BRANCH_START = InitialStateConfig(rotation_range=math.pi, off_path_depth=(0.005, 0.02))


@dataclass(frozen=True)
class PixelsConfig:
    """The fluoroscopy-like image: an orthographic projection of lumen and wire.

    The default looks down the model's -z axis (antero-posterior view of the phantoms, which
    lie in the x–y plane); the image frames the whole centerline graph.

    Attributes:
        height: Image height (pixels).
        width: Image width (pixels).
        view_direction: Direction the "X-ray" travels, in the vessel frame.
        up: Direction shown upwards in the image (made orthogonal to ``view_direction``).
    """

    height: int = 64
    width: int = 64
    view_direction: tuple[float, float, float] = (0.0, 0.0, -1.0)
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def __post_init__(self) -> None:
        require(self, "PixelsConfig", TaskConfigError, positive=("height", "width"))
        if self.height < 8 or self.width < 8:
            raise TaskConfigError(f"PixelsConfig: images must be >= 8x8, got {self}.")
        if abs(float(np.dot(_unit(self.view_direction), _unit(self.up)))) > 0.99:
            raise TaskConfigError("PixelsConfig: up must not be parallel to view_direction.")


#: Clinical coronary views, (primary, secondary) C-arm angles in degrees with DICOM's signs
#: (primary positive = LAO, secondary positive = cranial): the standard projections of the
#: left tree (RAO caudal, RAO cranial, AP cranial, LAO cranial, LAO caudal "spider") and of
#: the right (LAO, RAO). Sources: docs/tasks/cathlab.md.
CORONARY_VIEWS: tuple[tuple[float, float], ...] = (
    (-30.0, -25.0),
    (-30.0, 30.0),
    (0.0, 30.0),
    (45.0, 25.0),
    (45.0, -30.0),
    (30.0, 0.0),
    (-30.0, 0.0),
)


#: Patient axes of a frame that is already LPS (x left, y posterior, z superior).
LPS_AXES: tuple[tuple[float, float, float], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0),
                                                    (0.0, 0.0, 1.0))
#: A phantom lying face up: its x to the patient's left, its y to the head, its z anterior.
PHANTOM_AXES: tuple[tuple[float, float, float], ...] = ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0),
                                                        (0.0, -1.0, 0.0))


@dataclass(frozen=True)
class CathLabConfig:
    """What a cath-lab robot measures (:mod:`sim4endor.tasks.cathlab`): fluoroscopic tracking
    of the wire, the roadmap, the driver's load cell. The figures and their sources are in
    docs/tasks/cathlab.md.

    Attributes:
        views: C-arm angles (primary, secondary; deg, LAO and cranial positive) of which each
            episode draws one.
        patient_axes: The vessel frame's x, y and z axes in the patient's axes (x left, y
            posterior, z superior: DICOM's LPS), which the angles refer to. The identity
            suits a CTA in LPS; the phantoms lie on the table face up (their x-y plane the
            coronal plane). The generated trees have no orientation in a patient: the views
            then look at them from the clinical angles about their own axes.
        view_jitter: Half-width of the uniform jitter added to both angles (deg).
        biplane: A second plane (the ``*_b`` entries), drawn from the views whose beam is at
            least ``cathlab.BIPLANE_SEPARATION`` degrees from the first's.
        frame_rate: Fluoroscopy pulses per second; the image holds between pulses.
        latency: Seconds from a pulse to its track reaching the policy.
        tracking_noise: Standard deviation of each tracked image coordinate (m at the
            isocentre).
        dropout: Probability that the tracker loses the wire in a frame (the last track is
            kept and ``tracking_age`` grows).
        load_cell_noise: Standard deviation of the proximal load cell (N).
        roadmap_error: Standard deviation of the roadmap's registration to the image, a
            shift of each image coordinate drawn per episode and plane (m at the isocentre).
        match_window: How far along the roadmap (m) the match to the tracked tip may move in
            one frame, so that it does not jump to a branch the image overlaps.
    """

    views: tuple[tuple[float, float], ...] = CORONARY_VIEWS
    patient_axes: tuple[tuple[float, float, float], ...] = LPS_AXES
    view_jitter: float = 5.0
    biplane: bool = False
    frame_rate: float = 7.5
    latency: float = 0.1
    tracking_noise: float = 0.4e-3
    dropout: float = 0.02
    load_cell_noise: float = 0.01
    roadmap_error: float = 1.0e-3
    match_window: float = 0.02

    def __post_init__(self) -> None:
        views = self.views
        if isinstance(views, list):  # as read from YAML or JSON
            views = tuple(tuple(view) if isinstance(view, list) else view for view in views)
            object.__setattr__(self, "views", views)
        if not views or not all(isinstance(v, tuple) and len(v) == 2 and all(
                is_number(a) and abs(a) <= 90.0 for a in v) for v in views):
            raise TaskConfigError(
                f"CathLabConfig.views must be (primary, secondary) C-arm angles in degrees "
                f"within ±90, e.g. ((-30, -25), (45, 25)), got {views!r}."
            )
        axes = self.patient_axes
        if isinstance(axes, list):
            axes = tuple(tuple(axis) if isinstance(axis, list) else axis for axis in axes)
            object.__setattr__(self, "patient_axes", axes)
        matrix = np.asarray(axes, dtype=np.float64) if all(
            isinstance(axis, tuple) and len(axis) == 3 and all(map(is_number, axis))
            for axis in axes) and len(axes) == 3 else np.zeros((3, 3))
        if not (np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-6)
                and np.linalg.det(matrix) > 0):
            raise TaskConfigError(
                f"CathLabConfig.patient_axes must be the vessel frame's three axes in LPS "
                f"patient axes, a rotation (orthonormal rows, determinant +1), got {axes!r}."
            )
        if not isinstance(self.biplane, bool):
            raise TaskConfigError(f"CathLabConfig.biplane must be true or false, got "
                                  f"{self.biplane!r}.")
        require(self, "CathLabConfig", TaskConfigError,
                non_negative=("view_jitter", "latency", "tracking_noise", "load_cell_noise",
                              "roadmap_error"),
                positive=("frame_rate", "match_window"),
                fraction=("dropout",))
        if self.dropout >= 1.0:
            raise TaskConfigError(f"CathLabConfig.dropout must be below 1 (a tracker that "
                                  f"never finds the wire), got {self.dropout!r}.")


def _unit(vector: tuple[float, float, float]) -> np.ndarray:
    v = np.asarray(vector, dtype=np.float64)
    norm = float(np.linalg.norm(v))
    if norm == 0.0:
        raise TaskConfigError(f"PixelsConfig: direction {vector} has zero length.")
    return v / norm


@dataclass(frozen=True)
class Randomisation:
    """Domain randomisation for sim-to-real (:mod:`sim4endor.tasks.randomisation`): the
    ranges drawn per episode (each ``(lowest, highest)``, drawn uniformly).

    Attributes:
        tracking_noise: Of each tracked image coordinate's standard deviation (m).
        latency: Of the track's latency (s).
        dropout: Of the fraction of frames the tracker loses.
        frame_rates: Pulse rates to draw from (1/s).
        roadmap_error: Of the roadmap registration's standard deviation (m).
        action_delay: Of the control steps a command waits before the driver moves (whole
            steps, both ends included).
        roll_backlash: Of the roll's dead band (rad).
        insertion_slip: Of the fraction of each commanded advance lost to slip.
    """

    tracking_noise: tuple[float, float] = (0.2e-3, 1.0e-3)
    latency: tuple[float, float] = (0.05, 0.25)
    dropout: tuple[float, float] = (0.0, 0.05)
    frame_rates: tuple[float, ...] = (7.5, 15.0)
    roadmap_error: tuple[float, float] = (0.5e-3, 2.0e-3)
    action_delay: tuple[int, int] = (0, 2)
    roll_backlash: tuple[float, float] = (0.0, math.radians(2.0))
    insertion_slip: tuple[float, float] = (0.0, 0.1)

    def __post_init__(self) -> None:
        require_ranges(self, "Randomisation", TaskConfigError,
                       ("tracking_noise", "latency", "dropout", "roadmap_error", "action_delay",
                        "roll_backlash", "insertion_slip"))
        if isinstance(self.frame_rates, list):  # as read from YAML or JSON
            object.__setattr__(self, "frame_rates", tuple(self.frame_rates))
        if self.dropout[1] >= 1.0 or self.insertion_slip[1] >= 1.0:
            raise TaskConfigError("Randomisation: dropout and insertion_slip must stay below 1.")
        if not self.frame_rates or min(self.frame_rates) <= 0:
            raise TaskConfigError(f"Randomisation.frame_rates must be positive pulse rates, "
                                  f"got {self.frame_rates!r}.")


#: The ranges of ``task_kwargs={"randomise": True}``.
RANDOMISATION = Randomisation()


@dataclass(frozen=True)
class NavigationConfig:
    """Everything a navigation task needs besides the anatomy.

    Attributes:
        action: Action scaling and control frequency.
        reward: The paper's reward constants and metric.
        termination: Failure thresholds and time limit.
        initial_state: Randomisation of each episode's start.
        observations: Observation entries, defaults first (see ``OPTIONAL_OBSERVATIONS``).
        pixels: Image settings, used when ``"pixels"`` is observed.
        cathlab: The cath lab's sensors, used by the entries of ``CATHLAB_OBSERVATIONS``.
        randomisation: Ranges of the sensors and the driver drawn per episode
            (:mod:`sim4endor.tasks.randomisation`); ``None``: none drawn.
        motion: Ranges of the heart's beat and breath drawn per episode
            (:mod:`sim4endor.models.motion`; the scene needs ``moving_walls``); ``None``: a
            still heart.
    """

    action: ActionConfig = field(default_factory=ActionConfig)
    reward: RewardConfig = field(default_factory=RewardConfig)
    termination: TerminationConfig = field(default_factory=TerminationConfig)
    initial_state: InitialStateConfig = field(default_factory=InitialStateConfig)
    observations: tuple[str, ...] = DEFAULT_OBSERVATIONS
    pixels: PixelsConfig = field(default_factory=PixelsConfig)
    cathlab: CathLabConfig = field(default_factory=CathLabConfig)
    randomisation: Randomisation | None = None
    motion: MotionRanges | None = None

    def __post_init__(self) -> None:
        valid = DEFAULT_OBSERVATIONS + OPTIONAL_OBSERVATIONS
        unknown = [o for o in self.observations if o not in valid]
        if unknown:
            raise TaskConfigError(f"Unknown observations {unknown}; valid: {list(valid)}.")
        if len(set(self.observations)) != len(self.observations):
            raise TaskConfigError(f"Observations listed twice: {list(self.observations)}.")
        second = [o for o in self.observations if o in BIPLANE_OBSERVATIONS]
        if second and not self.cathlab.biplane:
            raise TaskConfigError(
                f"Observations {second} are a biplane lab's second plane; set "
                "task_kwargs cathlab={'biplane': True} or drop them."
            )
