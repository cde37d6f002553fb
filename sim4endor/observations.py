"""The names, units and sizes of the navigation tasks' observation entries, and their sets.

Plain data with no MuJoCo behind it, so the training configuration (and the command line,
which must start even where an OpenGL library is missing) can check names against it.
"""

from __future__ import annotations

#: Points of the ``path_ahead`` entry, and their spacing along the route (m): 8 x 2.5 mm =
#: 20 mm, past the next bifurcation in a coronary tree once the tip is within 20 mm of it
#: (the generator's segments are 15-60 mm long) and about four times the shaped tip's length.
PATH_POINTS = 8
PATH_SPACING = 0.0025
#: The ``manifold_distance`` entry saturates here (m), the reward's distance scale
#: (``RewardConfig.distance_divisor_mm``). Steering needs the route ahead (``path_ahead``), not
#: how far beyond a decimetre the target lies; the shipped ``generalist``, trained on the
#: unsaturated distance, froze at the start of 20 of its 32 missed held-out targets, every one
#: 104-144 mm away (docs/results/generalisation/results.md).
DISTANCE_HORIZON = 0.1
#: The ``tip_force`` and ``wall_force`` entries saturate here (N), ten times the driver's
#: largest push (0.5 N). The scripted expert's wall force on tuning trees 300-303 (5,825
#: control steps) had a median of 0.02 N and a 90th percentile of 0.43 N; the 2.5 % of steps
#: above 5 N read up to 2.7 kN, the contact artefact of a shaft segment pinched in a tight bend
#: (docs/tasks/coronary.md), which would reach a network as inputs in the thousands. Saturated,
#: both entries still say "pressing hard"; the tip-force failure and the step's info read the
#: forces themselves.
FORCE_HORIZON = 5.0
#: The ``stall_time`` entry counts the episode time since the tip last came this much (m)
#: closer to the target than ever before in the episode, and saturates at ``STALL_HORIZON``
#: (s). A tip that pushes on at an ostium it does not enter makes no such progress; the
#: scripted expert counts 60 control steps (3 s) so before it tries another aim
#: (``ExpertConfig.retry_steps``). The other entries describe one instant, so a memoryless
#: policy cannot tell a first attempt at a side branch from its tenth.
STALL_PROGRESS = 0.001
STALL_HORIZON = 5.0
#: Points of the ``tracked_wire`` entry behind the tracked tip, and their spacing along the
#: wire's image (m): 4 x 2.5 mm covers the shaped tip (2-3 mm) and the shaft behind it, whose
#: bend in the image shows which way the tip points.
TRACKED_POINTS = 4
TRACKED_SPACING = 0.0025
#: The ``tracking_age`` entries saturate here (s): ten pulses at 15 per second.
TRACKING_HORIZON = 0.7

#: Observation entries every task returns: the paper's state s_t = [p_t, v_t].
DEFAULT_OBSERVATIONS: tuple[str, ...] = ("tip_position", "tip_velocity")
#: Entries computed by the cath lab's sensor model (:mod:`sim4endor.tasks.cathlab`) from the
#: fluoroscopic image, the preoperative roadmap and the driver's load cell.
CATHLAB_OBSERVATIONS: tuple[str, ...] = (
    "tracked_wire",
    "roadmap_offset",
    "roadmap_ahead",
    "roadmap_remaining",
    "roadmap_stall",
    "tracking_age",
    "proximal_force",
)
#: The cath lab's entries of one image plane, which a biplane lab's second plane repeats.
PLANE_OBSERVATIONS: tuple[str, ...] = (
    "tracked_wire", "roadmap_offset", "roadmap_ahead", "tracking_age")
#: The second plane's entries, observed when the cath lab is biplane
#: (:class:`~sim4endor.tasks.config.CathLabConfig`).
BIPLANE_OBSERVATIONS: tuple[str, ...] = tuple(f"{name}_b" for name in PLANE_OBSERVATIONS)
#: What the robot knows of its own driver: the encoders and its last command.
_DRIVER: tuple[str, ...] = ("insertion", "rotation", "last_action")
#: Entries that can be added through ``task_kwargs={"observations": (...)}``.
OPTIONAL_OBSERVATIONS: tuple[str, ...] = (
    "target_position",
    "wire_shape",
    "last_action",
    "insertion",
    "rotation",
    "manifold_distance",
    "pixels",
    "path_ahead",
    "axis_offset",
    "lumen_radius",
    "tip_velocity_local",
    "tip_force",
    "wall_force",
    "stall_time",
    *CATHLAB_OBSERVATIONS,
    *BIPLANE_OBSERVATIONS,
)
#: Every entry a robot in a cath lab can measure: the cath lab's sensors, the driver's
#: encoders and its own last command. The others read simulation state no robot sees (the
#: 3D tip registered to the CTA, the wall's forces, the lumen around the tip).
MEASURABLE_OBSERVATIONS: frozenset[str] = frozenset(
    (*CATHLAB_OBSERVATIONS, *BIPLANE_OBSERVATIONS, *_DRIVER))
#: What the tip sees in its own frame (:mod:`sim4endor.tasks.tip_frame`) plus scalars: it does
#: not change when the anatomy is rotated or translated with the wire, so nothing in it names
#: one patient's coordinates.
_GENERALIST: tuple[str, ...] = (
    "path_ahead",
    "axis_offset",
    "lumen_radius",
    "tip_velocity_local",
    "manifold_distance",
    "tip_force",
    "wall_force",
    "last_action",
)
_NO_RADIUS = tuple(name for name in _GENERALIST if name != "lumen_radius")
#: Named observation sets (``task_kwargs={"observations": "generalist"}``), each used as it
#: is, without the defaults.
OBSERVATION_SETS: dict[str, tuple[str, ...]] = {
    "paper": DEFAULT_OBSERVATIONS,
    "generalist": _GENERALIST,
    # The generalist set without the calibre. Every coronary episode starts in the guide's
    # bore (1.03 mm), a phantom episode in its own 2.0-2.4 mm tube; a policy trained on the
    # coronary starts can read a wide lumen at the start as a cue to pull back (seed 2 of
    # 2026-11-28 reached 0/12 phantom episodes, 8/12 with the entry read as the bore's:
    # docs/results/generalisation). ``axis_offset`` still gives the wall's nearness in radii.
    "generalist_no_radius": _NO_RADIUS,
    # ... and the time since the last progress, so the policy can tell a stalled attempt at
    # a side branch from a first one (see ``STALL_HORIZON``).
    "generalist_stall": (*_NO_RADIUS, "stall_time"),
    # What a robot in a cath lab measures, for a student of the privileged generalist
    # (docs/tasks/cathlab.md); a test proves that it reads no other state.
    "deployable": (*CATHLAB_OBSERVATIONS, *_DRIVER),
    "deployable_biplane": (*CATHLAB_OBSERVATIONS, *BIPLANE_OBSERVATIONS, *_DRIVER),
}

_UNITS: dict[str, tuple[str, int | None]] = {
    "tip_position": ("m", 3),
    "tip_velocity": ("m/s", 3),
    "target_position": ("m", 3),
    "wire_shape": ("m", None),
    "last_action": ("1 (normalised action)", 2),
    "insertion": ("m", 1),
    "rotation": ("rad", 1),
    "manifold_distance": ("m", 1),
    "pixels": ("grey level 0-255", None),
    "path_ahead": ("m, tip frame", 3 * PATH_POINTS),
    "axis_offset": ("lumen radii, tip frame", 3),
    "lumen_radius": ("m", 1),
    "tip_velocity_local": ("m/s, tip frame", 3),
    "tip_force": ("N", 1),
    "wall_force": ("N", 1),
    "stall_time": ("s", 1),
    "tracked_wire": ("m at the isocentre, image axes", 2 * TRACKED_POINTS),
    "roadmap_offset": ("m at the isocentre, image axes", 2),
    "roadmap_ahead": ("m at the isocentre, image axes", 2 * PATH_POINTS),
    "roadmap_remaining": ("m", 1),
    "roadmap_stall": ("s", 1),
    "tracking_age": ("s", 1),
    "proximal_force": ("N", 1),
}
#: Unit and size of each observation entry (``wire_shape`` is 3 per wire vertex); the second
#: plane's entries are the first's.
OBSERVATION_UNITS: dict[str, tuple[str, int | None]] = {
    **_UNITS, **{f"{name}_b": _UNITS[name] for name in PLANE_OBSERVATIONS}}
