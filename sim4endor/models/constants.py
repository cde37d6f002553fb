"""Every MJCF name the guidewire scene code addresses (MuJoCo Playground style).

The scene builder creates elements under these names and :mod:`sim4endor.physics` looks them
up by name, so nothing in the library relies on element indices.
"""

from __future__ import annotations

#: Prefix of every element of the wire (bodies, joints, geoms, the tip site, the plugin).
WIRE_PREFIX = "guidewire/"
#: Name of the wire's elasticity plugin instance.
WIRE_PLUGIN = WIRE_PREFIX + "cable"
#: Site at the distal end of the wire.
WIRE_TIP_SITE = WIRE_PREFIX + "tip"
#: Default class of the wire's contact capsules (mjcf/guidewire_defaults.xml).
WIRE_CLASS = "guidewire"
#: Default class of the wire's hidden core capsules that carry the bending stiffness.
WIRE_CORE_CLASS = "guidewire_core"

#: The robot carriage body and its two joints / position actuators.
CARRIAGE_BODY = "driver/carriage"
INSERTION_JOINT = "driver/insertion"
ROTATION_JOINT = "driver/rotation"
INSERTION_ACTUATOR = "driver/insertion"
ROTATION_ACTUATOR = "driver/rotation"
#: Custom numerics holding the driver's speed limits (m/s and rad/s).
MAX_INSERTION_SPEED = "driver/max_insertion_speed"
MAX_ROTATION_SPEED = "driver/max_rotation_speed"
#: Custom numeric: 1 when the pre-bent tip starts straightened in the inlet's bore (it is
#: wider than the bore), 0 when it starts in its shape.
TIP_STRAIGHT_AT_START = "guidewire/tip_straight_at_start"

#: Static body holding the introducer sheath's convex wall pieces.
SHEATH_BODY = "sheath"
SHEATH_CLASS = "sheath"

#: Prefix given to every element of the attached vessel MJCF.
VESSEL_PREFIX = "vessel/"

#: Contact sensor reporting the wall contacts (count and forces) of the wire's first chain, the
#: whole wire when it is one chain (:func:`wall_contact_sensor` names the others).
WALL_CONTACT_SENSOR = "wall_contact"
#: Contact sensor reporting the contacts of the pre-bent tip's segments with the vessel wall.
TIP_CONTACT_SENSOR = "tip_contact"
#: Contacts a contact sensor reports one by one; more at once fall back to Python.
CONTACT_SENSOR_SLOTS = 32


def wire_body(index: int) -> str:
    """Returns the name of the wire's ``index``-th body (0 = proximal, welded to the driver)."""
    return f"{WIRE_PREFIX}body_{index:03d}"


def wire_joint(index: int) -> str:
    """Returns the name of the ball joint at the proximal end of wire body ``index`` (>= 1)."""
    return f"{WIRE_PREFIX}joint_{index:03d}"


def wire_chain_root(index: int) -> str:
    """Returns the name of the free body that starts the wire chain whose first segment is
    body ``index`` (a non-colliding copy of body ``index - 1``, welded to it), and of its
    free joint and weld."""
    return f"{WIRE_PREFIX}chain_root_{index:03d}"


def wall_contact_sensor(first_body: int) -> str:
    """Returns the name of the wall contact sensor of the wire chain starting at body
    ``first_body`` (:data:`WALL_CONTACT_SENSOR` for the first chain)."""
    return WALL_CONTACT_SENSOR if first_body == 0 else f"{WALL_CONTACT_SENSOR}_{first_body:03d}"


def wire_geom(index: int) -> str:
    """Returns the name of the contact capsule of wire body ``index``."""
    return f"{WIRE_PREFIX}geom_{index:03d}"


def wall_chunk_body(index: int) -> str:
    """Returns the name (inside the vessel's prefix) of the mocap body that carries chunk
    ``index`` of a moving wall's hulls (:mod:`sim4endor.models.motion`)."""
    return f"wall_chunk_{index:03d}"
