"""The field with N Cyber Rodents and M battery packs, assembled from the MJCF parts.

The world is the one physical object that the dm-control tasks, the behaviour learners and the
evolution runner all step. It keeps the hot path lean: every per-step quantity (wheel commands,
range readings, poses, LED state) is a numpy view into ``MjData`` or a precomputed index, read as
one flat slice, never by name (named access measured ~40x the cost of a slice read).

Assembly uses ``dm_control.mjcf`` (the pattern of dm_control's walkers: one XML per part,
attached with a name prefix), so the same compiled model also backs a ``dm_control`` ``Physics``
for the tasks. Placement is re-drawn at :meth:`World.reset` without recompiling: robots are free
bodies (qpos), packs are static bodies (``model.body_pos``).

A world may hold several copies of the field side by side (``WorldConfig.arenas``, each with its
own walls and its share of the robots and packs: :func:`lay_out_arenas`, docs/design.md §9.33).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from dm_control import mjcf

from cyber_rodent import constants as C
from cyber_rodent.assets import asset_path
from cyber_rodent.robot import SENSOR_KINDS, RobotModel, SensorRow, robot_model, robot_names
from cyber_rodent.validation import choice, integer, number, validate_fields

#: Colours of the LED (RGBA). Off is dark green, not invisible: a real LED is still there.
LED_ON_RGBA = np.array([0.1, 1.0, 0.1, 1.0])
LED_OFF_RGBA = np.array([0.05, 0.15, 0.05, 1.0])
#: Colour (RGBA) of an inactive pack's body (``WorldConfig.pack_reactivation_steps``): a dark,
#: unsaturated grey that no colour class of the camera's segmentation takes for blue.
PACK_INACTIVE_RGBA = np.array([0.15, 0.15, 0.15, 1.0])
#: Upper bound of ``WorldConfig.pack_reactivation_steps``, the same as the survival rules' step
#: counts (``cyber_rodent.survival.config.MAX_STEP_COUNT``): 1e6 control steps are longer than
#: any experiment; a larger count is a typo.
MAX_REACTIVATION_STEPS = 1_000_000

_PLACEMENT_MARGIN = 0.02  # m, extra gap between placed bodies and to the walls
_MAX_PACKING_DENSITY = 0.4  # share of the usable field area that placed discs may cover
_PLACEMENT_ATTEMPTS = 2000
#: Default extra clearance between a pack and the walls (m, ``WorldConfig.pack_wall_clearance``):
#: a robot (18 cm wide) can always pass between them, so no robot gets wedged in a pack-wall gap
#: it cannot turn in.
PACK_WALL_CLEARANCE = 0.2
#: Default smallest gap between two packs (m, ``WorldConfig.pack_gap``): wider than a robot
#: turning in place (0.28 m), so no robot gets jammed between two packs (a 19 cm gap once held
#: a robot for the rest of a run).
PACK_GAP = 0.3
#: Bounds of ``WorldConfig.field_size`` (m). Half a metre holds one robot; 50 m is about 20 times
#: the paper's side and holds some 12,000 robots at the placement's packing density, far more
#: than :data:`MAX_ROBOTS`, so a larger side is a typo.
MIN_FIELD_SIZE = 0.5
MAX_FIELD_SIZE = 50.0
#: The most robots and packs a world may hold, in a field large enough for them (the fit check
#: of :class:`WorldConfig` decides what fits a given field). Twice the largest colony the cost
#: benchmark measures (100 robots, 125 packs: ``benchmarks/colony_scale.py``); the geometric
#: vision keeps arrays of robots x targets, so much larger colonies are a different program.
MAX_ROBOTS = 200
MAX_PACKS = 300
#: Bound of ``WorldConfig.arenas``: every arena holds at least one robot.
MAX_ARENAS = MAX_ROBOTS
#: m, thickness of the arena file's walls (each wall box is 0.05 m half thick, its inner face on
#: the field's edge); a test checks it against the compiled model.
WALL_THICKNESS = 0.1
#: m, the floor between the outer faces of two neighbouring arenas' walls
#: (``WorldConfig.arenas``): enough to tell the arenas apart in a top-down image. Nothing
#: crosses it: a robot sees only its own arena's targets (the walls hide the others too), and
#: IR mating pairs only robots of one arena (docs/design.md §9.33).
ARENA_GAP = 0.2


def _usable_area(field_size: float) -> float:
    return field_size**2


def _robot_placement_radius(body_radius: float | None = None) -> float:
    """Robots are placed as discs this big: the robot's clearance disc (``RobotModel.body_radius``;
    None: the paper's robot) and a margin."""
    if body_radius is None:
        body_radius = robot_model().body_radius
    return body_radius + _PLACEMENT_MARGIN


def _pack_placement_radius(pack_gap: float = PACK_GAP) -> float:
    """Packs are placed as discs this big, which keeps ``pack_gap`` between any two."""
    return max(C.PACK_RADIUS + pack_gap / 2, C.PACK_RADIUS + _PLACEMENT_MARGIN)


def _pack_wall_margin(pack_gap: float, pack_wall_clearance: float) -> float:
    """How much further from the walls than its placement disc a pack's centre stays: the
    disc already holds half the pack gap, so only the rest of the clearance is added."""
    return max(0.0, C.PACK_RADIUS + pack_wall_clearance - _pack_placement_radius(pack_gap))


def _disc_area(
    n_robots: int, n_packs: int, pack_gap: float = PACK_GAP, body_radius: float | None = None
) -> float:
    r_robot = _robot_placement_radius(body_radius)
    r_pack = _pack_placement_radius(pack_gap)
    return math.pi * (n_robots * r_robot**2 + n_packs * r_pack**2)


def _pack_square(field_size: float, pack_gap: float, pack_wall_clearance: float) -> float:
    """Side of the square that the packs' placement discs stay within (m)."""
    return field_size - 2 * _pack_wall_margin(pack_gap, pack_wall_clearance)


def _packs_fit(
    n_packs: int, pack_gap: float, pack_wall_clearance: float, field_size: float = C.FIELD_SIZE
) -> bool:
    """Do ``n_packs`` placement discs fit in the square the wall clearance leaves them?

    One pack fits wherever its centre has room; more must also stay within the packing
    density of that square (the rule the whole field's check applies to all discs together).
    """
    if n_packs == 0:
        return True
    r_pack = _pack_placement_radius(pack_gap)
    side = _pack_square(field_size, pack_gap, pack_wall_clearance)
    if side <= 2 * r_pack:
        return False
    return n_packs == 1 or n_packs * math.pi * r_pack**2 <= side**2 * _MAX_PACKING_DENSITY


def fits(
    n_robots: int,
    n_packs: int,
    field_size: float = C.FIELD_SIZE,
    pack_gap: float = PACK_GAP,
    pack_wall_clearance: float = PACK_WALL_CLEARANCE,
    body_radius: float | None = None,
) -> bool:
    """Do ``n_robots`` robots and ``n_packs`` packs fit a field of side ``field_size`` (m)?

    The rule :class:`WorldConfig` applies: every robot's placement disc fits between the
    walls, the packs fit the square their wall clearance leaves them, and all placement discs
    together cover at most the packing density (40 %) of the field, which the placement's
    rejection sampling can still draw. ``body_radius`` is the robots' clearance disc
    (``RobotModel.body_radius``; None: the paper's robot), as in the functions below.
    """
    if field_size <= 2 * _robot_placement_radius(body_radius):
        return False
    if not _packs_fit(n_packs, pack_gap, pack_wall_clearance, field_size):
        return False
    area = _disc_area(n_robots, n_packs, pack_gap, body_radius)
    return area <= _usable_area(field_size) * _MAX_PACKING_DENSITY


def max_counts(
    pack_gap: float = PACK_GAP,
    pack_wall_clearance: float = PACK_WALL_CLEARANCE,
    field_size: float = C.FIELD_SIZE,
    body_radius: float | None = None,
) -> tuple[int, int]:
    """The largest robot count (with no packs) and pack count (with one robot) that fit a
    field of side ``field_size``."""
    budget = _usable_area(field_size) * _MAX_PACKING_DENSITY
    r_robot = _robot_placement_radius(body_radius)
    r_pack = _pack_placement_radius(pack_gap)
    max_robots = int(budget / (math.pi * r_robot**2))
    max_packs = int((budget - math.pi * r_robot**2) / (math.pi * r_pack**2))
    while max_packs > 0 and not _packs_fit(max_packs, pack_gap, pack_wall_clearance, field_size):
        max_packs -= 1
    return max_robots, max_packs


def most_robots(
    n_packs: int,
    field_size: float = C.FIELD_SIZE,
    pack_gap: float = PACK_GAP,
    pack_wall_clearance: float = PACK_WALL_CLEARANCE,
    body_radius: float | None = None,
) -> int:
    """The most robots (at most :data:`MAX_ROBOTS`) that fit beside ``n_packs`` packs (0 if
    none, or if the packs themselves do not fit)."""
    r = body_radius
    if not fits(1, n_packs, field_size, pack_gap, pack_wall_clearance, r):
        return 0
    spare = _usable_area(field_size) * _MAX_PACKING_DENSITY - _disc_area(0, n_packs, pack_gap)
    count = min(MAX_ROBOTS, int(spare / (math.pi * _robot_placement_radius(r) ** 2)) + 1)
    while count > 0 and not fits(count, n_packs, field_size, pack_gap, pack_wall_clearance, r):
        count -= 1
    return count


def most_packs(
    n_robots: int,
    field_size: float = C.FIELD_SIZE,
    pack_gap: float = PACK_GAP,
    pack_wall_clearance: float = PACK_WALL_CLEARANCE,
    body_radius: float | None = None,
) -> int:
    """The most packs (at most :data:`MAX_PACKS`) that fit beside ``n_robots`` robots (-1 if
    the robots alone do not fit)."""
    r = body_radius
    if not fits(n_robots, 0, field_size, pack_gap, pack_wall_clearance, r):
        return -1
    spare = _usable_area(field_size) * _MAX_PACKING_DENSITY - _disc_area(n_robots, 0, pack_gap, r)
    count = min(MAX_PACKS, int(spare / (math.pi * _pack_placement_radius(pack_gap) ** 2)) + 1)
    while count > 0 and not fits(n_robots, count, field_size, pack_gap, pack_wall_clearance, r):
        count -= 1
    return count


def smallest_field(
    n_robots: int,
    n_packs: int,
    pack_gap: float = PACK_GAP,
    pack_wall_clearance: float = PACK_WALL_CLEARANCE,
    body_radius: float | None = None,
) -> float:
    """The smallest field side (m, rounded up to the centimetre) that holds ``n_robots``
    robots and ``n_packs`` packs (:func:`fits`)."""
    r_pack = _pack_placement_radius(pack_gap)
    need = max(
        2 * _robot_placement_radius(body_radius),
        math.sqrt(_disc_area(n_robots, n_packs, pack_gap, body_radius) / _MAX_PACKING_DENSITY),
    )
    if n_packs:
        margin = 2 * _pack_wall_margin(pack_gap, pack_wall_clearance)
        side = math.sqrt(n_packs * math.pi * r_pack**2 / _MAX_PACKING_DENSITY)
        need = max(need, margin + (2 * r_pack if n_packs == 1 else side))
    size = math.ceil(need * 100 - 1e-6) / 100
    while not fits(n_robots, n_packs, size, pack_gap, pack_wall_clearance, body_radius):
        size = round(size + 0.01, 2)
    return size


# --- arenas: copies of the field side by side (WorldConfig.arenas) ------------------------------
def arena_grid(arenas: int) -> tuple[int, int]:
    """(columns, rows) of the grid the arenas are laid out in: ceil(sqrt(arenas)) columns,
    filled row by row from the top left (25 arenas: 5 x 5; 2: 2 x 1; 5: 3 x 2, the last row
    part filled)."""
    columns = math.isqrt(arenas - 1) + 1
    return columns, -(-arenas // columns)


def arena_pitch(field_size: float) -> float:
    """Distance between the centres of two neighbouring arenas (m): a field, both arenas'
    walls and the gap between them (:data:`ARENA_GAP`); 2.7 m for the paper's field."""
    return field_size + 2 * WALL_THICKNESS + ARENA_GAP


def arena_centres(arenas: int, field_size: float) -> np.ndarray:
    """(arenas, 2) x, y of each arena's centre (m): a grid of :func:`arena_grid`, arena 0 at
    the top left (largest y, smallest x), the next to its right, rows downwards, the whole
    layout centred on the origin (one arena: at the origin)."""
    columns, rows = arena_grid(arenas)
    pitch = arena_pitch(field_size)
    a = np.arange(arenas)
    x = (a % columns - (columns - 1) / 2) * pitch
    y = ((rows - 1) / 2 - a // columns) * pitch
    return np.column_stack([x, y]).astype(np.float64)


def arena_extent(arenas: int, field_size: float) -> float:
    """Side (m) of the square, centred on the origin, that holds every arena's field: the
    field's side for one arena, else the fields of the longer side of the grid and the walls
    and gaps between them. The geometric vision's grids and the top-down camera cover it."""
    columns, rows = arena_grid(arenas)
    return field_size + (max(columns, rows) - 1) * arena_pitch(field_size)


def arena_wall_name(arena: int, wall: str) -> str:
    """Name of arena ``arena``'s wall ``wall`` (one of ``constants.WALL_GEOMS``): arena 0's
    walls keep the arena file's names, so the paper's one-arena world is unchanged."""
    return wall if arena == 0 else f"{wall}_{arena}"


def _layout_problem(config: WorldConfig) -> str:
    """Why ``config``'s arenas cannot be laid out, in one line ("" if they can): the counts
    must split evenly, and the layout must fit the largest field (:data:`MAX_FIELD_SIZE`)."""
    arenas = config.arenas
    for name, count in (("n_robots", config.n_robots), ("n_packs", config.n_packs)):
        if count % arenas:
            return (
                f"{name} must be a multiple of arenas={arenas} (every arena holds "
                f"{name} / arenas of them), got {count}"
            )
    extent = arena_extent(arenas, config.field_size)
    if extent > MAX_FIELD_SIZE:
        return (
            f"arenas={arenas} of field_size={config.field_size:g} m make a layout "
            f"{extent:.4g} m wide; it must be at most {MAX_FIELD_SIZE:g} m (the largest "
            "field_size): fewer arenas or a smaller field_size"
        )
    return ""


def _fit_problem(config: WorldConfig) -> str:
    """Why ``config``'s robots and packs do not fit its field (each arena's share, with
    several arenas), in one line naming the fields and what fits ("" if they fit)."""
    n, k, size = config.robots_per_arena, config.packs_per_arena, config.field_size
    gap, clearance = config.pack_gap, config.pack_wall_clearance
    r = robot_model(config.robot).body_radius
    if fits(n, k, size, gap, clearance, r):
        return ""
    # With several arenas the counts are each arena's: name them by their fields.
    robots, packs = "n_robots", "n_packs"
    if config.arenas > 1:
        robots, packs = "n_robots / arenas", "n_packs / arenas"
    need = smallest_field(n, k, gap, clearance, r)
    if not _packs_fit(k, gap, clearance, size):
        alone = most_packs(0, size, gap, clearance, r)
        return (
            f"{packs}={k} packs do not fit in the field_size={size:g} m field with "
            f"pack_gap={gap} m and pack_wall_clearance={clearance} m: at most {max(alone, 0)} "
            f"fit; {n} robots and {k} packs need field_size >= {need:g} m (or a smaller "
            "pack_gap or pack_wall_clearance)"
        )
    most = most_packs(n, size, gap, clearance, r)
    beside = f"{n} robots with at most {most} packs" if most >= 0 else f"fewer than {n} robots"
    return (
        f"{robots}={n} and {packs}={k} do not fit in the field_size={size:g} m field together "
        f"with pack_gap={gap} m: it holds {beside}, or {k} packs with at most "
        f"{most_robots(k, size, gap, clearance, r)} robots; {n} robots and {k} packs need "
        f"field_size >= {need:g} m"
    )


#: The robots' contact models (:attr:`WorldConfig.contacts`).
CONTACT_MODELS = ("fixed", "published")
#: Impedance of the docking hold (the weld of a docked robot) in the fixed contact model: a
#: robot ramming a docked one from the side at 0.8 m/s for 3 s moves it 2.5 mm (MuJoCo's
#: default, 0.9-0.95, lets it creep 12.5 mm once the rammer's chassis, not its teeth, does
#: the pushing; ``tests/test_survival_physics.py``).
DOCK_HOLD_SOLIMP = (0.95, 0.99, 0.001)


@dataclass(frozen=True)
class WorldConfig:
    """Physical setup of the field.

    Attributes:
        field_size: side of the square, walled field, m (paper: 2.3). The walls, the placement
            and the camera's default range (the field's diagonal, docs/design.md §9.21)
            follow it; the inputs' distance normalisation does not (it stays the paper
            field's diagonal, 3.25 m, which the shipped behaviours learned on: §9.19). A
            colony at the paper's density has a side of 2.3 m x sqrt(n_robots / 4).
        n_robots: number of Cyber Rodents (paper, simulation: 4).
        n_packs: number of battery packs (paper, simulation: 5; hardware: 6).
        timestep: physics timestep in seconds. 1/120 s (24 substeps per 0.2 s control step)
            is the largest step, of those that divide the control step, whose trajectories
            stay within 2 cm of a 5x finer reference over 10 s of scripted driving
            (``benchmarks/timestep_study.py``: 1.90 cm; 1/110 s gives 2.39 cm).
        pack_gap: smallest gap between the edges of two packs placed by :meth:`World.reset`,
            m. The default 0.3 m is wider than a robot turning in place (0.28 m), so no robot
            gets jammed between two packs; a larger gap spreads the packs out (docs/design.md
            §9.18).
        pack_wall_clearance: smallest gap between a pack's edge and a wall at
            :meth:`World.reset`, m (half the pack gap if that is more). The default 0.2 m lets
            a robot (18 cm wide) pass between a pack and a wall (docs/design.md §9.18).
        pack_reactivation_steps: control steps a pack stays inactive after a robot docks onto
            it (docs/design.md §9.26). A docking during control step t makes the pack inactive
            at once, for the rest of step t and the N control steps after it (t+1 .. t+N); it
            is active again from control step t+N+1 (seen by that step's vision, dockable in
            that step's docking). An inactive pack is dark (invisible to both vision providers)
            and takes no new docking, but it is still a body that collides and hides what is
            behind it; a robot already docked onto it keeps recharging. 0, the default, is the
            paper's rule: packs are always available.
        arenas: copies of the field, each with its own four walls, ``n_robots / arenas``
            robots and ``n_packs / arenas`` packs (both must divide evenly; docs/design.md
            §9.33). 1, the default, is the paper's world. They are laid out in a grid of
            ceil(sqrt(arenas)) columns, filled row by row from the top left
            (:func:`arena_centres`), the outer faces of neighbouring arenas' walls
            :data:`ARENA_GAP` (0.2 m) apart, the whole centred on the origin, on one floor.
            Robot r is in arena r // (n_robots / arenas), pack j in arena
            j // (n_packs / arenas) (:attr:`World.robot_arena`, :attr:`World.pack_arena`).
            Placement, the fit check and the camera's default range are each arena's; a
            robot sees only its own arena's targets (the walls hide the others too) and IR
            mating pairs only robots of one arena. Adds robots while each keeps the paper's
            local world. The layout is at most :data:`MAX_FIELD_SIZE` wide.
        contacts: the robots' contact model. ``"fixed"``, the default (docs/design.md
            §9.35): the charging teeth, which stick out below another robot's body box, touch
            the floor, walls and packs but no robot, the chassis boxes meet each other
            (collision bit 4, :data:`cyber_rodent.constants.ROBOT_BIT`), and the docking hold
            is stiff (:data:`DOCK_HOLD_SOLIMP`). ``"published"``: the model the first
            published results ran on, whose teeth also touch other robots' bodies (a fast
            knock could lever a robot onto its back) and whose docking hold has MuJoCo's
            default impedance.
        robot: the robots' kind, a name of :data:`cyber_rodent.robot.ROBOTS`
            (``cyber_rodent``, the default, is the paper's robot; ``small_disc`` an e-puck
            class one; ``docs/extending.md`` §9). Its model (:class:`~cyber_rodent.robot.
            RobotModel`, :attr:`World.robot`) gives the body, the drive and the sensors;
            placement and the fit check keep its clearance disc free.

    The counts are bounded by :data:`MAX_ROBOTS` and :data:`MAX_PACKS` and by what fits in
    the field (:func:`fits`; with several arenas, what fits in each): the packs alone in the
    square the wall clearance leaves them, and robots and packs together, each at the packing
    density the placement can still draw. A combination that does not fit is refused with one
    line naming the fields, what the field holds and the smallest field that holds it.
    """

    field_size: float = number(
        C.FIELD_SIZE, MIN_FIELD_SIZE, MAX_FIELD_SIZE, unit="m", source="paper §3.2"
    )
    n_robots: int = integer(4, 1, MAX_ROBOTS, unit="robots", source="paper §3.2")
    n_packs: int = integer(5, 0, MAX_PACKS, unit="packs", source="paper §3.2")
    timestep: float = number(1.0 / 120.0, 1e-4, 0.05, unit="s", source="docs/design.md §4")
    pack_gap: float = number(PACK_GAP, 0.0, 1.5, unit="m", source="docs/design.md §9.18")
    pack_wall_clearance: float = number(
        PACK_WALL_CLEARANCE, 0.0, 0.8, unit="m", source="docs/design.md §9.18"
    )
    pack_reactivation_steps: int = integer(
        0, 0, MAX_REACTIVATION_STEPS, unit="control steps", source="docs/design.md §9.26"
    )
    arenas: int = integer(1, 1, MAX_ARENAS, unit="arenas", source="docs/design.md §9.33")
    contacts: str = choice("fixed", CONTACT_MODELS, source="docs/design.md §9.35")
    robot: str = choice("cyber_rodent", robot_names, source="docs/design.md §4")

    def __post_init__(self) -> None:
        validate_fields(self)
        problem = _layout_problem(self) or _fit_problem(self)
        if problem:
            raise ValueError(problem)

    @property
    def diagonal(self) -> float:
        """The field's diagonal, m (3.25 m for the paper's 2.3 m field); one arena's with
        several."""
        return self.field_size * math.sqrt(2)

    @property
    def robots_per_arena(self) -> int:
        """Robots in each arena: ``n_robots / arenas``."""
        return self.n_robots // self.arenas

    @property
    def packs_per_arena(self) -> int:
        """Packs in each arena: ``n_packs / arenas``."""
        return self.n_packs // self.arenas

    @property
    def extent(self) -> float:
        """Side of the square, centred on the origin, that holds every arena's field, m
        (:func:`arena_extent`): ``field_size`` with one arena."""
        return arena_extent(self.arenas, self.field_size)


def resize_field(arena: mjcf.RootElement, field_size: float) -> None:
    """Move the arena's walls, floor and top-down camera to a field of side ``field_size``.

    The arena file is the paper's 2.3 m field: each wall keeps its thickness and height, and
    moves out by the change in half side, growing by the same amount so that the corners stay
    closed; the floor grows with them and the top-down camera rises in proportion, so the whole
    field stays in its view. At 2.3 m nothing changes (the same compiled model, bit for bit).
    """
    grow = field_size / 2 - C.FIELD_SIZE / 2
    if grow == 0.0:
        return
    floor = arena.find("geom", C.FLOOR_GEOM)
    floor.size = [floor.size[0] + grow, floor.size[1] + grow, floor.size[2]]
    for name in C.WALL_GEOMS:
        wall = arena.find("geom", name)
        pos, size = list(wall.pos), list(wall.size)
        axis = 0 if abs(pos[0]) > abs(pos[1]) else 1  # the axis the wall stands across
        pos[axis] += math.copysign(grow, pos[axis])
        size[1 - axis] += grow
        wall.pos, wall.size = pos, size
    camera = arena.find("camera", C.TOP_CAMERA)
    camera.pos = [camera.pos[0], camera.pos[1], camera.pos[2] * (field_size / C.FIELD_SIZE)]


def arena_body_name(arena: int) -> str:
    """Name of the static body that carries arena ``arena``'s walls (several arenas only)."""
    return f"arena_{arena}"


def lay_out_arenas(arena: mjcf.RootElement, field_size: float, arenas: int) -> None:
    """Turn the (resized) arena's one field into ``arenas`` copies side by side.

    Each arena's four walls are the arena file's (their names: :func:`arena_wall_name`, arena
    0's unchanged), carried by a static body of its own at the arena's centre
    (:func:`arena_body_name`, :func:`arena_centres`). Not the world body: MuJoCo's broad phase
    pairs a robot with a whole body, and with the midphase off (``arena.xml``) it then tests
    the robot's geoms against each of that body's geoms, so one world body holding every
    arena's walls doubled the collision cost at 25 arenas; a body per arena is paired only
    with the robots near it. Static bodies never collide with each other or the floor. The
    floor grows to the whole layout, and the top-down camera rises until the layout's extent
    fills its view as one field did. With one arena nothing changes (the same model, bit for
    bit).
    """
    if arenas == 1:
        return
    centres = arena_centres(arenas, field_size)
    columns, rows = arena_grid(arenas)
    pitch = arena_pitch(field_size)
    walls = [arena.find("geom", name) for name in C.WALL_GEOMS]
    templates = [wall.get_attributes() for wall in walls]
    for wall in walls:
        wall.remove()
    for a, (cx, cy) in enumerate(centres):
        body = arena.worldbody.add("body", name=arena_body_name(a), pos=[cx, cy, 0.0])
        for name, attributes in zip(C.WALL_GEOMS, templates, strict=True):
            body.add("geom", **{**attributes, "name": arena_wall_name(a, name)})
    floor = arena.find("geom", C.FLOOR_GEOM)
    floor.size = [
        floor.size[0] + (columns - 1) * pitch / 2,
        floor.size[1] + (rows - 1) * pitch / 2,
        floor.size[2],
    ]
    camera = arena.find("camera", C.TOP_CAMERA)
    rise = arena_extent(arenas, field_size) / field_size
    camera.pos = [camera.pos[0], camera.pos[1], camera.pos[2] * rise]


def robot_sensor_name(robot: int, sensor: str) -> str:
    """Name of robot ``robot``'s sensor ``sensor`` of a kind other than ``range`` in an
    assembled world (such sensors sit in the world file after every robot's range sensors)."""
    return f"{C.ROBOT_MODEL_PREFIX}_{robot}_{sensor}"


def _detach_sensor(body: mjcf.RootElement, row: SensorRow) -> Any:
    """Remove ``row``'s sensor from a robot's tree if its file has one; its site element."""
    sensor = body.find("sensor", row.name)
    if sensor is not None:
        sensor.remove()
    site = body.find("site", row.site_name)
    if site is None:
        raise ValueError(f"robot {body.model!r} has no site {row.site_name!r} for {row.name!r}")
    return site


def dock_hold_name(robot: int) -> str:
    """Name of robot ``robot``'s docking-hold weld (an equality constraint of the world)."""
    return f"dock_hold_{robot}"


def build_mjcf(
    n_robots: int,
    n_packs: int,
    timestep: float,
    field_size: float = C.FIELD_SIZE,
    arenas: int = 1,
    contacts: str = "fixed",
    robot: RobotModel | None = None,
) -> mjcf.RootElement:
    """The field's MJCF tree with ``n_robots`` robots and ``n_packs`` packs at the origin, in a
    square field of side ``field_size`` (m), or in ``arenas`` such fields side by side
    (:func:`lay_out_arenas`), with the robots' contact model ``contacts``
    (:attr:`WorldConfig.contacts`). The robots are ``robot`` (None: the paper's), each with
    every sensor of its table: its range sensors in its own tree, any other after all robots'
    (:func:`robot_sensor_name`)."""
    robot = robot or robot_model()
    parts = robot.parts
    others = robot.other_sensors
    arena = mjcf.from_path(str(asset_path(C.ARENA_XML)))
    arena.option.timestep = timestep
    resize_field(arena, field_size)
    lay_out_arenas(arena, field_size, arenas)
    # MuJoCo's arena holds the contacts, the constraint rows and the solver's stack. Measured
    # peaks (arena + stack, robots driving into one pile at the paper's density): 0.14 MB for
    # 4 robots, 3.0 MB for 100. 1 MB per robot, at least the arena file's 16 MB, leaves a
    # margin of 30 or more; a larger arena costs address space, not memory, until it is used.
    arena.size.memory = f"{max(16, n_robots)}M"
    robot_file = str(robot.xml_path())
    pack_file = str(asset_path(C.BATTERY_PACK_XML))
    for i in range(n_robots):
        body = mjcf.from_path(robot_file)
        body.model = f"{C.ROBOT_MODEL_PREFIX}_{i}"
        sites = [_detach_sensor(body, row) for row in others]
        if contacts == "published":
            for name in (parts.chassis_geom, parts.teeth_geom):
                geom = body.find("geom", name)
                geom.contype, geom.conaffinity = C.BODY_BIT, C.BODY_BIT
        frame = arena.attach(body)
        frame.add("freejoint")
        # Docking hold (cyber_rodent/survival.py): an inactive weld of the chassis to
        # the world. The survival mechanics switch it on while the robot recharges (setting
        # its relative pose to the pose at docking) and off when recharging ends. Inactive
        # equality constraints cost nothing in the solver.
        hold = arena.equality.add(
            "weld",
            name=dock_hold_name(i),
            body1=body.find("body", parts.root_body),
            active=False,
        )
        if contacts == "fixed":
            hold.solimp = DOCK_HOLD_SOLIMP
        # Sensors of kinds other than range go after every robot's range sensors, so those
        # stay one contiguous block of sensordata (the hot path reads it as one slice).
        for row, site in zip(others, sites, strict=True):
            element = SENSOR_KINDS[row.kind].element
            arena.sensor.add(element, name=robot_sensor_name(i, row.name), site=site)
    for j in range(n_packs):
        pack = mjcf.from_path(pack_file)
        pack.model = f"{C.PACK_MODEL_PREFIX}_{j}"
        arena.attach(pack)  # no joint: a static body fixed in the field
    return arena


class World:
    """N robots and M packs in the walled field (or in several arenas), with fast per-step
    access.

    Args:
        config: the physical setup.
        rng: generator for the initial placement; :meth:`reset` takes its own.

    Attributes:
        robot: the robots' model (``config.robot``): body, drive and sensor table.
        robot_arena: (n_robots,) int, the arena each robot is in: robots in contiguous blocks
            of ``n_robots / arenas`` (robot r in arena r // (n_robots / arenas)); all 0 in the
            paper's one-arena world.
        pack_arena: (n_packs,) int, the arena each pack is in, packs likewise.
        arena_centres: (arenas, 2) m, x, y of each arena's centre (:func:`arena_centres`).
        wall_geom: (arenas, 4) int, each arena's wall geoms, in ``constants.WALL_GEOMS`` order.
    """

    def __init__(self, config: WorldConfig | None = None, rng: np.random.Generator | None = None):
        self.config = config or WorldConfig()
        cfg = self.config
        self.robot: RobotModel = robot_model(cfg.robot)
        self.mjcf_model = build_mjcf(
            cfg.n_robots,
            cfg.n_packs,
            cfg.timestep,
            cfg.field_size,
            cfg.arenas,
            cfg.contacts,
            self.robot,
        )
        # dm_control evaluates the model once as compiled, every robot stacked at the origin
        # until reset() places them: with contacts on, each robot would touch every other
        # there (100 robots overflowed a 400 MB arena). Contacts are off for that evaluation
        # only; nothing compiled depends on the flag.
        flags = self.mjcf_model.option.flag
        flags.contact = "disable"
        self.physics = mjcf.Physics.from_mjcf_model(self.mjcf_model)
        flags.contact = None
        self.model: mujoco.MjModel = self.physics.model.ptr
        self.data: mujoco.MjData = self.physics.data.ptr
        self.model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        self._index()
        self.led_on = np.zeros(self.config.n_robots, dtype=bool)
        #: (n_packs,) the pack shows its colour and takes dockings (``set_pack_active``).
        self.pack_active = np.ones(self.config.n_packs, dtype=bool)
        self.reset(rng if rng is not None else np.random.default_rng(0))

    # --- indexing (once, off the hot path) --------------------------------------------------
    def _index(self) -> None:
        m = self.model
        n = self.config.n_robots
        robot, parts = self.robot, self.robot.parts

        def obj_id(kind: mujoco.mjtObj, name: str) -> int:
            idx = int(mujoco.mj_name2id(m, kind, name))
            if idx < 0:
                raise KeyError(f"model has no {kind.name} named {name!r}")
            return idx

        def contiguous(ids: list[int], what: str) -> slice:
            arr = np.asarray(ids)
            if not np.array_equal(arr, np.arange(arr[0], arr[0] + len(arr))):
                raise RuntimeError(f"{what} are not contiguous in the compiled model")
            return slice(int(arr[0]), int(arr[0]) + len(arr))

        sensor_adr = []
        other_adr = []
        motor_ids = []
        self.root_qpos_adr = np.empty(n, dtype=np.int64)
        self.root_qvel_adr = np.empty(n, dtype=np.int64)
        self.chassis_body = np.empty(n, dtype=np.int64)
        self.led_geom = np.empty(n, dtype=np.int64)
        self.face_geom = np.empty(n, dtype=np.int64)
        self.teeth_geom = np.empty(n, dtype=np.int64)
        self.chassis_geom = np.empty(n, dtype=np.int64)
        self.ir_port_site = np.empty(n, dtype=np.int64)
        self.camera_site = np.empty(n, dtype=np.int64)
        for i in range(n):
            p = C.robot_prefix(i)
            for row in robot.range_sensors:
                sid = obj_id(mujoco.mjtObj.mjOBJ_SENSOR, p + row.name)
                sensor_adr.append(int(m.sensor_adr[sid]))
            for row in robot.other_sensors:
                sid = obj_id(mujoco.mjtObj.mjOBJ_SENSOR, robot_sensor_name(i, row.name))
                other_adr.append(int(m.sensor_adr[sid]) + SENSOR_KINDS[row.kind].component)
            motor_ids += [
                obj_id(mujoco.mjtObj.mjOBJ_ACTUATOR, p + parts.left_motor),
                obj_id(mujoco.mjtObj.mjOBJ_ACTUATOR, p + parts.right_motor),
            ]
            self.chassis_body[i] = obj_id(mujoco.mjtObj.mjOBJ_BODY, p + parts.root_body)
            root = int(m.body_jntadr[m.body_rootid[self.chassis_body[i]]])
            if root < 0 or m.jnt_type[root] != mujoco.mjtJoint.mjJNT_FREE:
                raise RuntimeError(f"robot {i} chassis has no free joint")
            self.root_qpos_adr[i] = m.jnt_qposadr[root]
            self.root_qvel_adr[i] = m.jnt_dofadr[root]
            self.led_geom[i] = obj_id(mujoco.mjtObj.mjOBJ_GEOM, p + parts.led_geom)
            self.face_geom[i] = obj_id(mujoco.mjtObj.mjOBJ_GEOM, p + parts.face_geom)
            self.teeth_geom[i] = obj_id(mujoco.mjtObj.mjOBJ_GEOM, p + parts.teeth_geom)
            self.chassis_geom[i] = obj_id(mujoco.mjtObj.mjOBJ_GEOM, p + parts.chassis_geom)
            self.ir_port_site[i] = obj_id(mujoco.mjtObj.mjOBJ_SITE, p + parts.ir_port_site)
            self.camera_site[i] = obj_id(mujoco.mjtObj.mjOBJ_SITE, p + parts.camera_site)
        self._range_slice = contiguous(sensor_adr, "range sensors")
        self._ctrl_slice = contiguous(motor_ids, "wheel motors")
        #: (n_robots, n_range) each range sensor's range, m (the robot's sensor table).
        self.range_max = np.tile(robot.range_limits, (n, 1))
        # The other sensors' readings: their sensordata addresses, robot-major.
        self._other_adr = np.asarray(other_adr, dtype=np.int64).reshape(n, -1)
        # Per-robot geom ids (every geom of every body under the chassis): for hiding a robot
        # from its own camera and for attributing contacts to robots.
        self.geom_robot = np.full(m.ngeom, -1, dtype=np.int64)
        root_of_body = m.body_rootid
        for i in range(n):
            robot_root = root_of_body[self.chassis_body[i]]
            self.geom_robot[root_of_body[m.geom_bodyid] == robot_root] = i

        self.pack_body = np.array(
            [
                obj_id(mujoco.mjtObj.mjOBJ_BODY, C.pack_prefix(j) + C.PACK_BODY)
                for j in range(self.config.n_packs)
            ],
            dtype=np.int64,
        )
        self.pack_geom = np.array(
            [
                obj_id(mujoco.mjtObj.mjOBJ_GEOM, C.pack_prefix(j) + C.PACK_GEOM)
                for j in range(self.config.n_packs)
            ],
            dtype=np.int64,
        )
        self.electrode_geom = np.array(
            [
                obj_id(mujoco.mjtObj.mjOBJ_GEOM, C.pack_prefix(j) + C.PACK_ELECTRODE_GEOM)
                for j in range(self.config.n_packs)
            ],
            dtype=np.int64,
        )
        #: (n_packs, 4) each pack body's own colour, restored when the pack is active again.
        self.pack_rgba = m.geom_rgba[self.pack_geom].astype(np.float64)
        self.top_camera = obj_id(mujoco.mjtObj.mjOBJ_CAMERA, C.TOP_CAMERA)
        cfg = self.config
        self.robot_arena = np.repeat(np.arange(cfg.arenas, dtype=np.int64), cfg.robots_per_arena)
        self.pack_arena = np.repeat(np.arange(cfg.arenas, dtype=np.int64), cfg.packs_per_arena)
        self.arena_centres = arena_centres(cfg.arenas, cfg.field_size)
        walls = [
            [obj_id(mujoco.mjtObj.mjOBJ_GEOM, arena_wall_name(a, w)) for w in C.WALL_GEOMS]
            for a in range(cfg.arenas)
        ]
        self.wall_geom = np.array(walls, dtype=np.int64).reshape(cfg.arenas, len(C.WALL_GEOMS))
        # Wheel radius and top speed read from the compiled model (the robot model rounds them
        # to the micrometre; the commands' conversion keeps the file's own numbers).
        wheel_geom = obj_id(mujoco.mjtObj.mjOBJ_GEOM, C.robot_prefix(0) + parts.left_wheel_geom)
        self.wheel_radius = float(m.geom_size[wheel_geom, 0])
        self.max_wheel_omega = float(m.actuator_ctrlrange[motor_ids[0], 1])
        # Views into MjData for the hot path.
        self._ctrl: np.ndarray = self.data.ctrl[self._ctrl_slice].reshape(n, 2)
        self._ranges_raw: np.ndarray = self.data.sensordata[self._range_slice].reshape(
            n, robot.n_range
        )

    # --- placement ---------------------------------------------------------------------------
    def reset(self, rng: np.random.Generator) -> None:
        """Zero the dynamics and place robots and packs at random, without overlap.

        Robots get uniformly random headings. Placement uses rejection sampling with clearance
        the robot's ``body_radius`` / ``PACK_RADIUS`` plus a margin, from walls and from each
        other; packs keep ``pack_gap`` between them and ``pack_wall_clearance`` from the walls.
        With several arenas each is placed by the same rules in turn, arena 0 first (its robots
        and packs: :attr:`robot_arena`, :attr:`pack_arena`), then every robot's heading. Every
        pack is active again.
        """
        mujoco.mj_resetData(self.model, self.data)
        cfg = self.config
        n, k = cfg.n_robots, cfg.n_packs
        n_arena, k_arena = cfg.robots_per_arena, cfg.packs_per_arena
        radii = np.concatenate(
            [
                np.full(n_arena, _robot_placement_radius(self.robot.body_radius)),
                np.full(k_arena, _pack_placement_radius(cfg.pack_gap)),
            ]
        )
        pack_wall = _pack_wall_margin(cfg.pack_gap, cfg.pack_wall_clearance)
        wall_margin = np.concatenate([np.zeros(n_arena), np.full(k_arena, pack_wall)])
        robots, packs = np.empty((n, 2)), np.empty((k, 2))
        for a, offset in enumerate(self.arena_centres):
            centres = place_discs(radii, cfg.field_size / 2, rng, wall_margin) + offset
            robots[a * n_arena : (a + 1) * n_arena] = centres[:n_arena]
            packs[a * k_arena : (a + 1) * k_arena] = centres[n_arena:]
        yaw = rng.uniform(-math.pi, math.pi, size=n)
        for i in range(n):
            self.set_robot_pose(i, robots[i, 0], robots[i, 1], yaw[i])
        for j in range(k):
            self.model.body_pos[self.pack_body[j], :2] = packs[j]
        self.led_on[:] = False
        self.model.geom_rgba[self.led_geom] = LED_OFF_RGBA
        self.pack_active[:] = True
        self.model.geom_rgba[self.pack_geom] = self.pack_rgba
        mujoco.mj_forward(self.model, self.data)

    def set_robot_pose(self, i: int, x: float, y: float, yaw: float) -> None:
        """Put robot ``i`` at rest on the floor at (x, y) facing ``yaw`` (call mj_forward after)."""
        a = int(self.root_qpos_adr[i])
        self.data.qpos[a : a + 3] = (x, y, 0.0)
        self.data.qpos[a + 3 : a + 7] = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
        v = int(self.root_qvel_adr[i])
        self.data.qvel[v : v + 6] = 0.0

    def set_pack_position(self, j: int, x: float, y: float) -> None:
        """Move static pack ``j`` (call mj_forward after)."""
        self.model.body_pos[self.pack_body[j], :2] = (x, y)

    # --- per-step access ---------------------------------------------------------------------
    def set_wheel_speeds(self, left: np.ndarray, right: np.ndarray) -> None:
        """Command wheel rim speeds in m/s for all robots; clipped to the robot's top speed.

        Raises:
            ValueError: if any command is NaN or infinite.
        """
        left = np.asarray(left, dtype=float)
        right = np.asarray(right, dtype=float)
        if not (np.all(np.isfinite(left)) and np.all(np.isfinite(right))):
            raise ValueError("wheel speed commands must be finite (got NaN or inf)")
        self._ctrl[:, 0] = left
        self._ctrl[:, 1] = right
        self._ctrl *= 1.0 / self.wheel_radius
        np.clip(self._ctrl, -self.max_wheel_omega, self.max_wheel_omega, out=self._ctrl)

    def step(self, n_substeps: int = 1) -> None:
        """Advance the physics by ``n_substeps`` timesteps."""
        mujoco.mj_step(self.model, self.data, nstep=n_substeps)

    @property
    def range_sensordata(self) -> np.ndarray:
        """(n_robots, n_range) live view of the rangefinders' raw ``sensordata`` (-1: no hit), for
        hot loops that saturate the readings themselves (see :meth:`range_readings`)."""
        return self._ranges_raw

    def range_readings(self, out: np.ndarray | None = None) -> np.ndarray:
        """(n_robots, n_range) distances in metres, in the order of the robot's range sensors
        (:attr:`~cyber_rodent.robot.RobotModel.range_sensors`).

        A ray that hits nothing within a sensor's range reads that sensor's range (the reading
        saturates, as an IR sensor's does).
        """
        raw = self._ranges_raw
        if out is None:
            out = np.empty_like(raw)
        np.copyto(out, raw)
        np.putmask(out, (raw < 0) | (raw > self.range_max), self.range_max)
        return out

    def sensor_values(self, out: np.ndarray | None = None) -> np.ndarray:
        """(n_robots, k) the values of the robot's sensors of every kind but ``range``
        (:attr:`~cyber_rodent.robot.RobotModel.other_sensors`, in table order), each read by
        its kind's reader; (n_robots, 0) for a robot with range sensors only."""
        raw = self.data.sensordata[self._other_adr]
        if out is None:
            out = np.empty_like(raw)
        rows = self.robot.other_sensors
        for kind in {row.kind for row in rows}:
            cols = [j for j, row in enumerate(rows) if row.kind == kind]
            limit = np.array([rows[j].limit for j in cols])
            values = np.empty((raw.shape[0], len(cols)))
            SENSOR_KINDS[kind].read(raw[:, cols], limit, values)
            out[:, cols] = values
        return out

    def poses(self) -> np.ndarray:
        """(n_robots, 3) array of x, y, yaw (rad) of each chassis."""
        xpos = self.data.xpos[self.chassis_body]
        xmat = self.data.xmat[self.chassis_body]
        yaw = np.arctan2(xmat[:, 3], xmat[:, 0])
        return np.column_stack([xpos[:, 0], xpos[:, 1], yaw])

    def uprightness(self) -> np.ndarray:
        """(n_robots,) body z-axis · world z: 1 upright, 0 on its side."""
        upright: np.ndarray = self.data.xmat[self.chassis_body, 8].copy()
        return upright

    def pack_positions(self) -> np.ndarray:
        """(n_packs, 2) x, y of each pack."""
        positions: np.ndarray = self.model.body_pos[self.pack_body, :2].copy()
        return positions

    def set_led(self, on: np.ndarray | bool, robot: int | None = None) -> None:
        """Switch LEDs on (green) or off (dark): all robots, or only ``robot``."""
        if robot is None:
            self.led_on[:] = np.broadcast_to(np.asarray(on, dtype=bool), self.led_on.shape)
        else:
            self.led_on[robot] = bool(on)
        self.model.geom_rgba[self.led_geom] = np.where(
            self.led_on[:, None], LED_ON_RGBA, LED_OFF_RGBA
        )

    def set_pack_active(self, pack: int, active: bool) -> None:
        """Show pack ``pack`` in its colour and let robots dock onto it, or make it inactive:
        dark grey (:data:`PACK_INACTIVE_RGBA`), invisible to vision, refusing new dockings
        (``WorldConfig.pack_reactivation_steps``)."""
        self.pack_active[pack] = bool(active)
        self.model.geom_rgba[self.pack_geom[pack]] = (
            self.pack_rgba[pack] if active else PACK_INACTIVE_RGBA
        )

    @property
    def time(self) -> float:
        return float(self.data.time)

    def replace(self, **changes: Any) -> World:
        """A new world with some config fields changed (placement from a fixed seed)."""
        return World(dataclasses.replace(self.config, **changes))


def place_discs(
    radii: np.ndarray,
    half_size: float,
    rng: np.random.Generator,
    wall_margin: np.ndarray | None = None,
) -> np.ndarray:
    """Centres for discs of ``radii`` inside [-half_size, half_size]², with no overlaps.

    ``wall_margin`` (per disc, default 0) keeps a disc that much further from the walls.

    Large discs are placed first (rejection sampling each), which keeps the draw order, and so
    the result, a pure function of the generator's state.

    Raises:
        ValueError: if the discs cannot be placed.
    """
    order = np.argsort(-radii, kind="stable")
    centres = np.zeros((len(radii), 2))
    margin = np.zeros(len(radii)) if wall_margin is None else np.asarray(wall_margin)
    placed: list[int] = []
    for idx in order:
        r = radii[idx]
        lim = half_size - r - margin[idx]
        if lim <= 0:
            raise ValueError(f"a disc of radius {r:.3f} m does not fit in the field")
        for _ in range(_PLACEMENT_ATTEMPTS):
            c = rng.uniform(-lim, lim, size=2)
            if not placed or np.all(np.hypot(*(centres[placed] - c).T) >= radii[placed] + r):
                centres[idx] = c
                placed.append(int(idx))
                break
        else:
            raise ValueError(
                f"could not place {len(radii)} bodies without overlap in the field; "
                "reduce n_robots, n_packs, pack_gap or pack_wall_clearance"
            )
    return centres
