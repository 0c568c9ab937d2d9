"""Hand-built hard scenes for the vision providers: the clutter a colony really makes.

Random placements (:func:`cyber_rodent.vision.agreement.random_scene`) rarely put robots in a
row, a pack right behind a robot or three robots around one pack, yet the colony does exactly
that: robots gather on packs, meet face to face to mate and look across the whole field. Each
family here builds such scenes through the public world API (robot poses, pack positions,
LEDs), seeded and jittered, so that both providers can be compared where they are most likely
to disagree (``benchmarks/vision_hard_scenes.py``; a few scenes of each family are tests).

A scene is physically valid: no two bodies interpenetrate by more than
:data:`MAX_PENETRATION` by MuJoCo's own collision geometry (touching is allowed), and everything
stands inside the walls. Each scene names its *designed* observer→target pairs, the ones the
family is about (the occluded robot of a row, the pack behind a robot, ...).

Target indices follow :class:`~cyber_rodent.vision.geometric.GeometricVision`: the LED of
robot ``j`` is ``j``, its face ``n_robots + j``, pack ``k`` is ``2 * n_robots + k``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.robot import robot_model
from cyber_rodent.world import World, WorldConfig

#: m, the deepest interpenetration of two bodies' collision geoms a scene may have.
MAX_PENETRATION = 0.001
#: m, pack centres stay this far inside the walls.
_PACK_MARGIN = C.PACK_RADIUS + 0.01
#: m, half the side of the paper's field, which the families' scenes are drawn in
#: (:meth:`Family.world_config`).
_HALF = C.FIELD_SIZE / 2
#: m, robot centre to pack centre when the robot's teeth touch the pack's electrode ring (the
#: teeth's front face is 0.134 m ahead of the robot's origin).
TEETH_TO_PACK = 0.134 + C.PACK_RADIUS
#: m, robot centre to pack centre when the pack touches the chassis side (half width 0.07).
SIDE_TO_PACK = 0.07 + C.PACK_RADIUS


@dataclass(frozen=True)
class Scene:
    """One hand-built scene.

    Attributes:
        robots: (x, y, yaw) of every robot, m and rad.
        packs: (x, y) of every pack, m.
        leds: whether each robot's LED is on.
        designed: (observer, target) pairs the scene is built to test (target indices as in
            the module docstring).
    """

    robots: tuple[tuple[float, float, float], ...]
    packs: tuple[tuple[float, float], ...]
    leds: tuple[bool, ...]
    designed: tuple[tuple[int, int], ...] = field(default=())


@dataclass(frozen=True)
class Family:
    """A family of hard scenes: a name, its world's counts and a seeded scene builder.

    Attributes:
        name: short identifier (used in tables and file names).
        title: what the scenes show, for tables.
        n_robots, n_packs: the world the scenes are built in.
        build: ``build(rng)`` proposes one scene (it may be invalid; :func:`make_scenes`
            redraws it).
    """

    name: str
    title: str
    n_robots: int
    n_packs: int
    build: Callable[[np.random.Generator], Scene]

    def world_config(self) -> WorldConfig:
        return WorldConfig(n_robots=self.n_robots, n_packs=self.n_packs)


def led(robot: int) -> int:
    """Target index of robot ``robot``'s LED."""
    return robot


def face(robot: int, n_robots: int) -> int:
    """Target index of robot ``robot``'s face."""
    return n_robots + robot


def pack(k: int, n_robots: int) -> int:
    """Target index of pack ``k``."""
    return 2 * n_robots + k


def place(world: World, scene: Scene) -> None:
    """Put the world in ``scene``'s state (poses, packs, LEDs; then ``mj_forward``)."""
    for i, (x, y, yaw) in enumerate(scene.robots):
        world.set_robot_pose(i, x, y, yaw)
    for k, (x, y) in enumerate(scene.packs):
        world.set_pack_position(k, x, y)
    world.set_led(np.asarray(scene.leds, dtype=bool))
    mujoco.mj_forward(world.model, world.data)


def valid(world: World, scene: Scene) -> bool:
    """Whether ``scene`` stands inside the walls with no interpenetrating bodies (placed)."""
    half = world.config.field_size / 2
    for x, y, _ in scene.robots:
        if max(abs(x), abs(y)) > half - robot_model().body_radius:
            return False
    for x, y in scene.packs:
        if max(abs(x), abs(y)) > half - _PACK_MARGIN:
            return False
    place(world, scene)
    d = world.data
    for c in range(d.ncon):
        con = d.contact[c]
        if con.dist < -MAX_PENETRATION:
            return False
    return True


def make_scenes(world: World, family: Family, count: int, seed: int) -> list[Scene]:
    """``count`` valid scenes of ``family`` in ``world`` (built for it), deterministic in
    ``seed``. The world is left in the last scene's state.

    Raises:
        ValueError: if the world's counts are not the family's, or a scene cannot be drawn.
    """
    if (world.config.n_robots, world.config.n_packs) != (family.n_robots, family.n_packs):
        raise ValueError(
            f"family {family.name} needs {family.n_robots} robots and {family.n_packs} packs"
        )
    scenes = []
    for s in range(count):
        rng = np.random.default_rng([seed, s])
        for _attempt in range(1000):
            scene = family.build(rng)
            if valid(world, scene):
                scenes.append(scene)
                break
        else:
            raise ValueError(f"family {family.name}: no valid scene in 1000 draws (scene {s})")
    return scenes


# --- building blocks ---------------------------------------------------------------------------
def ahead(
    x: float, y: float, direction: float, distance: float, lateral: float = 0.0
) -> tuple[float, float]:
    """The point ``distance`` along ``direction`` from (x, y), shifted ``lateral`` to its left."""
    c, s = math.cos(direction), math.sin(direction)
    return float(x + distance * c - lateral * s), float(y + distance * s + lateral * c)


def inside(rng: np.random.Generator, margin: float) -> tuple[float, float]:
    lim = _HALF - margin
    return float(rng.uniform(-lim, lim)), float(rng.uniform(-lim, lim))


def random_yaw(rng: np.random.Generator) -> float:
    return float(rng.uniform(-math.pi, math.pi))


def random_leds(rng: np.random.Generator, n: int, p: float = 0.8) -> tuple[bool, ...]:
    return tuple(bool(v) for v in rng.random(n) < p)


def _towards(x: float, y: float, tx: float, ty: float) -> float:
    return math.atan2(ty - y, tx - x)


# --- the families ------------------------------------------------------------------------------
def _row(rng: np.random.Generator) -> Scene:
    """An observer and three robots in a row ahead of it; the middle ones hide the far ones,
    with a small sideways jitter so that slivers of the hidden ones show."""
    n = 4
    x0, y0 = inside(rng, 0.25)
    direction = _towards(x0, y0, *inside(rng, 0.6)) + rng.uniform(-0.3, 0.3)
    first = rng.uniform(0.3, 0.6)
    spacing = rng.uniform(0.2, 0.4)
    robots = [(x0, y0, direction + rng.uniform(-math.pi, math.pi))]
    for k in range(3):
        x, y = ahead(x0, y0, direction, first + k * spacing, rng.uniform(-0.07, 0.07))
        robots.append((x, y, random_yaw(rng)))
    packs = [inside(rng, 0.1)]
    designed = [(0, t) for j in (2, 3) for t in (led(j), face(j, n))]
    return Scene(tuple(robots), tuple(packs), random_leds(rng, n), tuple(designed))


def _behind(rng: np.random.Generator) -> Scene:
    """A pack just behind a robot, and a robot just behind a pack, both seen by the observer
    over or past the nearer one."""
    n = 3
    x0, y0 = inside(rng, 0.25)
    robots = [(x0, y0, random_yaw(rng))]
    packs = []
    base = _towards(x0, y0, 0.0, 0.0)
    # A robot, then a pack behind it.
    d1 = rng.uniform(0.3, 0.8)
    a1 = base + rng.uniform(-0.8, 0.8)
    rx, ry = ahead(x0, y0, a1, d1)
    robots.append((rx, ry, random_yaw(rng)))
    packs.append(ahead(x0, y0, a1, d1 + rng.uniform(0.14, 0.35), rng.uniform(-0.1, 0.1)))
    # A pack, then a robot behind it.
    a2 = a1 + rng.choice([-1, 1]) * rng.uniform(0.5, 1.2)
    d2 = rng.uniform(0.25, 0.7)
    packs.append(ahead(x0, y0, a2, d2))
    px, py = ahead(x0, y0, a2, d2 + rng.uniform(0.2, 0.4), rng.uniform(-0.08, 0.08))
    robots.append((px, py, random_yaw(rng)))
    packs.append(inside(rng, 0.1))
    designed = [(0, pack(0, n)), (0, led(2)), (0, face(2, n)), (0, pack(1, n))]
    return Scene(tuple(robots), tuple(packs), random_leds(rng, n), tuple(designed))


def _touching(rng: np.random.Generator) -> Scene:
    """Three robots gathered on one pack (teeth or sides touching it, and each other), and an
    observer that touches a pack of its own with its front or side while it looks at them."""
    n = 4
    cx, cy = inside(rng, 0.35)
    packs = [(cx, cy)]
    robots: list[tuple[float, float, float]] = []
    start = random_yaw(rng)
    for k in range(3):
        around = start + k * rng.uniform(1.6, 2.3)
        docked = rng.random() < 0.7
        reach = TEETH_TO_PACK if docked else SIDE_TO_PACK
        x, y = ahead(cx, cy, around, reach + rng.uniform(0.0, 0.004))
        facing = around + math.pi if docked else around + rng.choice([-1, 1]) * math.pi / 2
        robots.append((x, y, facing + rng.uniform(-0.15, 0.15)))
    # The observer, 0.3-1.0 m from the cluster, with a pack touching its front or side.
    d = rng.uniform(0.35, 1.0)
    ox, oy = ahead(cx, cy, random_yaw(rng), d)
    look = _towards(ox, oy, cx, cy) + rng.uniform(-1.0, 1.0)
    side = rng.choice([0.0, math.pi / 2, -math.pi / 2, rng.uniform(-0.6, 0.6)])
    reach = TEETH_TO_PACK if abs(side) < 0.7 else SIDE_TO_PACK
    packs.append(ahead(ox, oy, look + side, reach + rng.uniform(0.0, 0.004)))
    robots.insert(0, (ox, oy, look))
    designed = [(0, pack(0, n)), (0, pack(1, n))]
    designed += [(0, t) for j in (1, 2, 3) for t in (led(j), face(j, n))]
    return Scene(tuple(robots), tuple(packs), random_leds(rng, n), tuple(designed))


def _seams(rng: np.random.Generator) -> Scene:
    """Targets whose axis lies within a few degrees of a seam between two of the 4 views."""
    n = 3
    x0, y0 = inside(rng, 0.4)
    yaw = random_yaw(rng)
    robots = [(x0, y0, yaw)]
    packs = []
    seams = rng.permutation([math.pi / 4, 3 * math.pi / 4, -math.pi / 4, -3 * math.pi / 4])
    for k, seam in enumerate(seams[:4]):
        bearing = yaw + seam + math.radians(rng.uniform(-4.0, 4.0))
        if k < 2:
            x, y = ahead(x0, y0, bearing, rng.uniform(0.3, 1.5))
            robots.append((x, y, random_yaw(rng)))
        else:
            packs.append(ahead(x0, y0, bearing, rng.uniform(0.17, 1.5)))
    designed = [(0, led(1)), (0, face(1, n)), (0, led(2)), (0, face(2, n))]
    designed += [(0, pack(0, n)), (0, pack(1, n))]
    return Scene(tuple(robots), tuple(packs), random_leds(rng, n, 1.0), tuple(designed))


def _far(rng: np.random.Generator) -> Scene:
    """An observer in one corner, robots and packs across the field near the opposite one:
    1.4-3 m, the camera's resolution limit."""
    n = 3
    lim = _HALF - 0.16
    corner = rng.choice([-1.0, 1.0], size=2)
    x0, y0 = corner * (lim - rng.uniform(0.0, 0.1, size=2))
    robots = [(float(x0), float(y0), random_yaw(rng))]
    packs = []
    for k in range(5):
        d = rng.uniform(1.4, 3.0)
        a = _towards(x0, y0, 0.0, 0.0) + rng.uniform(-0.5, 0.5)
        x, y = ahead(float(x0), float(y0), a, d)
        if k < 2:
            robots.append((x, y, random_yaw(rng)))
        else:
            packs.append((x, y))
    designed = [(0, t) for j in (1, 2) for t in (led(j), face(j, n))]
    designed += [(0, pack(k, n)) for k in range(3)]
    return Scene(tuple(robots), tuple(packs), random_leds(rng, n, 1.0), tuple(designed))


def _pack_cluster(rng: np.random.Generator) -> Scene:
    """Packs touching or nearly touching one another, seen from 0.2-1.5 m: in the image a
    farther pack stands above, beside or behind a nearer one."""
    n = 2
    cx, cy = inside(rng, 0.4)
    packs = [(cx, cy)]
    while len(packs) < 5:
        ax, ay = packs[int(rng.integers(len(packs)))]
        gap = rng.uniform(0.0, 0.1)
        x, y = ahead(ax, ay, random_yaw(rng), 2 * C.PACK_RADIUS + gap)
        if all(math.hypot(x - px, y - py) >= 2 * C.PACK_RADIUS for px, py in packs):
            packs.append((x, y))
    d = rng.uniform(0.3, 1.5)
    ox, oy = ahead(cx, cy, random_yaw(rng), d)
    robots = [(ox, oy, random_yaw(rng)), inside(rng, 0.2) + (random_yaw(rng),)]
    designed = [(0, pack(k, n)) for k in range(5)]
    return Scene(tuple(robots), tuple(packs), random_leds(rng, n), tuple(designed))


def _face_to_face(rng: np.random.Generator) -> Scene:
    """Two pairs of robots nose to nose, as when they mate (IR ports 0.05-0.35 m apart, within
    ±15°), near each other: each robot's partner face is the one the Mate behaviour reads."""
    n = 4
    robots: list[tuple[float, float, float]] = []
    cx, cy = inside(rng, 0.4)
    heading = random_yaw(rng)
    for pair in range(2):
        if pair == 1:
            cx, cy = ahead(cx, cy, random_yaw(rng), rng.uniform(0.45, 0.9))
            heading = random_yaw(rng)
        gap = 0.222 + rng.uniform(0.05, 0.35)  # centre to centre: 2 × 0.111 to the ports
        ax, ay = ahead(cx, cy, heading, -gap / 2)
        bx, by = ahead(cx, cy, heading, gap / 2)
        robots.append((ax, ay, heading + math.radians(rng.uniform(-15, 15))))
        robots.append((bx, by, heading + math.pi + math.radians(rng.uniform(-15, 15))))
    packs = [inside(rng, 0.1), inside(rng, 0.1)]
    designed = [(0, face(1, n)), (1, face(0, n)), (2, face(3, n)), (3, face(2, n))]
    designed += [(0, led(1)), (1, led(0)), (2, led(3)), (3, led(2))]
    return Scene(tuple(robots), tuple(packs), random_leds(rng, n), tuple(designed))


#: Every family, in report order.
FAMILIES: tuple[Family, ...] = (
    Family("row", "robots in a row, the middle ones occluding", 4, 1, _row),
    Family("behind", "a pack behind a robot, a robot behind a pack", 3, 3, _behind),
    Family("touching", "robots gathered on a pack, a pack touching the observer", 4, 2, _touching),
    Family("seams", "targets at the seams between the 4 views", 3, 2, _seams),
    Family("far", "targets across the field, 1.4-3 m", 3, 3, _far),
    Family("pack_cluster", "packs touching or nearly touching", 2, 5, _pack_cluster),
    Family("face_to_face", "two mating pairs nose to nose", 4, 2, _face_to_face),
)


def family(name: str) -> Family:
    """The family called ``name``.

    Raises:
        ValueError: for an unknown name (the message lists the known ones).
    """
    for f in FAMILIES:
        if f.name == name:
            return f
    raise ValueError(f"unknown scene family {name!r}; known: {', '.join(f.name for f in FAMILIES)}")
