"""Every MJCF name and fixed physical number the code relies on, in one place.

The XML files in ``assets/mjcf`` define these names; the code never spells a name itself. When
robots are attached to a world, dm_control's MJCF attachment prefixes each name with the robot's
model name (``cr_0/``), see :func:`robot_prefix`.
"""

from __future__ import annotations

# --- files -----------------------------------------------------------------------------------
ROBOT_XML = "cyber_rodent.xml"
BATTERY_PACK_XML = "battery_pack.xml"
ARENA_XML = "arena.xml"

# --- robot ----------------------------------------------------------------------------------
ROBOT_MODEL_PREFIX = "cr"
ROBOT_ROOT_BODY = "chassis"
CHASSIS_GEOM = "chassis_geom"
LEFT_WHEEL_JOINT = "left_wheel"
RIGHT_WHEEL_JOINT = "right_wheel"
LEFT_MOTOR = "left_motor"
RIGHT_MOTOR = "right_motor"
LED_GEOM = "led"
FACE_GEOM = "face"
TEETH_GEOM = "teeth"
IR_PORT_SITE = "ir_port"
CAMERA_MOUNT_SITE = "camera_mount"

#: Range sensors in sensordata order: (sensor name, bearing in degrees, range in metres).
#: Index 0 is the long-range sensor facing forward; 0..4 are the front arc, 5 the back, 6/7 the
#: sides. Search and the controller use the "six proximity" subset :data:`PROXIMITY_SIX`.
RANGE_SENSORS: tuple[tuple[str, float, float], ...] = (
    ("range_front", 0.0, 1.0),
    ("range_front_left30", 30.0, 0.3),
    ("range_front_right30", -30.0, 0.3),
    ("range_front_left60", 60.0, 0.3),
    ("range_front_right60", -60.0, 0.3),
    ("range_back", 180.0, 0.3),
    ("range_left", 90.0, 0.3),
    ("range_right", -90.0, 0.3),
)
N_RANGE = len(RANGE_SENSORS)
#: Indices into the 8 range readings of the 5 front + 1 back proximity sensors (docs/design.md §4).
PROXIMITY_SIX: tuple[int, ...] = (0, 1, 2, 3, 4, 5)

# Physical numbers that the XML fixes and the code needs (checked against the compiled model in
# the tests, so the two cannot drift apart).
WHEEL_RADIUS = 0.035  # m
HALF_WHEEL_BASE = 0.08  # m, wheel contact point to robot centre line
TOP_SPEED = 1.3  # m/s, wheel rim speed cap (actuator ctrlrange = TOP_SPEED / WHEEL_RADIUS)
BODY_LENGTH = 0.22  # m, chassis
BODY_RADIUS = 0.14  # m, radius of the disc that contains the robot (placement clearance)
ROBOT_MASS = 1.75  # kg

# --- battery pack ---------------------------------------------------------------------------
PACK_MODEL_PREFIX = "pack"
PACK_BODY = "pack"
PACK_GEOM = "pack_body"
PACK_ELECTRODE_GEOM = "electrode"
PACK_RADIUS = 0.045  # m, the electrode ring's outer radius (placement clearance)

# --- arena ----------------------------------------------------------------------------------
FLOOR_GEOM = "floor"
WALL_GEOMS = ("wall_north", "wall_south", "wall_east", "wall_west")
TOP_CAMERA = "top_down"
CHASE_CAMERA = "chase"
OMNI_CAMERAS = ("omni_front", "omni_left", "omni_back", "omni_right")
#: m, inner side length of the paper's square field: the arena file's walls and the default of
#: ``WorldConfig.field_size`` (the world resizes the walls for other sides).
FIELD_SIZE = 2.3

# --- collision bits (contype / conaffinity) -------------------------------------------------
# bit 0: ground contacts (wheels and casters touch the floor only);
# bit 1: bodies (chassis, teeth, packs, walls touch each other);
# bit 2: robot against robot, which only the chassis boxes accept, so the low teeth touch the
#        floor, walls and packs but no robot (docs/design.md §9.35).
GROUND_BIT = 1
BODY_BIT = 2
ROBOT_BIT = 4


def robot_prefix(index: int) -> str:
    """Name prefix of robot ``index`` in an assembled world, e.g. ``cr_0/``."""
    return f"{ROBOT_MODEL_PREFIX}_{index}/"


def pack_prefix(index: int) -> str:
    """Name prefix of battery pack ``index`` in an assembled world, e.g. ``pack_0/``."""
    return f"{PACK_MODEL_PREFIX}_{index}/"
