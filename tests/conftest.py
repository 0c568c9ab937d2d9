"""Shared fixtures. Rendering is off-screen (EGL) and needs no display.

The scene fixtures feed the kernel parity tests (``tests/test_kernel_parity.py``): crowded
worlds where robots hide each other and the packs, with LEDs on and off, in the sizes the
package supports (few and many robots, no packs).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402 (after MUJOCO_GL is set)
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from cyber_rodent.world import World, WorldConfig  # noqa: E402

if TYPE_CHECKING:
    from cyber_rodent.vision import CameraConfig
    from cyber_rodent.vision.batch_rendering import BatchOmniRenderer

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


@pytest.fixture
def batch_renderer(scene_world: World) -> Iterator[BatchOmniRenderer]:
    """The batch omni renderer of :func:`scene_world` (default camera), closed after the test.

    It opens a GL context, so only the tests that ask for it make one.
    """
    from cyber_rodent.vision import CameraConfig
    from cyber_rodent.vision.batch_rendering import BatchOmniRenderer

    with BatchOmniRenderer(scene_world, CameraConfig()) as batch:
        yield batch


@pytest.fixture
def segmentation_strips() -> dict[str, tuple[CameraConfig, np.ndarray]]:
    """Hand-made RGB strips (robots, height, width, 3) for the segmentation, with their camera.

    * ``colours``: 4 robots x 100 rows of random colours, then colours near each class's HSV
      edges (green, red, blue, 40 rows each, jittered by up to ±60 per channel).
    * ``blobs``: 2 robots x 12 rows on grey. Robot 0: green across the strip's seam (rows 3-4,
      columns 62-63 and 0-1): one LED of 8 px; two red squares touching at a corner (rows 5-6,
      columns 18-19; rows 7-8, columns 20-21): one face of 8 px (8-connectivity); a separate
      red square (rows 5-6, columns 40-41): another face of 4 px. Robot 1: one pack cut by its
      grey ring: blue rows 2-4 and 6-8, columns 30-33 (24 px).
    * ``checkerboard``: 4 robots x 12 rows, blue and red checkerboards on grey: more runs than
      the labelling's first allocation holds.
    * ``empty``: 3 robots x 12 rows of grey.
    """
    from cyber_rodent.vision import CameraConfig

    small = CameraConfig(n_views=4, view_width=16, height=12)
    green, red, blue, grey = (25, 230, 25), (230, 13, 13), (13, 38, 230), (140, 140, 140)
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, size=(400, 64, 3), dtype=np.uint8)
    for k, base in enumerate((green, red, blue)):
        jitter = rng.integers(-60, 61, size=(40, 64, 3))
        rgb[40 * k : 40 * (k + 1)] = np.clip(np.array(base) + jitter, 0, 255)
    colours = rgb.reshape(4, 100, 64, 3)
    blobs = np.full((2, 12, 64, 3), grey, dtype=np.uint8)
    blobs[0, 3:5, 62:] = green
    blobs[0, 3:5, :2] = green
    blobs[0, 5:7, 18:20] = red
    blobs[0, 7:9, 20:22] = red
    blobs[0, 5:7, 40:42] = red
    blobs[1, 2:5, 30:34] = blue
    blobs[1, 6:9, 30:34] = blue
    checkerboard = np.full((4, 12, 64, 3), grey, dtype=np.uint8)
    checkerboard[:, ::2, ::2] = blue
    checkerboard[:, 1::2, 1::2] = red
    return {
        "colours": (CameraConfig(n_views=4, view_width=16, height=100), colours),
        "blobs": (small, blobs),
        "checkerboard": (small, checkerboard),
        "empty": (small, np.full((3, 12, 64, 3), grey, dtype=np.uint8)),
    }
