"""Off-screen rendering: the top-down image shows packs where they are, and the LED."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cyber_rodent.render import FieldRenderer
from cyber_rodent.world import World, WorldConfig


def blue_mask(image: np.ndarray) -> np.ndarray:
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)  # OpenCV hue is 0..180
    return cv2.inRange(hsv, (105, 120, 60), (130, 255, 255)) > 0


def green_mask(image: np.ndarray) -> np.ndarray:
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
    return cv2.inRange(hsv, (45, 120, 120), (75, 255, 255)) > 0


@pytest.fixture(scope="module")
def scene():
    world = World(WorldConfig(), np.random.default_rng(4))
    renderer = FieldRenderer(world, 480, 480)
    yield world, renderer
    renderer.close()


def test_blue_pixels_exactly_where_the_packs_are(scene) -> None:
    world, renderer = scene
    image = renderer.top_down()
    assert image.shape == (480, 480, 3) and image.dtype == np.uint8
    # A pack's top and the side below its grey electrode ring are one object: close the gap.
    mask = cv2.morphologyEx(
        blue_mask(image).astype(np.uint8), cv2.MORPH_CLOSE, np.ones((7, 7), np.uint8)
    )
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(mask)
    blobs = [centroids[k] for k in range(1, n) if stats[k, cv2.CC_STAT_AREA] >= 4]
    tops = np.column_stack([world.pack_positions(), np.full(world.config.n_packs, 0.1)])
    expected = renderer.project_top_down(tops)
    assert len(blobs) == world.config.n_packs  # one blue blob per pack, none elsewhere
    for blob in blobs:
        assert np.min(np.hypot(*(expected - blob).T)) < 6.0  # px; a pack is ~18 px across
    for px in expected:
        assert np.min([np.hypot(*(px - b)) for b in blobs]) < 6.0


def test_led_toggle_changes_the_rendered_colour(scene) -> None:
    world, renderer = scene
    led_top = world.data.geom_xpos[world.led_geom[0]].copy()
    col, row = renderer.project_top_down(led_top + [0, 0, 0.007])[0].round().astype(int)
    window = (slice(row - 8, row + 9), slice(col - 8, col + 9))
    world.set_led(False)
    off = green_mask(renderer.top_down())[window].sum()
    world.set_led(True, robot=0)
    on_image = renderer.top_down()
    on = green_mask(on_image)[window].sum()
    world.set_led(False)
    assert off == 0 and on >= 5
    # Only robot 0's LED turned on: no green elsewhere.
    elsewhere = green_mask(on_image).copy()
    elsewhere[window] = False
    assert elsewhere.sum() == 0


def test_robot_view_renders(scene) -> None:
    world, renderer = scene
    image = renderer.robot_view(2)
    assert image.shape == (480, 480, 3) and image.std() > 5
    with pytest.raises(ValueError, match="robot"):
        renderer.robot_view(7)


@pytest.mark.parametrize("size", [0, -3, 100_000])
def test_impossible_image_size(size: int) -> None:
    world = World(WorldConfig(n_robots=1, n_packs=1), np.random.default_rng(0))
    with pytest.raises(ValueError, match="width"):
        FieldRenderer(world, size, 64)
