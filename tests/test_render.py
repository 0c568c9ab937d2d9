"""Off-screen rendering: the top-down image shows packs where they are, and the LED; robot
labels never overlap, however the robots crowd."""

from __future__ import annotations

import itertools
import math

import cv2
import mujoco
import numpy as np
import pytest

from cyber_rodent.render import (
    BACKGROUND_RGB,
    FieldRenderer,
    RobotTag,
    annotate_world,
    boxes_intersect,
    default_image_size,
    label_scale,
    label_size,
    place_labels,
    text_scale,
)
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


# --- annotations: robot IDs, heading arrows, labels that never overlap ---------------------------
def cluster_on_pack(world: World, distance: float = 0.2, pack: int = 0) -> None:
    """Park every robot around one pack, a few cm from its ring, facing it."""
    px, py = world.pack_positions()[pack]
    n = world.config.n_robots
    for i in range(n):
        a = 2 * math.pi * i / n + 0.4
        x, y = px + distance * math.cos(a), py + distance * math.sin(a)
        world.set_robot_pose(i, x, y, a + math.pi)
    mujoco.mj_forward(world.model, world.data)


def assert_disjoint(boxes: np.ndarray, bounds: tuple[int, int]) -> None:
    width, height = bounds
    assert (boxes[:, 0] >= 0).all() and (boxes[:, 1] >= 0).all()
    assert (boxes[:, 2] <= width).all() and (boxes[:, 3] <= height).all()
    assert (boxes[:, 2] > boxes[:, 0]).all() and (boxes[:, 3] > boxes[:, 1]).all()
    for a, b in itertools.combinations(boxes.tolist(), 2):
        assert not boxes_intersect(a, b), (a, b)


def test_labels_of_robots_clustered_on_one_pack_do_not_overlap() -> None:
    world = World(WorldConfig(), np.random.default_rng(4))
    cluster_on_pack(world)
    with FieldRenderer(world, 480, 480) as renderer:
        poses = world.poses()
        anchors = renderer.project_top_down(np.column_stack([poses[:, :2], np.full(4, 0.17)]))
        assert np.ptp(anchors, axis=0).max() < 0.5 * renderer.metres_to_px()  # one cluster
        tags = [RobotTag(f"CR{i} Recharge", energy=0.5) for i in range(4)]
        sizes = np.array([label_size(tag, 0.5) for tag in tags])
        clearance = 0.11 * renderer.metres_to_px()
        boxes = place_labels(anchors, sizes, (480, 480), clearance)
    assert boxes is not None and boxes.shape == (4, 4)
    assert_disjoint(boxes, (480, 480))
    assert ((boxes[:, 2:] - boxes[:, :2]) == sizes).all()  # every label at its full size
    # Each label stays near its robot (within a few label heights).
    centres = (boxes[:, :2] + boxes[:, 2:]) / 2
    assert np.hypot(*(centres - anchors).T).max() < clearance + 4 * sizes[:, 1].max()


@pytest.mark.parametrize("seed", range(40))
def test_labels_never_overlap_whatever_the_positions(seed: int) -> None:
    rng = np.random.default_rng(seed)
    width, height = int(rng.integers(120, 721)), int(rng.integers(120, 721))
    n = int(rng.integers(1, 27))
    kind = seed % 4
    if kind == 0:  # all on one point
        anchors = np.tile(rng.uniform(0, [width, height]), (n, 1))
    elif kind == 1:  # in a corner, partly outside the image
        anchors = rng.uniform(-20, 30, size=(n, 2))
    elif kind == 2:  # a tight cluster
        anchors = rng.normal([width / 2, height / 2], 5, size=(n, 2))
    else:
        anchors = rng.uniform(0, [width, height], size=(n, 2))
    scale = float(rng.uniform(0.3, 0.7))
    sizes = np.array([label_size(RobotTag(f"CR{i} Forage", energy=0.3), scale) for i in range(n)])
    boxes = place_labels(anchors, sizes, (width, height), clearance=12.0)
    cells = (width // (sizes[:, 0].max() + 3)) * (height // (sizes[:, 1].max() + 3))
    if n <= cells:  # room for a grid of the labels: they must all be placed
        assert boxes is not None
    if boxes is not None:
        assert_disjoint(boxes, (width, height))


def test_snapshot_annotations_ids_and_arrows() -> None:
    world = World(WorldConfig(), np.random.default_rng(4))
    cluster_on_pack(world)
    with FieldRenderer(world, 400, 400, background=BACKGROUND_RGB) as renderer:
        image = renderer.top_down()
        bare = image.copy()
        boxes = annotate_world(image, renderer)
    assert boxes is not None
    assert_disjoint(boxes, (400, 400))
    # The empty space around the field is painted, never left black.
    assert not (~bare.any(axis=2)).any()
    # Each label box holds light text on a dark box, and arrows changed pixels at the robots.
    for x0, y0, x1, y1 in boxes:
        inside = image[y0 + 2 : y1 - 2, x0 + 2 : x1 - 2]
        assert (inside.min(axis=2) > 200).sum() >= 10
    assert (image != bare).any(axis=2).sum() > 500


def test_background_only_replaces_empty_space() -> None:
    world = World(WorldConfig(), np.random.default_rng(4))
    with FieldRenderer(world, 320, 200) as plain, FieldRenderer(
        world, 320, 200, background=BACKGROUND_RGB
    ) as painted:
        a, b = plain.top_down(), painted.top_down()
    empty = ~a.any(axis=2)
    assert empty.sum() > 1000  # a wide image shows space beside the field
    assert (b[empty] == BACKGROUND_RGB).all()
    np.testing.assert_array_equal(a[~empty], b[~empty])


def test_a_large_field_is_framed_whole_with_labels_at_the_robots_scale() -> None:
    # A 6.3 m field (30 robots at the paper's density): the snapshot's default side grows to
    # keep the paper's pixels per metre, 640 x 6.3 / 2.3 = 1753 px; the top-down camera rises
    # with the field, so all four corners stay in view.
    assert default_image_size(2.3) == 640 and default_image_size(6.3) == 1753
    assert default_image_size(11.5) == 2048  # capped
    world = World(WorldConfig(field_size=6.3, n_robots=30, n_packs=38), np.random.default_rng(1))
    with FieldRenderer(world, 600, 600, background=BACKGROUND_RGB) as renderer:
        corners = np.array([[x, y, 0.0] for x in (-3.15, 3.15) for y in (-3.15, 3.15)])
        px = renderer.project_top_down(corners)
        assert (px > 20).all() and (px < 580).all()
        image = renderer.top_down()
        per_m = renderer.metres_to_px()
        boxes = annotate_world(image, renderer)
        poses = world.poses()
        anchors = renderer.project_top_down(np.column_stack([poses[:, :2], np.full(30, 0.17)]))
    assert boxes is not None
    assert_disjoint(boxes, (600, 600))
    # Labels about a robot's length tall: the font follows the robots, not the image.
    assert label_scale(600, per_m) == max(0.35, 0.004 * per_m) < text_scale(600)
    # The paper's field at 640 px shows 232 px per metre: there the image's scale is smaller.
    assert label_scale(640, 232.0) == text_scale(640)
    # Each robot's label sits by its robot.
    centres = (boxes[:, :2] + boxes[:, 2:]) / 2
    assert np.hypot(*(centres - anchors).T).max() < 0.6 * per_m
