"""Every MJCF name and fixed physical number the code relies on, in one place.

The XML files in ``assets/mjcf`` define these names; the code never spells a name itself. When
robots are attached to a world, dm_control's MJCF attachment prefixes each name with the robot's
model name (``cr_0/``), see :func:`robot_prefix`.
"""

from __future__ import annotations

# --- files -----------------------------------------------------------------------------------
ROBOT_XML = "cyber_rodent.xml"  # the paper's robot (cyber_rodent.robot.ROBOTS)
BATTERY_PACK_XML = "battery_pack.xml"
ARENA_XML = "arena.xml"

# --- robot ----------------------------------------------------------------------------------
# The robot's parts, body, drive and sensors are its model's (cyber_rodent/robot.py,
# RobotModel, read from its MJCF file and its sensor table); a world names its robots so:
ROBOT_MODEL_PREFIX = "cr"

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
