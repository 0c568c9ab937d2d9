"""The hardware-like profile: seeded noise, each switch changes only what it names, actuators in
the physics, the runner hook (determinism, resume), per-robot statistics."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from behaviours import BehaviourPolicies
from cyber_rodent.profiles import (
    PROFILE_PARTS,
    ActuatorVariation,
    FieldLayout,
    HardwareProfile,
    RangeNoise,
    RangeSensorNoise,
    VisionUncertainty,
    apply_actuators,
    apply_field,
    apply_vision,
    profile_by_name,
    randomised,
)
from cyber_rodent.vision import CameraConfig, VisionNoise
from cyber_rodent.world import World, WorldConfig
from evolution.config import EvolutionConfig
from evolution.lab.transfer import hardware_run_config
from evolution.runner import EvolutionRunner, RunConfig
from evolution.stats import StatisticsRecorder

RANGE_MAX = np.tile(np.array([0.8, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3]), (3, 1))
SMALL = EvolutionConfig(population_size=8, n_robots=4, lifetime_steps=80, time_sharing_steps=40)


# --- range noise ---------------------------------------------------------------------------------
def test_range_noise_is_seeded() -> None:
    readings = np.full((3, 8), 0.2)

    def noisy(seed: int) -> np.ndarray:
        model = RangeSensorNoise(RangeNoise(), RANGE_MAX, np.random.default_rng(seed))
        return np.stack([model.apply(readings.copy()) for _ in range(5)])

    np.testing.assert_array_equal(noisy(7), noisy(7))
    assert not np.array_equal(noisy(7), noisy(8))


def test_range_noise_hand_computed() -> None:
    readings = np.array([[0.5, 0.29, 0.0, 0.1, 0.1, 0.1, 0.1, 0.1]] * 3)
    model = RangeSensorNoise(RangeNoise(std=0.1, dropout=0.0), RANGE_MAX, np.random.default_rng(3))
    gauss = np.random.default_rng(3).standard_normal((3, 8))
    expected = np.clip(readings + 0.1 * gauss, 0.0, RANGE_MAX)
    np.testing.assert_array_equal(model.apply(readings.copy()), expected)
    # every reading dropped: the sensor sees nothing, i.e. reads its full range
    dropped = RangeSensorNoise(
        RangeNoise(std=0.0, dropout=1.0), RANGE_MAX, np.random.default_rng(0)
    )
    np.testing.assert_array_equal(dropped.apply(readings.copy()), RANGE_MAX)
    # switched off: untouched, and no random numbers drawn
    rng = np.random.default_rng(0)
    off = RangeSensorNoise(RangeNoise(enabled=False), RANGE_MAX, rng)
    np.testing.assert_array_equal(off.apply(readings.copy()), readings)
    assert rng.random() == np.random.default_rng(0).random()


# --- validation ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: RangeNoise(std=-0.1), r"range_noise.std must be a number in \[0, 1\]"),
        (lambda: RangeNoise(dropout=1.5), r"range_noise.dropout must be a number in \[0, 1\]"),
        (lambda: VisionUncertainty(bearing_std_deg=100), r"vision.bearing_std_deg .*\[0, 90\]"),
        (
            lambda: ActuatorVariation(motor_lag_s=(0.2, 0.1)),
            r"actuators.motor_lag_s\[1\] must be a number in \[0.2, 1\]",
        ),
        (lambda: ActuatorVariation(weak_gain=0.0), r"actuators.weak_gain .*\[0.1, 1\]"),
        (
            lambda: ActuatorVariation(weak_robot=-2),
            r"actuators.weak_robot must be an integer in \[-1, ∞\)",
        ),
        (lambda: FieldLayout(n_robots=0), r"field.n_robots must be an integer in \[1, ∞\)"),
        (lambda: RangeNoise(enabled=1), r"range_noise.enabled must be true or false"),
        (lambda: HardwareProfile(vision=RangeNoise()), r"vision must be a VisionUncertainty"),
        (lambda: HardwareProfile().without("camera"), r"parts must be among range_noise, vision"),
        (lambda: profile_by_name("real"), r"profile must be one of sim, hardware"),
    ],
)
def test_bad_values_get_clear_errors(make, message) -> None:
    with pytest.raises(ValueError, match=message):
        make()


def test_weak_robot_must_exist() -> None:
    world = World(WorldConfig(n_robots=2, n_packs=0))
    with pytest.raises(ValueError, match=r"actuators.weak_robot must be in \[-1, 1\]"):
        apply_actuators(world, ActuatorVariation(weak_robot=2), np.random.default_rng(0))


# --- each switch changes only what it names -------------------------------------------------------
def test_defaults_and_switches() -> None:
    p = HardwareProfile()
    assert p.enabled_parts == PROFILE_PARTS
    assert (p.field.n_robots, p.field.n_packs) == (3, 6)  # the paper's hardware field
    assert p.without("vision").enabled_parts == ("range_noise", "actuators", "field")
    assert p.only("actuators").enabled_parts == ("actuators",)
    assert p.without("vision").range_noise == p.range_noise  # magnitudes kept, only the switch
    assert profile_by_name("sim") is None and profile_by_name("hardware") == HardwareProfile()


def test_apply_field_and_vision_change_only_their_part() -> None:
    world, camera = WorldConfig(), CameraConfig()
    assert apply_field(world, FieldLayout()) == dataclasses.replace(world, n_robots=3, n_packs=6)
    assert apply_field(world, FieldLayout(enabled=False)) == world
    noisy = apply_vision(camera, VisionUncertainty())
    assert noisy == dataclasses.replace(camera, noise=VisionNoise(5.0, 0.15, 0.1))
    assert apply_vision(camera, VisionUncertainty(enabled=False)) == camera


def _model_arrays(world: World) -> dict[str, np.ndarray]:
    m = world.model
    return {
        name: getattr(m, name).copy()
        for name in ("actuator_gainprm", "actuator_biasprm", "actuator_dynprm", "geom_friction",
                     "actuator_forcerange", "body_mass", "opt_timestep")
        if hasattr(m, name)
    }  # fmt: skip


def test_apply_actuators_hand_computed_and_only_actuators() -> None:
    world = World(WorldConfig(n_robots=3, n_packs=0))
    before = _model_arrays(world)
    variation = ActuatorVariation(
        wheel_gain_spread=0.0, friction_spread=0.0, motor_lag_s=(0.08, 0.08), weak_robot=1,
        weak_gain=0.5,
    )  # fmt: skip
    sample = apply_actuators(world, variation, np.random.default_rng(0))
    np.testing.assert_array_equal(sample.wheel_gain, [[1, 1], [0.5, 0.5], [1, 1]])
    motors = np.arange(world._ctrl_slice.start, world._ctrl_slice.stop)
    after = _model_arrays(world)
    np.testing.assert_allclose(
        after["actuator_gainprm"][motors, 0], 0.15 * np.repeat([1, 0.5, 1], 2)
    )
    np.testing.assert_allclose(after["actuator_dynprm"][motors, 0], 0.08)
    np.testing.assert_array_equal(after["actuator_biasprm"], before["actuator_biasprm"])
    np.testing.assert_array_equal(after["geom_friction"], before["geom_friction"])  # factor 1
    # a disabled part changes nothing and draws nothing
    other = World(WorldConfig(n_robots=3, n_packs=0))
    rng = np.random.default_rng(1)
    assert apply_actuators(other, ActuatorVariation(enabled=False), rng) is None
    for name, value in _model_arrays(other).items():
        np.testing.assert_array_equal(value, before[name], err_msg=name)
    assert rng.random() == np.random.default_rng(1).random()


def test_weak_robot_is_slower_in_the_physics() -> None:
    """Gain 0.5 on robot 1: driving straight it covers about half the distance of robot 0."""
    world = World(WorldConfig(n_robots=2, n_packs=0), np.random.default_rng(0))
    world.set_robot_pose(0, -0.6, -0.6, 0.0)
    world.set_robot_pose(1, -0.6, 0.6, 0.0)
    apply_actuators(
        world,
        ActuatorVariation(wheel_gain_spread=0, friction_spread=0, motor_lag_s=(0.05, 0.05),
                          weak_robot=1, weak_gain=0.5),
        np.random.default_rng(0),
    )  # fmt: skip
    mujoco.mj_forward(world.model, world.data)
    start = world.poses()[:, 0].copy()
    world.set_wheel_speeds(np.full(2, 0.5), np.full(2, 0.5))
    world.step(int(round(1.0 / world.model.opt.timestep)))
    travelled = world.poses()[:, 0] - start
    assert travelled[0] == pytest.approx(0.5, abs=0.06)  # 0.5 m/s for 1 s, minus the lag
    assert travelled[1] / travelled[0] == pytest.approx(0.5, abs=0.05)


def _runner(profile: HardwareProfile | None, seed: int = 0, base: RunConfig | None = None):
    base = base if base is not None else RunConfig(evolution=SMALL)
    config = hardware_run_config(base, profile, robots=3, agents_per_robot=2)
    return EvolutionRunner(config, seed, BehaviourPolicies.reactive())


@pytest.mark.parametrize("part", PROFILE_PARTS)
def test_each_switch_changes_only_what_it_names(part: str) -> None:
    plain = _runner(HardwareProfile().without(*PROFILE_PARTS))
    one = _runner(HardwareProfile().only(part))
    field_changed = (one.world.config.n_robots, one.world.config.n_packs) != (
        plain.world.config.n_robots, plain.world.config.n_packs,
    )  # fmt: skip
    assert field_changed == (part == "field")
    assert (one.config.camera != plain.config.camera) == (part == "vision")
    assert (one.range_noise is not None) == (part == "range_noise")
    assert (one.actuator_sample is not None) == (part == "actuators")
    if part != "field":  # same field: compare the compiled models and the first readings
        a, b = _model_arrays(plain.world), _model_arrays(one.world)
        changed = {name for name in a if not np.array_equal(a[name], b[name])}
        assert changed == ({"actuator_gainprm", "actuator_dynprm", "geom_friction"}
                           if part == "actuators" else set())  # fmt: skip
        np.testing.assert_array_equal(plain.world.poses(), one.world.poses())
        plain.perception.update()
        one.perception.update()
        ranges_differ = not np.array_equal(
            plain.perception.sensors.ranges, one.perception.sensors.ranges
        )
        assert ranges_differ == (part == "range_noise")
        vision_differs = not np.array_equal(
            plain.perception.nearest.distance, one.perception.nearest.distance
        )
        assert vision_differs == (part == "vision")
    plain.close()
    one.close()


def test_no_profile_is_the_plain_simulation() -> None:
    """A run without a profile is the run it always was: the profile's extra random stream
    does not shift the others, and a profile with every part off steps identically."""
    config = RunConfig(evolution=SMALL)
    a = EvolutionRunner(config, 4, BehaviourPolicies.reactive())
    b = EvolutionRunner(
        hardware_run_config(config, HardwareProfile().without(*PROFILE_PARTS), robots=4,
                            agents_per_robot=2),
        4, BehaviourPolicies.reactive(),
    )  # fmt: skip
    for _ in range(30):
        a.step()
        b.step()
    np.testing.assert_array_equal(a.world.poses(), b.world.poses())
    assert "profile" not in str(a.fingerprint)


def test_runner_config_checks_profile_consistency() -> None:
    with pytest.raises(ValueError, match=r"profile.field \(3 robots, 6 packs\) must match world"):
        RunConfig(evolution=SMALL, profile=HardwareProfile())
    with pytest.raises(ValueError, match=r"profile.vision .* must equal camera.noise"):
        RunConfig(evolution=SMALL, profile=HardwareProfile().without("field"))
    with pytest.raises(ValueError, match=r"profile must be a HardwareProfile or None"):
        RunConfig(evolution=SMALL, profile="hardware")


def test_profile_runs_are_seeded_and_resume_bit_identically(tmp_path) -> None:
    a, b = _runner(HardwareProfile(), seed=5), _runner(HardwareProfile(), seed=5)
    for _ in range(40):
        a.step()
        b.step()
    np.testing.assert_array_equal(a.world.poses(), b.world.poses())
    np.testing.assert_array_equal(a.perception.sensors.ranges, b.perception.sensors.ranges)
    np.testing.assert_array_equal(a.actuator_sample.wheel_gain, b.actuator_sample.wheel_gain)
    path = a.save_checkpoint(tmp_path / "gen_00000.ckpt")
    for _ in range(40):
        a.step()
    resumed = EvolutionRunner.from_checkpoint(path, BehaviourPolicies.reactive())
    for _ in range(40):
        resumed.step()
    np.testing.assert_array_equal(a.world.poses(), resumed.world.poses())
    np.testing.assert_array_equal(
        a.perception.sensors.ranges, resumed.perception.sensors.ranges
    )
    c = _runner(HardwareProfile(), seed=6)
    assert not np.array_equal(a.actuator_sample.wheel_gain, c.actuator_sample.wheel_gain)
    for r in (a, b, c, resumed):
        r.close()


def test_randomised_profile_samples_within_the_ranges() -> None:
    p = HardwareProfile()
    draws = [randomised(p, np.random.default_rng(s)) for s in range(20)]
    assert randomised(p, np.random.default_rng(3)) == draws[3]  # seeded
    for d in draws:
        assert 0 <= d.range_noise.std <= p.range_noise.std
        assert 0 <= d.vision.dropout <= p.vision.dropout
        assert p.actuators.weak_gain <= d.actuators.weak_gain <= 1.0
        assert d.field == p.field
    assert len({d.range_noise.std for d in draws}) == 20
    off = randomised(p.without("vision"), np.random.default_rng(0))
    assert not off.vision.enabled


# --- per-robot statistics (Fig. 7) ---------------------------------------------------------------
def test_per_robot_statistics_hand_computed() -> None:
    stats = StatisticsRecorder()
    stats.record_full_life(0, batteries=4, matings=1, robot=0)
    stats.record_full_life(0, batteries=6, matings=0, robot=0)  # unmated: scored 0
    stats.record_full_life(0, batteries=3, matings=2, robot=1)
    stats.record_full_life(0, batteries=9, matings=1)  # no robot given: pooled only
    row = stats.close(0, spare_list_size=0)
    assert row.batteries_full_life_mean == pytest.approx((4 + 0 + 3 + 9) / 4)
    assert stats.robot_records() == [
        {"generation": 0, "robot": 0, "batteries_mean": 2.0, "full_lifetimes": 2, "completed": 1},
        {"generation": 0, "robot": 1, "batteries_mean": 3.0, "full_lifetimes": 1, "completed": 1},
    ]
