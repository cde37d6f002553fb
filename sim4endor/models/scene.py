"""Scene composition with MjSpec: options + vessel + driver + sheath + guidewire.

The insertion axis starts at the vessel's manifest inlet and points along the inlet direction.
At rotation 0 the wire's pre-bent tip points towards the component of world +y orthogonal to
that axis (world +z when the axis is parallel to y), so the tip of the shipped phantoms, which
lie in the x–y plane, bends in their plane.

A compiled model is cached per (vessel folder, wire config, driver config, timestep):
compiling costs tens of milliseconds, resetting microseconds, so environments should compile
once per anatomy and reset only the state. :func:`build_model` returns a copy of the cached
model, so callers may edit their copy.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from sim4endor import assets
from sim4endor.errors import Sim4EndoRError
from sim4endor.models import constants as names
from sim4endor.models.driver import DriverConfig, add_driver, add_sheath
from sim4endor.models.guidewire import (
    FRICTION_CONES,
    INTEGRATORS,
    GuidewireConfig,
    add_guidewire,
    chain_starts,
)
from sim4endor.models.motion import CHUNK_SIZE
from sim4endor.vessels import CENTERLINE_FILE, Vessel
from sim4endor.vessels.axis import branch_chains
from sim4endor.vessels.centerline import INLET_LABEL, CenterlineGraph, arc_lengths
from sim4endor.vessels.manifest import MANIFEST_FILE
from sim4endor.vessels.mjcf_writer import WALL_CLASS

#: How wide a tapered-core wire's pre-bent tip may be, in (inlet bore radius − wire radius),
#: where the wire starts (a coronary tree's guide catheter). A soft tip starts straight in the
#: bore and takes its shape outside, so the bore does not bound the shape; a cardiologist sizes
#: the curve to the vessel proximal to the target ("roughly the length of the diameter", the
#: 1–5 mm of :data:`~sim4endor.models.wires.SHAPE_LENGTH_RANGE`), and a secondary curve to
#: the vessel's size. 6 lets a tip reach 5.11 mm sideways from the 7F guide with a 0.014 in
#: wire: every single curve the catalogue allows keeps its form (the widest, 5 mm at 90°,
#: reaches 3.18 mm; a J 2.16 mm), and so does a 2 mm/60° tip with a 40° secondary curve 7 mm
#: from the end (4.93 mm), sized to span a 3.5-3.9 mm proximal LAD or RCA and the far wall
#: of a wide parent at a side branch (docs/tasks/coronary.md, 2026-11-29, later). It was 4
#: (3.40 mm) until then, and with the cap at 3 (2.55 mm, 2026-11-27 to 2026-11-29)
#: a 5 mm/90° tip was silently narrowed to 65°; kept at 90° it took the expert to 70 of the 80
#: episodes of issue 15's check trees built as vessel folders, against 68 with 5 mm/60°
#: (docs/tasks/coronary.md, 2026-11-29). A 1 gf tip bends where a distal lumen is narrower.
#: Before 2026-11-27 the cap was 2 (1.70 mm: the bore's width); before 2026-11-26 the coronary
#: room was that of the smallest lumen drawn (1.5 mm), which held every tip to 1.14 mm, and the
#: phantoms' 0.85 of the narrowest lumen (made for the paper wire's stiff 118 gf tip) cut the
#: workhorse's 2 mm/45° tip to 28° (46 of 76 coronary tuning targets reached instead of 54).
#: Vessel folders wired with such a wire take the same rule (:func:`config_for_vessel`).
SOFT_TIP_FILL = 6.0


#: How tight a turn into a branch is taken to be, in radii of the narrowest vessel meeting at
#: the junction (:func:`segment_limits`): the tightest bend a swept tube keeps its
#: lumen through, as the coronary generator caps its bends (``max_curvature_ratio`` 0.4) and
#: the ``coronary`` domain sizes its segments for its narrowest branch.
JUNCTION_BEND_RADII = 2.5


class SceneError(Sim4EndoRError, ValueError):
    """Raised when a wire cannot be placed in a vessel; the message names the fix."""


@dataclass(frozen=True)
class SceneConfig:
    """Everything besides the anatomy that defines a compiled scene.

    Attributes:
        wire: Guidewire parameters.
        driver: Driver and sheath parameters.
        timestep: Physics time step (s); ``None`` keeps ``mjcf/options.xml`` (5 ms), or the
            wire's ``max_timestep`` where that is shorter.
        moving_walls: The wall's hulls in chunks of mocap bodies, which a beating and
            breathing heart moves (:mod:`sim4endor.models.motion`); otherwise static geoms.
    """

    wire: GuidewireConfig = field(default_factory=GuidewireConfig)
    driver: DriverConfig = field(default_factory=DriverConfig)
    timestep: float | None = None
    moving_walls: bool = False


def config_for_vessel(
    vessel: Vessel, base: SceneConfig | None = None, margin: float = 0.01,
    tip_fill: float = 0.85,
) -> SceneConfig:
    """Returns ``base`` with the insertion range, wire length, tip bend and shaft segments
    fitted to ``vessel``.

    Per-step cost grows with the number of wire segments, so the wire is only as long as the
    deepest target needs: ``max_insertion`` = the largest centerline distance from the inlet
    to a target plus ``margin``; the wire adds the protrusion and 3 mm of sheath slack.

    The tip: a uniform wire's (the ``paper`` preset's stiff 118 gf tip) is narrowed until its
    lateral offset is at most ``tip_fill`` × (narrowest lumen radius − wire radius), as the
    paper's setup needs (a 35°/5 mm tip is 1.48 mm wide; a coronary branch of 0.85 mm radius
    needs about 12°). A tapered-core wire's soft tip (the catalogue's coronary wires) bends
    where a lumen is narrower, as a real one does, so it keeps the shape given to it unless it
    is wider than :data:`SOFT_TIP_FILL` × (inlet radius − wire radius), as on the ``coronary``
    domain; narrowed to the narrowest lumen, the workhorse's 2 mm/45° tip became 28° and a
    3 mm/75° one 19° where branches end 1.5 mm across, and the probing expert reached fewer
    targets of generated coronary trees built as vessel folders (docs/tasks/coronary.md,
    Measured).

    The shaft segments are cut until each lies in every bend of the centerline and in the
    turn into every branch that it can reach (:func:`fit_segments_to_vessel`); the shipped
    phantoms keep the wire's 5 mm. The wire's straight protrusion at the start is cut where the
    vessel bends away within it (:func:`fit_protrusion`).
    """
    scene = fit_travel(vessel, fit_protrusion(vessel, base or SceneConfig()), margin)
    if scene.wire.core_profile is None:
        wire = fit_tip(scene.wire, float(vessel.centerline.radii.min()), tip_fill, vessel.name)
    else:
        wire = fit_tip(scene.wire, vessel.manifest.inlet.radius, SOFT_TIP_FILL,
                       f"{vessel.name}'s inlet")
    wire = fit_segments_to_vessel(wire, vessel.centerline, tip_reach(scene.driver))
    return dataclasses.replace(scene, wire=wire)


#: Room (m) the wire's straight protrusion at the start keeps between itself and the wall.
START_CLEARANCE = 1e-4
#: How much longer (m) than the shaped tip the protrusion stays at least, so that the tip starts
#: free of the sheath (``DriverConfig.check_wire``).
_PROTRUSION_OVER_TIP = 5e-4


def fit_protrusion(vessel: Vessel, base: SceneConfig) -> SceneConfig:
    """Returns ``base`` with the wire's protrusion at insertion 0 cut to the straight run along
    the inlet direction in which the wire keeps :data:`START_CLEARANCE` from the wall.

    The wire leaves the sheath straight along the inlet direction. A vessel cut short of its
    ostium can bend away within the default 8 mm: the right tree of a real patient's mesh
    (NARCO_119) turns 17° in its first 8 mm at 1.1 mm radius, so the straight wire started
    0.4 mm into the wall and every episode ended at its first step, a 5.6 N tip force. The
    protrusion stays longer than the shaped tip (``DriverConfig.check_wire``), so a vessel
    that bends sooner still starts as before that far."""
    driver, wire = base.driver, base.wire
    step = 2.5e-4
    along = driver.sheath_overlap + np.arange(step, driver.initial_protrusion + step / 2, step)
    points = vessel.inlet_position + along[:, None] * (
        vessel.inlet_direction / np.linalg.norm(vessel.inlet_direction))
    tight = np.nonzero(vessel.centerline.tube_excesses(points) + wire.radius
                       > -START_CLEARANCE)[0]
    if not tight.size:
        return base
    free = float(along[tight[0]] - step - driver.sheath_overlap)
    protrusion = max(free, wire.tip_length + _PROTRUSION_OVER_TIP)
    if protrusion >= driver.initial_protrusion:
        return base
    return dataclasses.replace(base, driver=dataclasses.replace(
        driver, initial_protrusion=protrusion))


def tip_reach(driver: DriverConfig) -> float:
    """How far along the centerline from the inlet the wire's tip can get (m): the sheath's
    reach into the vessel, the protrusion beyond it and the driver's whole travel."""
    return driver.sheath_overlap + driver.initial_protrusion + driver.max_insertion


def fit_travel(vessel: Vessel, base: SceneConfig | None = None, margin: float = 0.01
               ) -> SceneConfig:
    """Returns ``base`` with the driver's travel the deepest target's centerline distance from
    the inlet plus ``margin``, and a wire just long enough for it (:func:`with_travel`)."""
    graph = vessel.centerline
    from_inlet = graph.geodesic_from(graph.labels[INLET_LABEL])
    depth = max(float(from_inlet[graph.labels[name]]) for name in vessel.targets)
    return with_travel(base or SceneConfig(), depth + margin)


def with_travel(base: SceneConfig, max_insertion: float) -> SceneConfig:
    """Returns ``base`` with the driver's insertion travel ``max_insertion`` (m) and a wire
    just long enough for it: the travel, the protrusion at the start and 3 mm of sheath slack."""
    driver = dataclasses.replace(base.driver, max_insertion=max_insertion)
    length = max_insertion + driver.initial_protrusion + 0.003
    return dataclasses.replace(base, driver=driver,
                               wire=dataclasses.replace(base.wire, length=length))


def fit_tip(wire: GuidewireConfig, lumen_radius: float, tip_fill: float = 0.85,
            where: str = "the vessel") -> GuidewireConfig:
    """Returns ``wire`` with its tip angle (and any secondary curve's, in proportion) reduced
    until the pre-bent tip's lateral offset is at most ``tip_fill`` × (``lumen_radius`` −
    wire radius).

    Raises:
        SceneError: If the lumen is not wider than the wire.
    """
    room = _room(wire, lumen_radius, tip_fill, where)
    if wire.tip_lateral_offset <= room:
        return wire

    def narrowed(angle: float) -> GuidewireConfig:
        secondary = wire.secondary_angle * angle / wire.tip_angle if wire.tip_angle else 0.0
        return dataclasses.replace(wire, tip_angle=angle, secondary_angle=secondary)

    low, high = 0.0, wire.tip_angle  # bisection: the offset grows with the angles
    while high - low > 1e-5:
        middle = 0.5 * (low + high)
        if narrowed(middle).tip_lateral_offset > room:
            high = middle
        else:
            low = middle
    return narrowed(low)


def fit_segments(wire: GuidewireConfig, bend_radius: float, lumen_radius: float,
                 fill: float = 0.75, where: str = "the vessel") -> GuidewireConfig:
    """Returns ``wire`` with its shaft segments short enough to lie in a bend of axis radius
    ``bend_radius`` (m) of a lumen of ``lumen_radius`` (m).

    A straight segment of length l laid in the bend bows off its axis by the sagitta
    l² / (8 R). Where that exceeds the room the lumen leaves the wire, the segment cannot lie
    in the lumen at all: the contacts pinch it between the walls and the step blows up. The
    longest segment is cut until the sagitta is at most ``fill`` × (``lumen_radius`` − wire
    radius).

    Raises:
        SceneError: If the lumen is not wider than the wire.
    """
    longest = math.sqrt(8.0 * bend_radius * _room(wire, lumen_radius, fill, where))
    if wire.max_segment_length <= longest:
        return wire
    return dataclasses.replace(wire, max_segment_length=longest)


def segment_limits(wire: GuidewireConfig, graph: CenterlineGraph, fill: float = 0.75,
                   precision: float = 1e-5) -> NDArray[np.float64]:
    """The longest shaft segment (m) that can lie at each node of ``graph``, up to ``wire``'s
    ``max_segment_length``: within the bends of the node's branch and, at a junction, in the
    turn into every branch.

    **Bends.** A straight segment of length l laid as a chord from any node along its branch
    must stay within ``fill`` x (the narrowest lumen radius under it - wire radius) of the
    centerline between the chord's ends. A user's folder says nothing of its tightest bend, and
    a segment longer than that jams there: in a vessel folder of a generated coronary tree
    (1.5 mm acute marginal, bends of 2.6 lumen radii), 5 mm segments stopped the wire 2.6-3.3
    mm short of the branch's end at the driver's 0.5 N push limit with 0.04-0.06 N on the tip
    (docs/tasks/coronary.md, 2026-11-29). Chords end at junctions: a wire crossing one runs
    through the parent's wider lumen. A chord over a lumen no wider than the wire (a stenosis
    the wire does not pass) is not measured. Each chord's longest fitting length is found by
    bisection to ``precision`` (m) and holds for every node it spans.

    **Junctions.** A centerline turns into a branch at a node, so the chords, which stay
    within branches, cannot see how tight the turn is; and a chord measured across the
    junction's node lies on the kink, missing the lumen's flare, and would allow only 1.1-2.5
    mm where 2.5 mm segments pass. The junction node takes :func:`fit_segments`'s rule with
    the turn as a bend of :data:`JUNCTION_BEND_RADII` radii of the narrowest vessel meeting
    there, read one junction radius from the junction, past the flare. Where two 0.85 mm
    vessels meet at 85° (a tree of issue 15's calibre, ``coronary_tree`` seed 3103), 5 mm
    segments jammed across the junction at the driver's 0.5 N push limit with 0.01 N on the
    tip; with this rule's 2.93 mm the probing expert reached all 64 episodes of eight such
    trees, against 60 (docs/tasks/coronary.md, 2026-11-29, evening, and 2026-12-01). With a
    0.014 in wire, vessels of 1.4 mm radius or more (the shipped phantoms) keep a 5 mm segment.
    """
    longest = wire.max_segment_length
    limits = np.full(graph.num_nodes, longest)
    for chain in branch_chains(graph):
        points = graph.nodes[chain]
        rooms = fill * (graph.radii[chain] - wire.radius)
        arc = arc_lengths(points)
        for start in range(len(chain)):
            fits, span = _chord_fits(points, rooms, arc, start, longest)
            if fits:
                continue
            low, high = 0.0, longest
            while high - low > precision:
                middle = 0.5 * (low + high)
                fits, _ = _chord_fits(points, rooms, arc, start, middle)
                low, high = (middle, high) if fits else (low, middle)
            spanned = np.asarray(chain[start:span + 1])
            limits[spanned] = np.minimum(limits[spanned], low)
    degrees = graph.degrees()
    for chain in branch_chains(graph):
        for end in (chain, chain[::-1]):
            if degrees[end[0]] < 3:
                continue
            arc = arc_lengths(graph.nodes[end])
            past_flare = min(int(np.searchsorted(arc, graph.radii[end[0]])), len(end) - 1)
            radius = float(graph.radii[end[past_flare]])
            if radius > wire.radius:
                turn = fit_segments(wire, JUNCTION_BEND_RADII * radius, radius, fill)
                limits[end[0]] = min(limits[end[0]], turn.max_segment_length)
    return limits


def fit_segments_to_vessel(wire: GuidewireConfig, graph: CenterlineGraph,
                           reach: float | None = None, fill: float = 0.75,
                           step: float = 0.02) -> GuidewireConfig:
    """Returns ``wire`` with shaft segments short enough for every bend and junction of
    ``graph`` that they can reach (:func:`segment_limits`).

    Without ``reach`` every segment is cut to the tightest place of the whole tree (the wire's
    ``max_segment_length``). With it, the tip's deepest reach along the centerline from the
    inlet (m), a point of the wire ``s`` from the tip can lie no deeper than ``reach - s``: the
    proximal wire only ever lies in the proximal vessels, which are wider, so its segments
    may be longer (``GuidewireConfig.segment_limits``): on eight generated coronary trees
    43-57 segments instead of 54-71, the same cut as before wherever the tip can go. The
    limits keep a new value only where it is at least ``step`` (relative) longer than the
    last one kept, so that the wire takes a few zones, not one per node.
    """
    limits = segment_limits(wire, graph, fill)
    if reach is None:
        shortest = float(limits.min())
        if shortest >= wire.max_segment_length:
            return wire
        return dataclasses.replace(wire, max_segment_length=shortest)
    depth = graph.geodesic_from(graph.labels[INLET_LABEL])
    order = np.argsort(depth)
    order = order[depth[order] <= reach]  # nodes the tip cannot get to constrain nothing
    # For s from the tip up: the nodes within reach - s are the shallowest ones, so the cap
    # at s is the least limit of the nodes no deeper than that.
    deepest_first = order[::-1]
    caps = np.minimum.accumulate(limits[order])[::-1]  # caps[j]: nodes up to deepest_first[j]
    pairs: list[tuple[float, float]] = []
    for node, cap in zip(deepest_first, caps, strict=True):
        s = max(0.0, reach - float(depth[node]))
        if not pairs:
            pairs.append((0.0, float(cap)))
        elif cap >= pairs[-1][1] * (1.0 + step) and s > pairs[-1][0]:
            pairs.append((s, float(cap)))
    if pairs[-1][1] < wire.max_segment_length and reach > float(depth[order[0]]):
        # Beyond the inlet's reach (the wire that never leaves the sheath): the wire's own cap.
        pairs.append((reach - float(depth[order[0]]) + 1e-9, wire.max_segment_length))
    if len(pairs) == 1 and pairs[0][1] >= wire.max_segment_length:
        return wire
    return dataclasses.replace(wire, segment_limits=tuple(pairs))


def _chord_fits(points: np.ndarray, rooms: np.ndarray, arc: np.ndarray, start: int,
                length: float) -> tuple[bool, int]:
    """Whether a segment of ``length`` (m) laid as a chord from node ``start`` of the branch
    ``points`` to a later node stays within the ``rooms`` (m) of the nodes it spans, and the
    last node it spans (the branch's last if it runs past its end)."""
    # A chord is no longer than the arc it spans: start the search where the arc is long
    # enough.
    end = int(np.searchsorted(arc, arc[start] + length))
    while end < len(points) and np.linalg.norm(points[end] - points[start]) < length:
        end += 1
    if end >= len(points):
        return True, len(points) - 1
    # The chord's far end: where the branch's last edge crosses the sphere of radius
    # ``length`` about the start (|a + t d| = length), not the node past it.
    a, d = points[end - 1] - points[start], points[end] - points[end - 1]
    b, c = float(a @ d), float(a @ a) - length**2
    t = (-b + math.sqrt(b * b - float(d @ d) * c)) / float(d @ d)
    span = points[start:end] - points[start]
    axis = (a + t * d) / length
    off = np.linalg.norm(span - np.outer(span @ axis, axis), axis=1)
    room = rooms[start:end + 1].min()
    return not (room > 0 and off.max() > room), end


def _room(wire: GuidewireConfig, lumen_radius: float, fill: float, where: str) -> float:
    """``fill`` × the room a lumen of ``lumen_radius`` leaves the wire (m): the budget of
    :func:`fit_tip` and :func:`fit_segments`."""
    room = fill * (lumen_radius - wire.radius)
    if room <= 0:
        raise SceneError(
            f"{where}'s narrowest lumen ({lumen_radius * 1e3:.2f} mm radius) is not "
            f"wider than the wire ({wire.radius * 1e3:.2f} mm radius)."
        )
    return room


def base_spec() -> mujoco.MjSpec:
    """Returns a spec holding only ``mjcf/options.xml`` (options, visual, default classes)."""
    return mujoco.MjSpec.from_file(str(assets.mjcf_path("options.xml")))


def set_wire_options(spec: mujoco.MjSpec, wire: GuidewireConfig,
                     timestep: float | None = None) -> None:
    """Sets the options of ``spec`` that ``wire``'s numerical settings choose: the physics
    step (``timestep`` if given, else the wire's ``max_timestep`` where it is shorter than the
    spec's), the friction cone and the integrator. A scene holds one wire, so the wire's
    choices are the scene's."""
    if timestep is not None:
        spec.option.timestep = timestep
    elif wire.max_timestep is not None:
        spec.option.timestep = min(spec.option.timestep, wire.max_timestep)
    if wire.friction_cone is not None:
        spec.option.cone = FRICTION_CONES[wire.friction_cone]
    if wire.integrator is not None:
        spec.option.integrator = INTEGRATORS[wire.integrator]


def insertion_frame(direction: np.ndarray) -> np.ndarray:
    """Returns the quaternion (w, x, y, z) whose x axis is ``direction`` and y axis is 'up'.

    'Up' is world +y made orthogonal to ``direction`` (world +z if they are parallel).
    """
    x = np.asarray(direction, dtype=np.float64)
    x = x / np.linalg.norm(x)
    up = np.array([0.0, 1.0, 0.0]) if abs(x[1]) < 0.99 else np.array([0.0, 0.0, 1.0])
    y = up - x * np.dot(up, x)
    y /= np.linalg.norm(y)
    z = np.cross(x, y)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.column_stack([x, y, z]).ravel())
    return quat


def _attach_vessel(spec: mujoco.MjSpec, vessel: Vessel,
                   chunks: Mapping[str, int] | None = None) -> None:
    """Attaches the vessel's MJCF; ``chunks`` (wall geom name to chunk index) moves each
    named hull into its chunk's mocap body (the body at the origin, the hull where it was)."""
    child = mujoco.MjSpec.from_file(str(vessel.mjcf_path))
    # Mesh files are relative to the vessel folder; make them absolute so the parent spec,
    # which lives elsewhere, still finds them.
    mesh_root = Path(child.modelfiledir) / (child.meshdir or "")
    for mesh in child.meshes:
        if mesh.file:
            mesh.file = str((mesh_root / mesh.file).resolve())
    child.meshdir = ""
    if chunks:
        wall = child.find_default(WALL_CLASS)
        bodies = [child.worldbody.add_body(name=names.wall_chunk_body(k), mocap=True)
                  for k in range(max(chunks.values()) + 1)]
        for geom in [g for g in child.geoms if g.name in chunks]:
            name, mesh = geom.name, geom.meshname
            child.delete(geom)
            bodies[chunks[name]].add_geom(default=wall, name=name, meshname=mesh)
    spec.attach(child, prefix=names.VESSEL_PREFIX, frame=spec.worldbody.add_frame())


def wall_chunks(model: mujoco.MjModel, size: float = CHUNK_SIZE) -> dict[str, int]:
    """Groups a compiled static scene's wall hulls into chunks of at most ``size`` (m) along
    each axis, by their centres: wall geom name (inside the vessel's prefix) to chunk."""
    prefix = names.VESSEL_PREFIX
    walls = [g for g in range(model.ngeom)
             if (model.geom_contype[g] & 2) and model.geom_bodyid[g] == 0
             and mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g).startswith(prefix)]
    cells = np.floor(model.geom_pos[walls] / size).astype(np.int64)
    _, chunk = np.unique(cells, axis=0, return_inverse=True)
    return {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)[len(prefix):]: int(k)
            for g, k in zip(walls, chunk.ravel(), strict=True)}


def _add_wall_contact_sensor(spec: mujoco.MjSpec, name: str, wire_body: str) -> None:
    """Adds a sensor for the contacts of ``wire_body``'s subtree with vessel-wall hulls.

    The hulls are geoms of the world body (the sheath has its own body, so it is not
    included). MuJoCo fills the sensor inside ``mj_step``, so reading a wall force is one
    slice instead of a pass over the contact list in Python (see
    :meth:`sim4endor.physics.GuidewirePhysics.wall_contact_force`).
    """
    sensor = spec.add_sensor()
    sensor.name = name
    sensor.type = mujoco.mjtSensor.mjSENS_CONTACT
    sensor.objtype = mujoco.mjtObj.mjOBJ_XBODY  # the body's whole subtree
    sensor.objname = wire_body
    sensor.reftype = mujoco.mjtObj.mjOBJ_BODY
    sensor.refname = "world"
    # data="found force" (bits 0 and 1), reduce="none", num=slots: per slot
    # [number of matching contacts, normal force, two tangential forces].
    sensor.intprm = [0b11, 0, names.CONTACT_SENSOR_SLOTS]


def starts_straight(wire: GuidewireConfig, bore_radius: float) -> bool:
    """Whether ``wire``'s shaped tip (secondary curve included) is too wide for a bore of
    ``bore_radius`` (m): such a tip starts straightened in it, as a real wire's tip does in a
    guide catheter, and springs into its shape as it leaves (GuidewirePhysics.place_driver);
    one that fits starts shaped."""
    return wire.tip_lateral_offset >= bore_radius - wire.radius


def build_spec(vessel: Vessel | None, config: SceneConfig | None = None,
               chunks: Mapping[str, int] | None = None) -> mujoco.MjSpec:
    """Returns the uncompiled scene spec.

    Args:
        vessel: The anatomy; ``None`` gives the wire and driver alone with the inlet at the
            origin pointing along +x (used by the cantilever validation).
        config: Wire, driver and timestep; ``None`` uses the defaults.
        chunks: For moving walls: each wall hull's chunk (:func:`wall_chunks`).

    A pre-bent tip wider than the inlet's lumen starts straightened
    (:data:`~sim4endor.models.constants.TIP_STRAIGHT_AT_START`).
    """
    config = config or SceneConfig()
    wire, driver = config.wire, config.driver
    driver.check_wire(wire.length, wire.radius, wire.tip_length)
    spec = base_spec()
    set_wire_options(spec, wire, config.timestep)
    if vessel is None:
        inlet, direction = np.zeros(3), np.array([1.0, 0.0, 0.0])
        straight = False
    else:
        inlet, direction = vessel.inlet_position, vessel.inlet_direction
        straight = starts_straight(wire, vessel.manifest.inlet.radius)
        _attach_vessel(spec, vessel, chunks)
    direction = direction / np.linalg.norm(direction)
    quat = insertion_frame(direction)
    back = driver.sheath_length(wire.length)
    start = inlet - back * direction
    add_sheath(spec, start - 0.002 * direction, quat, back + 0.002 + driver.sheath_overlap, driver)
    carriage = add_driver(spec, start, quat, driver)
    add_guidewire(spec, carriage, wire)
    spec.add_numeric(name=names.TIP_STRAIGHT_AT_START, data=[float(straight)])
    for first in chain_starts(wire, wire.num_segments):
        root = names.wire_body(0) if first == 0 else names.wire_chain_root(first)
        _add_wall_contact_sensor(spec, names.wall_contact_sensor(first), root)
    first_tip_body = wire.num_segments - wire.tip_segments
    _add_wall_contact_sensor(spec, names.TIP_CONTACT_SENSOR, names.wire_body(first_tip_body))
    spec.stat.center = list(inlet + 0.5 * driver.max_insertion * direction)
    spec.stat.extent = max(0.05, driver.max_insertion)
    spec.stat.meansize = 0.002
    return spec


@functools.lru_cache(maxsize=8)
def _compiled(
    vessel_root: str | None, stamp: tuple[int, ...], config: SceneConfig
) -> mujoco.MjModel:
    # ``stamp`` (file modification times) makes a rebuilt folder at the same path a new entry.
    from sim4endor import vessels  # the vessel folder is re-read once per cache entry

    vessel = None if vessel_root is None else vessels.load(Path(vessel_root))
    chunks = None
    if config.moving_walls and vessel is not None:
        # The hulls' centres come from the static scene (MuJoCo centres each mesh).
        static = _compiled(vessel_root, stamp, dataclasses.replace(config, moving_walls=False))
        chunks = wall_chunks(static)
    spec = build_spec(vessel, config, chunks)
    try:
        return spec.compile()
    except ValueError as exc:
        where = vessel_root or "the wire-only scene"
        raise SceneError(f"MuJoCo could not compile {where}: {exc}") from None


def build_model(vessel: Vessel | None, config: SceneConfig | None = None) -> mujoco.MjModel:
    """Returns the compiled scene, compiled once per (vessel folder, config) and copied."""
    if vessel is None:
        return copy.copy(_compiled(None, (), config or SceneConfig()))
    stamp = tuple(
        (vessel.root / name).stat().st_mtime_ns
        for name in (MANIFEST_FILE, vessel.manifest.mjcf, CENTERLINE_FILE)
    )
    return copy.copy(_compiled(str(vessel.root), stamp, config or SceneConfig()))

