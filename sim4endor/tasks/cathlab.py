"""What a robot in a cath lab measures: the wire tracked on fluoroscopy, the roadmap, the load cell.

The privileged entries (:mod:`sim4endor.tasks.tip_frame`) read the 3D tip registered to the
CTA and the wall's forces, which no robot has. This sensor model sees the procedure as the
cath lab does:

* **Fluoroscopy.** A C-arm at one of the clinical coronary views, drawn per episode and
  jittered, projects the wire onto its image (orthographic, metres at the isocentre, the
  patient's left to the right of an AP image and the head up). It pulses ``frame_rate``
  times a second; a tracker finds the tip and the wire behind it in each frame with
  Gaussian noise, loses them with probability ``dropout`` (the last track stays), and its
  result reaches the policy ``latency`` seconds after the pulse. Optionally biplane.
* **The roadmap.** The preoperative centerline route from the inlet to the target,
  projected onto the same image and registered to it with an error drawn per episode. The
  tracked tip is matched to it in the image (the nearest route point, searched within
  ``match_window`` of the last match, so that a branch the projection overlaps does not
  capture it); what lies ahead of the match is the route to follow, and the route's length
  from there the distance left.
* **The driver.** Its encoders (the task's ``insertion`` and ``rotation`` entries) and the
  load cell between the driver and the wire, with Gaussian noise.

Everything here is computed from a :class:`Measurement`, which holds only what those
sensors see; the task builds it from the physics' wire points (what the X-ray images), the
driver's encoders, its axial force and the clock, and a test proves that an observation of
these entries reads no other state. The figures behind the defaults are in
docs/tasks/cathlab.md.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim4endor.observations import (
    DISTANCE_HORIZON,
    FORCE_HORIZON,
    PATH_POINTS,
    PATH_SPACING,
    STALL_HORIZON,
    STALL_PROGRESS,
    TRACKED_POINTS,
    TRACKED_SPACING,
    TRACKING_HORIZON,
)
from sim4endor.tasks.config import CathLabConfig, TaskConfigError
from sim4endor.vessels.centerline import arc_lengths, points_along

FloatArray = NDArray[np.float64]

#: A biplane lab's second beam is at least this far (deg) from the first: the two planes of
#: a biplane coronary run are set roughly orthogonal, so that each shows what the other
#: foreshortens.
BIPLANE_SEPARATION = 45.0
#: Largest spacing (m) at which the roadmap's route is resampled for matching.
_ROADMAP_STEP = 0.25e-3


@dataclass(frozen=True)
class Measurement:
    """What the cath lab's sensors see at one control step.

    Attributes:
        time: Episode time (s).
        wire_points: The wire's centreline, proximal first, tip last (m, vessel frame): what
            the X-ray images; only its projection is used.
        axial_force: The driver's axial load on the wire (N, positive pushing).
    """

    time: float
    wire_points: FloatArray
    axial_force: float


@dataclass(frozen=True)
class CathLabView:
    """The cath lab's observation entries at one control step (image axes, m at isocentre).

    Attributes:
        tracked_wire: (planes, TRACKED_POINTS, 2) tracked wire points behind the tip,
            relative to the tracked tip.
        roadmap_offset: (planes, 2) from the tracked tip to its match on the roadmap.
        roadmap_ahead: (planes, PATH_POINTS, 2) roadmap points ahead of the match, relative
            to the tracked tip.
        roadmap_remaining: Route length from the match to the target (m), saturated.
        roadmap_stall: Seconds since the match last advanced 1 mm beyond its furthest.
        tracking_age: (planes,) age of each plane's shown track (s): latency, the time
            between pulses and frames the tracker lost.
        proximal_force: The load cell's reading (N).
    """

    tracked_wire: FloatArray
    roadmap_offset: FloatArray
    roadmap_ahead: FloatArray
    roadmap_remaining: float
    roadmap_stall: float
    tracking_age: FloatArray
    proximal_force: float


def beam_direction(primary: float, secondary: float) -> FloatArray:
    """The X-ray's direction of travel (source to detector) for C-arm angles in degrees
    (primary positive LAO, secondary positive cranial), in LPS patient axes (x left, y
    posterior, z superior): AP is anterior-going, (0, -1, 0)."""
    a, b = math.radians(primary), math.radians(secondary)
    return np.array([math.sin(a) * math.cos(b), -math.cos(a) * math.cos(b), math.sin(b)])


def image_basis(beam: FloatArray) -> FloatArray:
    """Rows: the image's right and up axes for a beam, as displayed (the patient's head up,
    the patient's left to the right of an AP image)."""
    up = np.array([0.0, 0.0, 1.0]) - beam * beam[2]
    up /= np.linalg.norm(up)
    return np.stack([np.cross(up, beam), up])


class CathLab:
    """The sensor model of one task: draws its views per episode and observes each step."""

    def __init__(self, config: CathLabConfig, planes: int) -> None:
        """Checks that the views allow ``planes`` planes (1, or 2 for a biplane lab)."""
        self.config = config
        # This episode's settings: the lab's own, or a randomised draw of them.
        self.sensors = config
        self.planes = planes
        beams = [beam_direction(*view) for view in config.views]
        if planes == 2 and not any(self._separated(a, b) for a in beams for b in beams):
            raise TaskConfigError(
                f"CathLabConfig.views {config.views!r} hold no two views "
                f"{BIPLANE_SEPARATION:g} deg apart for a biplane lab; add one."
            )
        self._bases = np.zeros((planes, 2, 3))
        self._random = np.random.RandomState(0)
        self._frames: collections.deque[tuple[float, FloatArray, FloatArray]] = \
            collections.deque()
        self._next_pulse = 0.0
        self._last_track = np.zeros((planes, TRACKED_POINTS + 1, 2))
        self._found_at = np.zeros(planes)
        self._route_arc = np.zeros(0)
        self._roadmap = np.zeros((planes, 0, 2))
        self._match = 0.0
        self._frames_matched = False
        self._furthest = 0.0
        self._furthest_time = 0.0
        self._view: tuple[float, CathLabView] | None = None
        self._tracked_tip = np.zeros((planes, 2))

    @staticmethod
    def _separated(a: FloatArray, b: FloatArray) -> bool:
        return float(np.dot(a, b)) <= math.cos(math.radians(BIPLANE_SEPARATION))

    def reset(self, route: FloatArray, random: np.random.RandomState,
              config: CathLabConfig | None = None) -> None:
        """Starts an episode: draws the views and the sensors' noise seed from ``random``.

        Args:
            route: (M, 3) the preoperative centerline route from the inlet to the target
                (m, vessel frame): the roadmap.
            random: The task's generator.
            config: This episode's sensors (a randomised draw), if not the lab's own.
        """
        self.sensors = config or self.config
        self._random = np.random.RandomState(random.randint(2**31))
        beams = [self._draw_beam()]
        while len(beams) < self.planes:
            beam = self._draw_beam()
            if self._separated(beam, beams[0]):
                beams.append(beam)
        # Image axes in the patient's frame, then in the vessel's (a vessel point's patient
        # coordinates are axes.T @ point).
        axes = np.asarray(self.sensors.patient_axes)
        self._bases = np.stack([image_basis(beam) @ axes.T for beam in beams])
        arc = arc_lengths(route)
        self._route_arc = np.linspace(0.0, arc[-1], math.ceil(arc[-1] / _ROADMAP_STEP) + 1)
        self._roadmap = self.image(points_along(route, self._route_arc)) + \
            self._random.normal(0.0, self.sensors.roadmap_error, (self.planes, 1, 2))
        self._frames.clear()
        self._next_pulse = -math.inf
        self._match = self._furthest = self._furthest_time = 0.0
        self._frames_matched = False
        self._view = None

    def image(self, points: FloatArray) -> FloatArray:
        """(planes, N, 2): vessel-frame points (m) as this episode's planes show them."""
        return np.einsum("pij,mj->pmi", self._bases, points)

    @property
    def tracked_tip(self) -> FloatArray:
        """(planes, 2): where on each plane the last observation's tracked tip lies (m), which
        the entries are relative to (for drawing; a policy is not told it)."""
        return self._tracked_tip

    @property
    def roadmap(self) -> FloatArray:
        """(planes, M, 2): this episode's roadmap on each plane, with its registration error."""
        return self._roadmap

    def _draw_beam(self) -> FloatArray:
        views, jitter = self.sensors.views, self.sensors.view_jitter
        primary, secondary = views[self._random.randint(len(views))]
        return beam_direction(primary + self._random.uniform(-jitter, jitter),
                              secondary + self._random.uniform(-jitter, jitter))

    def observe(self, measurement: Measurement) -> CathLabView:
        """The entries at ``measurement``'s time; one view per control step, however often
        it is asked (the sensors' noise is drawn once per pulse and reading)."""
        if self._view is not None and self._view[0] == measurement.time:
            return self._view[1]
        if measurement.time >= self._next_pulse:
            self._pulse(measurement)
        track, found_at = self._shown(measurement.time)
        tip = self._tracked_tip = track[:, -1]
        self._match_roadmap(tip)
        if self._match > self._furthest + STALL_PROGRESS:
            self._furthest, self._furthest_time = self._match, measurement.time
        ahead = self._roadmap_at(self._match + PATH_SPACING * np.arange(1, PATH_POINTS + 1))
        force = measurement.axial_force + self._random.normal(0.0, self.sensors.load_cell_noise)
        view = CathLabView(
            tracked_wire=track[:, -2::-1] - tip[:, None],
            roadmap_offset=self._roadmap_at(np.array([self._match]))[:, 0] - tip,
            roadmap_ahead=ahead - tip[:, None],
            roadmap_remaining=min(self._route_arc[-1] - self._match, DISTANCE_HORIZON),
            roadmap_stall=min(measurement.time - self._furthest_time, STALL_HORIZON),
            tracking_age=np.minimum(measurement.time - found_at, TRACKING_HORIZON),
            proximal_force=min(max(force, -FORCE_HORIZON), FORCE_HORIZON),
        )
        self._view = (measurement.time, view)
        return view

    def _pulse(self, measurement: Measurement) -> None:
        """Images the wire and tracks it in each plane; a lost plane keeps its last track."""
        first = not self._frames
        period = 1.0 / self.sensors.frame_rate
        # The pulses run on their own clock but are imaged at control steps (the only
        # instants the state is known): the next at the first step on or after the next tick.
        self._next_pulse = (math.floor(measurement.time / period + 1e-9) + 1) * period - 1e-9
        images = self.image(measurement.wire_points)
        for plane, image in enumerate(images):
            # The first frame of an episode is always tracked: the operator starts on one.
            if first or self._random.uniform() >= self.sensors.dropout:
                self._last_track[plane] = self._track(image)
                self._found_at[plane] = measurement.time
        self._frames.append((measurement.time, self._last_track.copy(), self._found_at.copy()))

    def _track(self, image: FloatArray) -> FloatArray:
        """(TRACKED_POINTS + 1, 2): the tracked wire, proximal first and the tip last."""
        backwards = image[::-1]
        points = points_along(backwards, TRACKED_SPACING * np.arange(TRACKED_POINTS + 1))[::-1]
        return points + self._random.normal(0.0, self.sensors.tracking_noise, points.shape)

    def _shown(self, time: float) -> tuple[FloatArray, FloatArray]:
        """The newest frame whose track has reached the policy by ``time`` (the episode's
        first frame until one has)."""
        ready = time - self.sensors.latency + 1e-9
        while len(self._frames) > 1 and self._frames[1][0] <= ready:
            self._frames.popleft()
        _, track, found_at = self._frames[0]
        return track, found_at

    def _match_roadmap(self, tip: FloatArray) -> None:
        """Moves the match to the route point nearest the tracked tip in every plane,
        within ``match_window`` of the last match (anywhere at the episode's first)."""
        if self._frames_matched:
            window = self.sensors.match_window
            low = int(np.searchsorted(self._route_arc, self._match - window))
            high = int(np.searchsorted(self._route_arc, self._match + window, side="right"))
        else:  # the episode's first frame: the operator finds the tip on the whole roadmap
            low, high = 0, len(self._route_arc)
        self._frames_matched = True
        cost = ((self._roadmap[:, low:high] - tip[:, None]) ** 2).sum(axis=(0, 2))
        self._match = float(self._route_arc[low + int(np.argmin(cost))])

    def _roadmap_at(self, stations: NDArray[np.floating]) -> FloatArray:
        """(planes, len(stations), 2) the projected route at arc lengths ``stations``."""
        arc = self._route_arc
        index = np.clip(np.round(stations / max(arc[-1], 1e-12) * (len(arc) - 1)), 0,
                        len(arc) - 1).astype(int)
        return self._roadmap[:, index]
