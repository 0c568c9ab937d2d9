"""Camera configuration, provider selection and output normalisation: bad input and hand cases."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cyber_rodent.vision import (
    PROVIDER_NAMES,
    CameraConfig,
    ColourThreshold,
    VisionNoise,
    camera_for_field,
    default_max_range,
    follow_field,
    make_provider,
    normalise_bearing,
    normalise_distance,
)
from cyber_rodent.vision.types import DEFAULT_MAX_DISTANCE
from cyber_rodent.world import World, WorldConfig


@pytest.fixture(scope="module")
def world() -> World:
    return World(WorldConfig(n_robots=2, n_packs=1))


def test_defaults_are_valid_and_documented_band() -> None:
    c = CameraConfig()
    assert (c.n_views, c.view_width, c.height) == (4, 128, 192)
    assert c.elevation_min_deg == -45.0 and c.elevation_max_deg == 3.0
    assert c.max_range == pytest.approx(2.3 * math.sqrt(2))
    assert c.strip_width == 512
    assert c.min_blob_area == (1, 3, 3)
    assert not c.noise.enabled


@pytest.mark.parametrize("field", ["view_width", "height"])
@pytest.mark.parametrize("value", [0, -1, -128, 100_000, 10**9, 2.5, True, "64"])
def test_impossible_resolution_is_rejected_naming_the_field(field: str, value) -> None:
    with pytest.raises(ValueError, match=field):
        CameraConfig(**{field: value})


def test_strip_wider_than_the_limit_is_rejected() -> None:
    with pytest.raises(ValueError, match="strip"):
        CameraConfig(n_views=8, view_width=1024)


def test_rendered_buffer_too_large_for_the_world_is_rejected() -> None:
    # Each config field is legal, but 4 robots x 4096 rows x 4096 columns (64 Mpx) exceed the
    # one off-screen buffer; the error comes before any OpenGL allocation.
    config = CameraConfig(view_width=1024, height=4096)
    with pytest.raises(ValueError, match="resolution"):
        make_provider("rendered", World(WorldConfig(n_robots=4, n_packs=0)), config)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"n_views": 2}, "n_views"),
        ({"n_views": 17}, "n_views"),
        ({"elevation_min_deg": 0.0}, "elevation_min_deg"),
        ({"elevation_min_deg": -85.0}, "elevation_min_deg"),
        ({"elevation_max_deg": -1.0}, "elevation_max_deg"),
        ({"elevation_max_deg": float("nan")}, "elevation_max_deg"),
        ({"max_range": 0.0}, "max_range"),
        ({"max_range": float("inf")}, "max_range"),
        ({"min_blob_area": 1}, "min_blob_area"),
        ({"min_blob_area": (1, 0, 3)}, "min_blob_area"),
        ({"min_blob_area": (1, 3)}, "min_blob_area"),
        ({"min_blob_area": (1, 3, 2.5)}, "min_blob_area"),
        ({"near_clip": 0.2}, "near_clip"),
    ],
)
def test_bad_camera_fields_are_rejected(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        CameraConfig(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"hue_low": 180}, "hue_low"),
        ({"hue_high": -1}, "hue_high"),
        ({"sat_min": 256}, "sat_min"),
        ({"val_min": 1.5}, "val_min"),
    ],
)
def test_bad_colour_thresholds_are_rejected(kwargs: dict, field: str) -> None:
    base = {"hue_low": 40, "hue_high": 80, "sat_min": 100, "val_min": 100}
    with pytest.raises(ValueError, match=field):
        ColourThreshold(**(base | kwargs))


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"bearing_std_deg": -1.0}, "bearing_std_deg"),
        ({"distance_rel_std": 2.0}, "distance_rel_std"),
        ({"dropout": 1.5}, "dropout"),
    ],
)
def test_bad_noise_is_rejected(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        VisionNoise(**kwargs)


def test_unknown_provider_name_lists_the_allowed_names(world: World) -> None:
    with pytest.raises(ValueError) as err:
        make_provider("raytraced", world)
    for name in PROVIDER_NAMES:
        assert name in str(err.value)
    assert set(PROVIDER_NAMES) == {"geometric", "rendered"}


def test_config_of_the_wrong_type_is_rejected(world: World) -> None:
    with pytest.raises(ValueError, match="CameraConfig"):
        make_provider("geometric", world, config={"view_width": 64})


def test_noise_without_a_generator_is_rejected(world: World) -> None:
    config = CameraConfig(noise=VisionNoise(dropout=0.1))
    with pytest.raises(ValueError, match="rng"):
        make_provider("geometric", world, config)


def test_bearing_normalisation_hand_cases() -> None:
    got = normalise_bearing(np.array([-math.pi, -math.pi / 2, 0.0, math.pi / 2, math.pi]))
    np.testing.assert_allclose(got, [0.0, 0.25, 0.5, 0.75, 1.0])


def test_distance_normalisation_hand_cases() -> None:
    d = np.array([0.0, DEFAULT_MAX_DISTANCE / 2, 10.0, 0.5, np.inf])
    visible = np.array([True, True, True, False, False])
    np.testing.assert_allclose(normalise_distance(d, visible), [0.0, 0.5, 1.0, 1.0, 1.0])
    # An unseen target's distance is 1 whatever the stored distance (docs/design.md §5).
    assert normalise_distance(np.array([0.1]), np.array([False]))[0] == 1.0


def test_the_default_range_is_the_field_diagonal() -> None:
    # 2.3 m x sqrt(2) = 3.2527 m; a 4.6 m field's diagonal is twice that, 6.5054 m.
    assert default_max_range(2.3) == DEFAULT_MAX_DISTANCE == CameraConfig().max_range
    assert default_max_range(4.6) == pytest.approx(6.5054, abs=1e-4)
    assert camera_for_field(2.3) == CameraConfig()
    wide = camera_for_field(4.6)
    assert wide.max_range == pytest.approx(6.5054, abs=1e-4)
    assert dataclasses.replace(wide, max_range=DEFAULT_MAX_DISTANCE) == CameraConfig()
    # A provider given no camera sees to its own world's diagonal.
    world = World(WorldConfig(field_size=4.6, n_robots=2, n_packs=1))
    assert make_provider("geometric", world).config.max_range == wide.max_range


def test_a_hand_set_range_stays_when_the_field_changes() -> None:
    moved = follow_field(CameraConfig(), 2.3, 4.6)
    assert moved.max_range == pytest.approx(6.5054, abs=1e-4)
    assert follow_field(moved, 4.6, 2.3) == CameraConfig()
    assert follow_field(CameraConfig(max_range=2.0), 2.3, 4.6).max_range == 2.0
    assert follow_field(CameraConfig(), 2.3, 2.3) == CameraConfig()


def test_distance_normalisation_stays_the_paper_fields() -> None:
    # The inputs' scale is the paper field's diagonal whatever the field (the shipped
    # behaviours learned on it): 1.6 m is 1.6 / 3.2527 = 0.4919 in any field.
    assert DEFAULT_MAX_DISTANCE == pytest.approx(3.2527, abs=1e-4)
    d = normalise_distance(np.array([1.6, 5.0]), np.array([True, True]))
    np.testing.assert_allclose(d, [0.4919, 1.0], atol=1e-4)
