"""Shared fixtures. Rendering is off-screen (EGL) and needs no display.

The scene fixtures feed the kernel parity tests (``tests/test_kernel_parity.py``): crowded
worlds where robots hide each other and the packs, with LEDs on and off, in the sizes the
package supports (few and many robots, no packs).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402 (after MUJOCO_GL is set)
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from cyber_rodent.world import World, WorldConfig  # noqa: E402

#: (robots, packs) of the parity scenes: the default world, crowded ones, one without packs.
SCENE_SIZES = [(4, 5), (3, 6), (8, 10), (2, 0)]

Scenes = Callable[[int], Iterator[int]]


def crowd(world: World, rng: np.random.Generator, count: int) -> Iterator[int]:
    """Yield ``count`` times after placing the robots ever less tightly around the centre.

    Each scene: a fresh placement of the packs (``World.reset``), the robots at random poses
    within ±(0.3 + 0.03 k) m of the centre (the first scenes are crowded: robots touch and hide
    each other), random LEDs (60 % on), and MuJoCo's derived quantities recomputed.
    """
    n = world.config.n_robots
    for trial in range(count):
        world.reset(rng)
        spread = 0.3 + 0.03 * trial
        for i in range(n):
            x, y = rng.uniform(-spread, spread, size=2)
            world.set_robot_pose(i, x, y, rng.uniform(-math.pi, math.pi))
        world.set_led(rng.random(n) < 0.6)
        mujoco.mj_forward(world.model, world.data)
        yield trial


@pytest.fixture(params=SCENE_SIZES, ids=lambda size: f"{size[0]}robots-{size[1]}packs")
def scene_world(request: pytest.FixtureRequest) -> World:
    """A world of one of :data:`SCENE_SIZES`."""
    n_robots, n_packs = request.param
    return World(WorldConfig(n_robots=n_robots, n_packs=n_packs))


@pytest.fixture
def scenes(scene_world: World) -> Scenes:
    """``scenes(count)`` iterates crowded scenes of :func:`scene_world` (seeded by its size)."""
    seed = 7 * scene_world.config.n_robots + scene_world.config.n_packs

    def make(count: int) -> Iterator[int]:
        return crowd(scene_world, np.random.default_rng(seed), count)

    return make
