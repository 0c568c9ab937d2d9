"""The runner's perception equals the public vision and behaviour-input functions.

:class:`evolution.runner.Perception` recomputes, into reused buffers, what
``GeometricVision.observe`` and ``behaviours.behaviour_inputs`` return (it skips their per-call
allocations). These tests compare the two bit for bit on random scenes of the physics world, with
and without the vision noise model, so neither side can drift from the other unnoticed.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from behaviours import BehaviourPolicies, behaviour_inputs
from cyber_rodent.robot import cyber_rodent
from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.vision import BATTERY, FACE, LED, CameraConfig, VisionNoise, make_provider
from cyber_rodent.vision.types import normalise_distance
from cyber_rodent.world import World, WorldConfig
from evolution.config import EvolutionConfig
from evolution.runner import EvolutionRunner, Perception, RunConfig

#: The paper's robot, read from its MJCF file and sensor table.
CR = cyber_rodent()


def _scatter(world: World, rng: np.random.Generator, spread: float) -> None:
    """Random poses close together, so robots see and occlude each other."""
    world.reset(rng)
    for i in range(world.config.n_robots):
        x, y = rng.uniform(-spread, spread, size=2)
        world.set_robot_pose(i, x, y, rng.uniform(-math.pi, math.pi))
    world.set_led(rng.random(world.config.n_robots) < 0.6)
    mujoco.mj_forward(world.model, world.data)


def _check_equal(perception: Perception, frame, world: World) -> None:
    np.testing.assert_array_equal(perception.nearest.visible, frame.visible)
    np.testing.assert_array_equal(perception.nearest.bearing, frame.bearing)
    np.testing.assert_array_equal(perception.nearest.distance, frame.distance)
    ranges = world.range_readings()
    np.testing.assert_array_equal(perception.sensors.ranges, ranges)
    expected = behaviour_inputs(frame, ranges, world.range_max)
    got = perception.inputs.behaviour
    for name in ("mate", "forage", "search", "mate_available", "forage_available"):
        np.testing.assert_array_equal(getattr(got, name), getattr(expected, name), err_msg=name)
    columns = list(CR.proximity)  # proximity = clip(1 - range / range_max, 0, 1)
    expected_proximity = np.clip(1.0 - ranges[:, columns] / world.range_max[:, columns], 0, 1)
    np.testing.assert_array_equal(perception.inputs.proximity, expected_proximity)
    for cls in (LED, FACE, BATTERY):
        np.testing.assert_array_equal(
            perception.inputs.norm_distance[:, cls],
            normalise_distance(frame.distance[:, cls], frame.visible[:, cls]),
        )


def test_geometric_fast_path_equals_observe_and_behaviour_inputs() -> None:
    world = World(WorldConfig(n_robots=4, n_packs=5))
    vision = make_provider("geometric", world)
    perception = Perception(world, vision)
    rng = np.random.default_rng(7)
    seen = np.zeros(3, dtype=int)
    for trial in range(60):
        _scatter(world, rng, spread=0.3 + 0.02 * trial)
        perception.update()
        frame = vision.observe()
        _check_equal(perception, frame, world)
        seen += frame.visible.sum(axis=0)
    # The scenes exercised every class, so the comparison was not vacuous.
    assert (seen > 10).all()


def test_fast_path_with_noise_consumes_the_same_random_numbers() -> None:
    noise = VisionNoise(bearing_std_deg=3.0, distance_rel_std=0.1, dropout=0.2)
    world = World(WorldConfig(n_robots=3, n_packs=4))
    camera = CameraConfig(noise=noise)
    fast = make_provider("geometric", world, camera, np.random.default_rng(11))
    reference = make_provider("geometric", world, camera, np.random.default_rng(11))
    perception = Perception(world, fast)
    rng = np.random.default_rng(3)
    for _ in range(30):
        _scatter(world, rng, spread=0.6)
        perception.update()
        _check_equal(perception, reference.observe(), world)


def test_unseen_targets_map_to_ahead_and_far() -> None:
    # One robot, no packs: it sees nothing at all.
    world = World(WorldConfig(n_robots=1, n_packs=0))
    perception = Perception(world, make_provider("geometric", world))
    inputs = perception.update().behaviour
    assert not perception.nearest.visible.any()
    np.testing.assert_array_equal(inputs.mate, [[0.5, 1.0]])
    np.testing.assert_array_equal(inputs.forage, [[0.5, 1.0]])
    np.testing.assert_array_equal(perception.inputs.norm_distance, [[1.0, 1.0, 1.0]])
    assert not inputs.mate_available[0] and not inputs.forage_available[0]


def test_proximity_hand_computed() -> None:
    # A robot 0.1 m from the west wall, facing it: the front sensor (range 1 m) reads about
    # 0.1 m minus the sensor's offset from the centre, so proximity = 1 - range / 1.
    sw = SurvivalWorld(WorldConfig(n_robots=1, n_packs=0))
    world = sw.world
    world.set_robot_pose(0, -1.15 + 0.3, 0.0, math.pi)
    mujoco.mj_forward(world.model, world.data)
    perception = Perception(world, make_provider("geometric", world))
    perception.update()
    ranges = world.range_readings()
    assert ranges[0, 0] < 0.3
    assert perception.inputs.proximity[0, 0] == pytest.approx(1.0 - ranges[0, 0] / 1.0)
    # The back sensor (range 0.3 m) sees nothing: proximity 0.
    assert perception.inputs.proximity[0, 5] == 0.0
    # Search's inputs are the two largest proximities, in decreasing order.
    top = np.sort(perception.inputs.proximity[0])[::-1][:2]
    np.testing.assert_array_equal(perception.inputs.behaviour.search[0], top)


def test_inputs_keep_the_paper_fields_scale_in_a_larger_field() -> None:
    """In a 4.6 m field the camera sees to 6.5 m, while distances are still normalised by the
    paper field's diagonal, 3.25 m, which the shipped behaviours learned on."""
    evo = EvolutionConfig(population_size=8, n_robots=4)
    config = RunConfig(evolution=evo, world=WorldConfig(field_size=4.6, n_robots=4))
    runner = EvolutionRunner(config, 0, BehaviourPolicies.reactive())
    assert runner.vision.config.max_range == pytest.approx(6.5054, abs=1e-4)
    assert runner.perception.rules.max_distance == pytest.approx(3.2527, abs=1e-4)
    for _ in range(5):
        runner.step()
