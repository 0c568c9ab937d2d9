"""The lazy nearest-target pass of the geometric provider equals the full pass, bit for bit.

:meth:`GeometricVision.nearest_targets` casts occlusion rays only at each class's nearest
untried candidate and stops as soon as visibility is certain; the evolution loop relies on it
giving exactly what ``observe()`` reports as the nearest target of each class. Random crowded
scenes (robots hiding each other and the packs, LEDs on and off) compare the two.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from cyber_rodent.vision import CameraConfig, make_provider
from cyber_rodent.world import World, WorldConfig
from tests.conftest import crowd


@pytest.mark.parametrize(("n_robots", "n_packs"), [(4, 5), (3, 4), (8, 10), (2, 0)])
def test_nearest_targets_equal_observe(n_robots: int, n_packs: int) -> None:
    world = World(WorldConfig(n_robots=n_robots, n_packs=n_packs))
    vision = make_provider("geometric", world)
    rng = np.random.default_rng(100 * n_robots + n_packs)
    seen, hidden_nearest = 0, 0
    for _ in crowd(world, rng, 60):
        frame = vision.observe()
        nearest = vision.nearest_targets()
        np.testing.assert_array_equal(nearest.visible, frame.visible)
        np.testing.assert_array_equal(nearest.distance, frame.distance)
        np.testing.assert_array_equal(nearest.bearing, frame.bearing)
        seen += int(frame.visible.sum())
        # Count cases where the nearest candidate (in range, lit, facing, large enough) was
        # hidden, so the lazy pass had to try the next one.
        t = vision.measure_targets()
        candidate = t.candidate
        for i in range(n_robots):
            for c in range(3):
                cols = np.flatnonzero((vision.target_cls == c) & candidate[i])
                if len(cols) and not t.visible[i, cols[np.argmin(t.distance[i, cols])]]:
                    hidden_nearest += 1
    assert seen > 20 * n_robots  # not vacuous: plenty of targets seen
    assert hidden_nearest > 0  # and the nearest target was often not the visible one


def test_nearest_targets_small_blob_threshold() -> None:
    """A large min_blob_area makes partial visibility decide: the early stop must agree."""
    world = World(WorldConfig(n_robots=4, n_packs=5))
    vision = make_provider("geometric", world, CameraConfig(min_blob_area=(4, 40, 40)))
    rng = np.random.default_rng(5)
    for trial in range(40):
        world.reset(rng)
        for i in range(4):
            x, y = rng.uniform(-0.4 - 0.03 * trial, 0.4 + 0.03 * trial, size=2)
            world.set_robot_pose(i, x, y, rng.uniform(-math.pi, math.pi))
        world.set_led(rng.random(4) < 0.6)
        mujoco.mj_forward(world.model, world.data)
        frame = vision.observe()
        nearest = vision.nearest_targets()
        np.testing.assert_array_equal(nearest.visible, frame.visible)
        np.testing.assert_array_equal(nearest.distance, frame.distance)
        np.testing.assert_array_equal(nearest.bearing, frame.bearing)
