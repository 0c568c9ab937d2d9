"""The geometric provider alone: occlusion rays, culling fix, noise model, range, determinism."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from cyber_rodent.vision import BATTERY, FACE, LED, CameraConfig, VisionNoise, make_provider
from cyber_rodent.vision.geometric import (
    VISIBLE_GROUPS,
    GeometricVision,
    widen_ray_culling_bounds,
)
from cyber_rodent.world import World, WorldConfig


def _place(world: World, robots, packs, leds=False) -> None:
    for i, (x, y, yaw) in enumerate(robots):
        world.set_robot_pose(i, x, y, yaw)
    for j, (x, y) in enumerate(packs):
        world.set_pack_position(j, x, y)
    world.set_led(leds)
    mujoco.mj_forward(world.model, world.data)


@pytest.fixture(scope="module")
def world() -> World:
    return World(WorldConfig(n_robots=2, n_packs=2))


def _pack_ahead(world: World) -> None:
    """Robot 0 at (-0.5, 0) facing +x, pack 0 at the origin (0.5 m ahead); the rest away."""
    _place(world, [(-0.5, 0.0, 0.0), (-0.9, 0.9, math.pi)], [(0.0, 0.0), (0.9, -0.9)])


def test_pack_ahead_exact_bearing_and_distance(world: World) -> None:
    _pack_ahead(world)
    frame = make_provider("geometric", world).observe()
    assert frame.visible[0, BATTERY]
    assert frame.bearing[0, BATTERY] == pytest.approx(0.0, abs=1e-9)
    assert frame.distance[0, BATTERY] == pytest.approx(0.5, abs=1e-9)
    # Robot 1 at (-0.9, 0.9) facing -x sees pack 1 at (0.9, -0.9) over its right shoulder...
    # and robot 0's LED is off, so no green for anyone.
    assert not frame.visible[:, LED].any()


def test_max_range_drops_farther_targets(world: World) -> None:
    _pack_ahead(world)
    near = GeometricVision(world, CameraConfig(max_range=0.45)).measure_targets()
    far = GeometricVision(world, CameraConfig(max_range=0.55)).measure_targets()
    pack0 = 2 * world.config.n_robots  # targets: LEDs, faces, then packs
    assert far.visible[0, pack0] and not near.visible[0, pack0]


def test_face_seen_from_the_front_not_from_behind(world: World) -> None:
    geo = make_provider("geometric", world)
    # Robot 1 0.6 m ahead of robot 0, facing it: its face is seen; turned away: not.
    _place(world, [(-0.3, 0.0, 0.0), (0.3, 0.0, math.pi)], [(0.9, 0.9), (0.9, -0.9)])
    f = geo.observe()
    assert f.visible[0, FACE]
    assert f.distance[0, FACE] == pytest.approx(0.6 - 0.111, abs=0.002)  # face plate 11 cm ahead
    _place(world, [(-0.3, 0.0, 0.0), (0.3, 0.0, 0.0)], [(0.9, 0.9), (0.9, -0.9)])
    assert not geo.observe().visible[0, FACE]


def test_own_led_and_face_are_never_targets(world: World) -> None:
    geo = GeometricVision(world)
    rng = np.random.default_rng(3)
    for _ in range(20):
        world.reset(rng)
        world.set_led(True)
        t = geo.measure_targets()
        own = geo.target_owner[None, :] == np.arange(world.config.n_robots)[:, None]
        assert not t.visible[own].any()


def test_multiray_after_widening_matches_exact_mj_ray() -> None:
    """mj_multiRay (culled) must hit exactly what mj_ray (linear scan) hits, ray by ray."""
    world = World(WorldConfig(n_robots=4, n_packs=5))
    geo = GeometricVision(world)
    m, d = world.model, world.data
    rng = np.random.default_rng(11)
    gid = np.zeros(1, dtype=np.int32)
    n_rays = 0
    for _ in range(6):
        world.reset(rng)
        cam = d.site_xpos[world.camera_site]
        targets = d.geom_xpos[geo.target_geom]
        for i in range(world.config.n_robots):
            rays = targets - cam[i] + rng.normal(0.0, 0.02, size=targets.shape)
            got_g = np.zeros(len(rays), dtype=np.int32)
            got_d = np.zeros(len(rays))
            mujoco.mj_multiRay(
                m,
                d,
                cam[i],
                rays.ravel(),
                VISIBLE_GROUPS,
                1,
                int(world.chassis_body[i]),
                got_g,
                got_d,
                None,
                len(rays),
                10.0,
            )
            for k, ray in enumerate(rays):
                dist = mujoco.mj_ray(
                    m, d, cam[i], ray, VISIBLE_GROUPS, 1, int(world.chassis_body[i]), gid
                )
                assert got_g[k] == gid[0]
                assert got_d[k] == pytest.approx(dist)
                n_rays += 1
    assert n_rays == 6 * 4 * 13


def test_widening_the_culling_bounds_leaves_physics_bit_identical() -> None:
    def run(widen: bool) -> np.ndarray:
        w = World(WorldConfig(n_robots=2, n_packs=1))
        if widen:
            widen_ray_culling_bounds(w.model)
            widen_ray_culling_bounds(w.model)  # idempotent
        # Two robots driven head-on into each other and then into the pack.
        _place(w, [(-0.4, 0.0, 0.0), (0.4, 0.05, math.pi)], [(0.0, 0.5)])
        for step in range(150):
            s = 1.0 if step < 100 else -0.5
            w.set_wheel_speeds(np.array([s, 0.8]), np.array([s, 1.0]))
            w.step(10)
        return w.data.qpos.copy()

    np.testing.assert_array_equal(run(False), run(True))


def test_noise_is_seeded_and_has_the_configured_spread(world: World) -> None:
    _pack_ahead(world)
    noise = VisionNoise(bearing_std_deg=5.0, distance_rel_std=0.1)
    config = CameraConfig(noise=noise)
    a = make_provider("geometric", world, config, np.random.default_rng(5))
    b = make_provider("geometric", world, config, np.random.default_rng(5))
    c = make_provider("geometric", world, config, np.random.default_rng(6))
    fa, fb, fc = a.observe(), b.observe(), c.observe()
    np.testing.assert_array_equal(fa.bearing, fb.bearing)
    np.testing.assert_array_equal(fa.distance, fb.distance)
    assert not np.array_equal(fa.bearing, fc.bearing)
    frames = [a.observe() for _ in range(400)]
    bearings = np.degrees([f.bearing[0, BATTERY] for f in frames])
    distances = np.array([f.distance[0, BATTERY] for f in frames])
    assert abs(bearings.mean()) < 1.0 and 4.0 < bearings.std() < 6.0
    assert abs(distances.mean() - 0.5) < 0.01 and 0.04 < distances.std() < 0.06


def test_dropout_one_hides_everything_and_zero_noise_is_exact(world: World) -> None:
    _pack_ahead(world)
    gone = make_provider(
        "geometric", world, CameraConfig(noise=VisionNoise(dropout=1.0)), np.random.default_rng(0)
    ).observe()
    assert not gone.visible.any()
    assert np.all(np.isinf(gone.distance))
    clean = make_provider("geometric", world).observe()
    again = make_provider("geometric", world).observe()
    np.testing.assert_array_equal(clean.bearing, again.bearing)
    np.testing.assert_array_equal(clean.distance, again.distance)


def test_measurements_are_fresh_arrays() -> None:
    """Measurements kept from one call must not change at the next (the kernels' buffers are
    reused; what leaves the provider is a copy)."""
    from tests.conftest import crowd

    world = World(WorldConfig())
    vision = GeometricVision(world, backend="numba")
    scenes = crowd(world, np.random.default_rng(3), 2)
    next(scenes)
    first = vision.measure_targets()
    kept = first.distance.copy(), first.visible.copy()
    next(scenes)
    second = vision.measure_targets()
    assert not np.array_equal(second.distance, kept[0])  # the scene did change
    np.testing.assert_array_equal(first.distance, kept[0])
    np.testing.assert_array_equal(first.visible, kept[1])


def test_backend_is_validated() -> None:
    world = World(WorldConfig(n_robots=2, n_packs=1))
    with pytest.raises(ValueError, match=r"backend must be one of numba, numpy, got 'cuda'"):
        GeometricVision(world, backend="cuda")  # type: ignore[arg-type]
    assert GeometricVision(world).backend == "numba"  # the compiled kernels by default
