"""The compiled geometric-vision kernel agrees with the numpy reference implementation.

:mod:`cyber_rodent.vision.geometric_kernel` is the evolution loop's vision (numba, with
MuJoCo's ``mj_ray`` called from compiled code). The numpy implementation is the reference:
on random crowded scenes both must make the same decisions (candidates, samples in view,
nearest visible target of each class) and give the same numbers up to rounding (numpy's small
matrix products may round the last bit differently).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from cyber_rodent.vision import geometric_kernel
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.world import World, WorldConfig

pytestmark = pytest.mark.skipif(
    not geometric_kernel.AVAILABLE, reason=geometric_kernel.unavailable_reason()
)


def _scenes(world: World, rng: np.random.Generator, count: int):
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


@pytest.mark.parametrize(("n_robots", "n_packs"), [(4, 5), (3, 6), (8, 10), (2, 0)])
def test_compiled_kernel_matches_numpy(n_robots: int, n_packs: int) -> None:
    world = World(WorldConfig(n_robots=n_robots, n_packs=n_packs))
    compiled = GeometricVision(world, backend="compiled")
    reference = GeometricVision(world, backend="numpy")
    assert (compiled.backend, reference.backend) == ("compiled", "numpy")
    out_c = np.zeros((n_robots, 3)), np.zeros((n_robots, 3)), np.zeros((n_robots, 3), bool)
    out_r = np.zeros((n_robots, 3)), np.zeros((n_robots, 3)), np.zeros((n_robots, 3), bool)
    seen = 0
    for _ in _scenes(world, np.random.default_rng(7 * n_robots + n_packs), 60):
        fc, fr = compiled._front(), reference._front()
        np.testing.assert_array_equal(fc.candidate, fr.candidate)
        np.testing.assert_array_equal(fc.sample_ok, fr.sample_ok)
        for name in ("bearing", "distance", "half_angle", "local", "rays"):
            np.testing.assert_allclose(getattr(fc, name), getattr(fr, name), rtol=0, atol=1e-12)
        for name in ("width_px", "height_px", "full_area"):
            np.testing.assert_allclose(getattr(fc, name), getattr(fr, name), rtol=1e-11, atol=0)
        compiled.nearest_targets(*out_c)
        reference.nearest_targets(*out_r)
        np.testing.assert_array_equal(out_c[2], out_r[2])
        np.testing.assert_allclose(out_c[1], out_r[1], rtol=0, atol=1e-12)
        np.testing.assert_allclose(out_c[0], out_r[0], rtol=0, atol=1e-12)
        seen += int(out_c[2].sum())
    assert seen > 20 * n_robots  # not vacuous


def test_compiled_front_returns_fresh_arrays() -> None:
    """Measurements kept from one call must not change at the next (the kernel's buffers
    are reused; what leaves the provider is a copy)."""
    world = World(WorldConfig())
    vision = GeometricVision(world, backend="compiled")
    rng = np.random.default_rng(3)
    scenes = _scenes(world, rng, 2)
    next(scenes)
    first = vision.measure_targets()
    kept = first.distance.copy()
    next(scenes)
    vision.measure_targets()
    np.testing.assert_array_equal(first.distance, kept)


def test_backend_is_validated() -> None:
    world = World(WorldConfig(n_robots=2, n_packs=1))
    with pytest.raises(ValueError, match=r"backend must be one of auto, compiled, numpy"):
        GeometricVision(world, backend="cuda")
    assert GeometricVision(world).backend == "compiled"  # auto prefers the kernel
