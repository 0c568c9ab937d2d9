"""What the camera looks for, read from the compiled model: the LED ring, the face, the pack.

Both providers need the targets' shapes: the geometric provider to cast rays at them and to
predict their size in the image, the rendered provider to turn a blob's image edges into a
distance (the classic ground-plane / known-height method of omni cameras: a point of known
height seen at a known depression angle lies at a known horizontal distance). Reading them from
``MjModel`` keeps the vision code in step with the MJCF files.

Distance convention (both providers): the horizontal distance from the observing robot's camera
axis (the vertical line through its ``camera_mount`` site) to the target's vertical axis: the
other robot's LED ring axis (= its camera axis), the vertical line through the centre of its
face plate, the battery pack's cylinder axis. Bearing is measured to the same axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import mujoco

from cyber_rodent.vision.types import BATTERY, FACE, LED
from cyber_rodent.world import World


@dataclass(frozen=True)
class TargetShape:
    """The coloured part of a target, in the frame of the body that carries it.

    A target is either a vertical cylinder (LED ring, pack) or a flat plate facing along the
    body's x axis (face). Seen from a camera above it, a cylinder's silhouette spans from its
    near bottom rim to its far top rim. A plate is a thin box standing proud of its body: its
    front face is seen from the front, and the strip of its sides that stands out of the body
    is seen edge-on, from the side (the rendered camera sees that red edge too).

    Attributes:
        cls: colour class.
        plate: True for a flat plate, False for a vertical cylinder.
        half_width: m, cylinder radius or half the plate's width.
        z_bottom, z_top: m, height of the coloured part above the floor.
        depth_front: m, the plate's front face ahead of its centre (0 for cylinders).
        depth_back: m, where the part of its sides that stands out of the body begins,
            relative to its centre (negative: behind it; 0 for cylinders).
        gap_bottom, gap_top: m above the floor, a grey band that cuts the coloured part in
            two (a pack's electrode ring; both 0 if none).
        gap_radius: m, that band's radius (it stands out of the cylinder).
        body_half_width: m, half the width of the body a plate is fixed to (0 for cylinders):
            a camera behind the plate's front face sees its edge only past the body's side.
        rim_offset: m, how much nearer (bottom) / farther (top) than the target's axis the
            silhouette's bottom and top edges lie (the radius for cylinders, 0 for plates).
    """

    cls: int
    plate: bool
    half_width: float
    z_bottom: float
    z_top: float
    depth_front: float = 0.0
    depth_back: float = 0.0
    gap_bottom: float = 0.0
    gap_top: float = 0.0
    gap_radius: float = 0.0
    body_half_width: float = 0.0

    @property
    def edge_slope(self) -> float:
        """How far behind the front face, per metre beside the plate's edge, a camera still
        sees that edge past the body's side (0 for cylinders; inf if the body is no wider)."""
        if not self.plate:
            return 0.0
        margin = self.body_half_width - self.half_width
        return math.inf if margin <= 0 else (self.depth_front - self.depth_back) / margin

    @property
    def rim_offset(self) -> float:
        return 0.0 if self.plate else self.half_width

    @property
    def height(self) -> float:
        return self.z_top - self.z_bottom


@dataclass(frozen=True)
class TargetGeometry:
    """Camera height and the three target shapes of a world.

    Attributes:
        camera_height: m above the floor of the camera (the ``camera_mount`` site).
        shapes: per class (LED, FACE, BATTERY), the target's coloured shape.
    """

    camera_height: float
    shapes: tuple[TargetShape, TargetShape, TargetShape]


def _geom_height_above_floor(m: mujoco.MjModel, geom: int) -> float:
    """Height of a geom's centre above its root body's origin (robots and packs stand on the
    floor at their root body's origin)."""
    z = float(m.geom_pos[geom, 2])
    body = int(m.geom_bodyid[geom])
    root = int(m.body_rootid[body])
    while body != root and body != 0:
        z += float(m.body_pos[body, 2])
        body = int(m.body_parentid[body])
    return z


def target_geometry(world: World) -> TargetGeometry:
    """Read the camera height and the LED, face and pack shapes from the world's model.

    Raises:
        ValueError: if a target geom has a type the vision model does not describe.
    """
    m = world.model
    site = int(world.camera_site[0])
    cam_z = float(m.site_pos[site, 2])
    body = int(m.site_bodyid[site])
    root = int(m.body_rootid[body])
    while body != root and body != 0:
        cam_z += float(m.body_pos[body, 2])
        body = int(m.body_parentid[body])

    def cylinder(cls: int, geom: int) -> TargetShape:
        if m.geom_type[geom] != mujoco.mjtGeom.mjGEOM_CYLINDER:
            raise ValueError(f"vision expects geom {geom} (class {cls}) to be a cylinder")
        r, half_h = float(m.geom_size[geom, 0]), float(m.geom_size[geom, 1])
        zc = _geom_height_above_floor(m, geom)
        return TargetShape(
            cls=cls, plate=False, half_width=r, z_bottom=zc - half_h, z_top=zc + half_h
        )

    face_geom = int(world.face_geom[0])
    if m.geom_type[face_geom] != mujoco.mjtGeom.mjGEOM_BOX:
        raise ValueError("vision expects the face geom to be a box")
    half_d, half_w, half_h = (float(s) for s in m.geom_size[face_geom])
    zc = _geom_height_above_floor(m, face_geom)
    # The face's sides show only where they stand out of the chassis's front face.
    chassis = int(world.chassis_geom[0])
    if m.geom_bodyid[chassis] != m.geom_bodyid[face_geom]:
        raise ValueError("vision expects the face on the chassis body")
    chassis_front = float(m.geom_pos[chassis, 0] + m.geom_size[chassis, 0])
    face_x = float(m.geom_pos[face_geom, 0])
    face = TargetShape(
        cls=FACE,
        plate=True,
        half_width=half_w,
        z_bottom=zc - half_h,
        z_top=zc + half_h,
        depth_front=half_d,
        depth_back=min(max(chassis_front - face_x, -half_d), half_d),
        body_half_width=float(m.geom_size[chassis, 1]),
    )
    led = cylinder(LED, int(world.led_geom[0]))
    if len(world.pack_geom):
        pack = cylinder(BATTERY, int(world.pack_geom[0]))
        ring = int(world.electrode_geom[0])
        ring_z = _geom_height_above_floor(m, ring)
        ring_half = float(m.geom_size[ring, 1])
        pack = replace(
            pack,
            gap_bottom=ring_z - ring_half,
            gap_top=ring_z + ring_half,
            gap_radius=float(m.geom_size[ring, 0]),
        )
    else:  # no packs in this world: a placeholder that is never looked for
        pack = TargetShape(cls=BATTERY, plate=False, half_width=0.04, z_bottom=0.0, z_top=0.1)
    return TargetGeometry(camera_height=cam_z, shapes=(led, face, pack))
