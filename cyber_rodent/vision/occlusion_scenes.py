"""Randomised partial-occlusion scenes: targets partly hidden by a robot, generated from seeds.

:mod:`cyber_rodent.vision.hard_scenes` designs its families by hand, with small jitters. The
families here are generated instead: every distance, lateral offset, heading and LED is drawn
from a seed within wide ranges, so that the targets behind a robot show every share of their
occlusion samples, from a sliver to the whole. They measure where the providers disagree most,
the targets only partly in view (``benchmarks/vision_occlusion.py``).

* ``rows``: 3 or 4 robots in a row, the observer at one end, gaps of 0.25-1.0 m, the row in
  any direction and each robot beyond the observer shifted sideways by up to
  :data:`ROW_LATERAL` m, so that a nearer robot partly hides a farther one; the fourth robot,
  if not in the row, stands anywhere.
* ``pack_behind``: two robots at 0.3-2 m from the observer, each with a pack behind it
  (0.12-0.45 m farther, up to :data:`PACK_LATERAL` m aside), so that the robot partly hides
  the pack; a third pack anywhere.
* ``behind_robot``: a far robot 0.5-2 m from the observer, a middle robot between them (at
  least 0.25 m from both) up to :data:`MIDDLE_LATERAL` m off their line, hiding part of the
  far robot's LED and face; the far robot is turned towards the observer in most scenes, so
  that its face can be seen.

Scenes use :class:`~cyber_rodent.vision.hard_scenes.Scene`: a scene is physically valid
(:func:`~cyber_rodent.vision.hard_scenes.valid`: inside the walls, no interpenetrating
bodies); a drawn scene that is not is drawn again from the same generator. Scene ``k`` of a
seed set is drawn from its own seed (:func:`seeds`), so a scene does not depend on how many
are drawn. The ``tune`` and ``report`` sets are disjoint: rules are tuned on one and measured
on the other.
"""

from __future__ import annotations

import math

import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.robot import robot_model
from cyber_rodent.vision.hard_scenes import (
    Family,
    Scene,
    ahead,
    face,
    inside,
    led,
    pack,
    random_leds,
    random_yaw,
    valid,
)
from cyber_rodent.world import World

#: m, half the side of the paper's field.
_HALF = C.FIELD_SIZE / 2
#: m, the largest sideways shift of a robot off the row's line (``rows``).
ROW_LATERAL = 0.1
#: m, the largest sideways shift of a pack off the line through the robot before it.
PACK_LATERAL = 0.15
#: m, the largest sideways shift of the middle robot off the observer-far robot line.
MIDDLE_LATERAL = 0.1
#: Each seed set's first seed; scene ``k`` of a set is drawn from seed ``base + k``.
SEED_BASES = {"tune": 1000, "report": 2000}
#: The most scenes a seed set holds, so that the sets never share a seed.
MAX_SCENES = 1000
#: Draws of one scene before giving up.
_ATTEMPTS = 1000


def seeds(name: str, count: int) -> list[int]:
    """The seeds of the first ``count`` scenes of seed set ``name`` (``tune`` or ``report``).

    Raises:
        ValueError: for an unknown set or more than :data:`MAX_SCENES` scenes.
    """
    if name not in SEED_BASES:
        raise ValueError(f"unknown seed set {name!r}; known: {', '.join(SEED_BASES)}")
    if not 0 <= count <= MAX_SCENES:
        raise ValueError(f"a seed set holds 0 to {MAX_SCENES} scenes, not {count}")
    base = SEED_BASES[name]
    return list(range(base, base + count))


def make_scene(world: World, family: Family, seed: int) -> Scene:
    """One valid scene of ``family`` drawn from ``seed`` (the world is left in its state).

    Raises:
        ValueError: if the world's counts are not the family's, or no valid scene is drawn.
    """
    if (world.config.n_robots, world.config.n_packs) != (family.n_robots, family.n_packs):
        raise ValueError(
            f"family {family.name} needs {family.n_robots} robots and {family.n_packs} packs"
        )
    rng = np.random.default_rng(seed)
    for _attempt in range(_ATTEMPTS):
        scene = family.build(rng)
        if valid(world, scene):
            return scene
    raise ValueError(f"family {family.name}: no valid scene in {_ATTEMPTS} draws (seed {seed})")


def make_scenes(world: World, family: Family, scene_seeds: list[int]) -> list[Scene]:
    """One valid scene of ``family`` per seed (:func:`make_scene`)."""
    return [make_scene(world, family, s) for s in scene_seeds]


# --- building blocks ---------------------------------------------------------------------------
def _facing(rng: np.random.Generator, x: float, y: float, ox: float, oy: float) -> float:
    """A heading that turns the robot at (x, y) towards (ox, oy) within ±90° (p = 0.6), or any."""
    if rng.random() < 0.6:
        return math.atan2(oy - y, ox - x) + float(rng.uniform(-0.5 * math.pi, 0.5 * math.pi))
    return random_yaw(rng)


def _fit(
    rng: np.random.Generator, offsets: np.ndarray, margin: float
) -> tuple[float, float] | None:
    """A random start for a shape given by ``offsets`` (k, 2) from it that keeps every point
    ``margin`` inside the walls, or None if it cannot fit."""
    lim = _HALF - margin
    lo = -lim - offsets.min(axis=0)
    hi = lim - offsets.max(axis=0)
    if np.any(lo > hi):
        return None
    return float(rng.uniform(lo[0], hi[0])), float(rng.uniform(lo[1], hi[1]))


# --- the families ------------------------------------------------------------------------------
def _rows(rng: np.random.Generator) -> Scene:
    """3 or 4 robots in a row, the observer (robot 0) at one end (see the module docstring)."""
    n = 4
    length = int(rng.integers(3, 5))
    along = np.concatenate([[0.0], np.cumsum(rng.uniform(0.25, 1.0, size=length - 1))])
    lateral = np.concatenate([[0.0], rng.uniform(-ROW_LATERAL, ROW_LATERAL, size=length - 1)])
    for _try in range(100):  # a direction in which the row fits the field
        direction = random_yaw(rng)
        offsets = np.array(
            [ahead(0.0, 0.0, direction, a, b) for a, b in zip(along, lateral, strict=True)]
        )
        start = _fit(rng, offsets, robot_model().body_radius)
        if start is not None:
            break
    # A row too long for the field in every direction tried: outside the walls, drawn again.
    x0, y0 = start if start is not None else (2 * _HALF, 2 * _HALF)
    robots = [(x0, y0, random_yaw(rng))]
    for dx, dy in offsets[1:]:
        x, y = x0 + float(dx), y0 + float(dy)
        robots.append((x, y, _facing(rng, x, y, x0, y0)))
    while len(robots) < n:
        robots.append((*inside(rng, robot_model().body_radius), random_yaw(rng)))
    packs = [inside(rng, 0.1)]
    designed = [(0, t) for j in range(2, length) for t in (led(j), face(j, n))]
    return Scene(tuple(robots), tuple(packs), random_leds(rng, n), tuple(designed))


def _pack_behind(rng: np.random.Generator) -> Scene:
    """Two robots 0.3-2 m from the observer, a pack behind each (see the module docstring)."""
    n = 3
    x0, y0 = inside(rng, robot_model().body_radius)
    robots = [(x0, y0, random_yaw(rng))]
    packs = []
    first = random_yaw(rng)
    for k in range(2):
        direction = first + (k * rng.choice([-1.0, 1.0]) * rng.uniform(0.4, math.pi))
        d = rng.uniform(0.3, 2.0)
        x, y = ahead(x0, y0, direction, d)
        robots.append((x, y, random_yaw(rng)))
        lateral = rng.uniform(-PACK_LATERAL, PACK_LATERAL)
        packs.append(ahead(x0, y0, direction, d + rng.uniform(0.12, 0.45), lateral))
    packs.append(inside(rng, 0.1))
    designed = [(0, pack(0, n)), (0, pack(1, n))]
    return Scene(tuple(robots), tuple(packs), random_leds(rng, n), tuple(designed))


def _behind_robot(rng: np.random.Generator) -> Scene:
    """A far robot 0.5-2 m away behind a middle robot (see the module docstring)."""
    n = 3
    x0, y0 = inside(rng, robot_model().body_radius)
    direction = random_yaw(rng)
    far = rng.uniform(0.5, 2.0)
    middle = rng.uniform(0.25, far - 0.25)
    mx, my = ahead(x0, y0, direction, middle, rng.uniform(-MIDDLE_LATERAL, MIDDLE_LATERAL))
    fx, fy = ahead(x0, y0, direction, far)
    robots = [
        (x0, y0, random_yaw(rng)),
        (mx, my, random_yaw(rng)),
        (fx, fy, _facing(rng, fx, fy, x0, y0)),
    ]
    packs = [inside(rng, 0.1), inside(rng, 0.1)]
    leds = random_leds(rng, n)[:2] + (bool(rng.random() < 0.9),)
    designed = [(0, led(2)), (0, face(2, n))]
    return Scene(tuple(robots), tuple(packs), leds, tuple(designed))


#: Every family, in report order.
FAMILIES: tuple[Family, ...] = (
    Family("rows", "3-4 robots in a row, nearer ones partly hiding farther ones", 4, 1, _rows),
    Family("pack_behind", "packs partly hidden behind robots 0.3-2 m away", 3, 3, _pack_behind),
    Family("behind_robot", "a far robot's LED and face behind a middle robot", 3, 2, _behind_robot),
)


def family(name: str) -> Family:
    """The family called ``name``.

    Raises:
        ValueError: for an unknown name (the message lists the known ones).
    """
    for f in FAMILIES:
        if f.name == name:
            return f
    known = ", ".join(f.name for f in FAMILIES)
    raise ValueError(f"unknown occlusion family {name!r}; known: {known}")
