"""The robot as an object (``cyber_rodent/robot.py``): its numbers read from its MJCF file, its
sensor table checked against the file, two bodies in one process, and what derives from it."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from behaviours.definitions import load_values
from cyber_rodent.commands import COMMAND_SPEEDS, command_speeds
from cyber_rodent.gym_env import CyberRodentEnv
from cyber_rodent.observations import OBSERVATION_NAMES, observation_table
from cyber_rodent.robot import (
    CYBER_RODENT_PROXIMITY,
    CYBER_RODENT_SENSORS,
    RobotModel,
    RobotParts,
    SensorKind,
    SensorRow,
    cyber_rodent,
    register_sensor_kind,
    robot_model,
    unregister_sensor_kind,
)
from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.world import World, WorldConfig

PAGE = Path(__file__).resolve().parents[1] / "docs" / "extending.md"


def test_small_disc_numbers_are_read_from_its_file() -> None:
    """assets/mjcf/small_disc.xml: wheel spheres of 2.05 cm at ±2.65 cm, servos capped at
    6.341463 rad/s, a chassis cylinder 3.7 cm in radius, 0.16 + 2 x 0.02 kg."""
    disc = robot_model("small_disc")
    assert (disc.wheel_radius, disc.half_wheel_base, disc.mass) == (0.0205, 0.0265, 0.2)
    assert disc.top_speed == round(6.341463 * 0.0205, 6) == 0.13
    assert disc.body_length == 0.074 and disc.motor_time_constant == 0.05
    # Its farthest point from above: the teeth box's front corners at (0.046, ±0.012).
    assert disc.footprint_radius == pytest.approx(math.hypot(0.046, 0.012), abs=1e-6)
    assert disc.body_radius == 0.05
    assert disc.n_range == 8 and (disc.range_limits == 0.08).all()


def _refusal(**changes: object) -> str:
    arguments: dict[str, object] = {
        "name": "probe",
        "xml": "cyber_rodent.xml",
        "sensors": CYBER_RODENT_SENSORS,
        "proximity": CYBER_RODENT_PROXIMITY,
    }
    arguments.update(changes)
    with pytest.raises(ValueError) as error:
        RobotModel.from_mjcf(**arguments)  # type: ignore[arg-type]
    message = str(error.value)
    assert "\n" not in message
    return message


def test_a_sensor_table_that_disagrees_with_the_file_is_refused_in_one_line() -> None:
    turned = (SensorRow("range_front", "range", 1.0, 10.0), *CYBER_RODENT_SENSORS[1:])
    assert "'range_front' faces 0.0 deg, its row says 10" in _refusal(sensors=turned)
    unknown = (*CYBER_RODENT_SENSORS, SensorRow("sonar", "sonar", 2.0))
    assert "kind must be one of" in _refusal(sensors=unknown)
    nowhere = (*CYBER_RODENT_SENSORS, SensorRow("range_up", "range", 0.3, site="no_site"))
    assert "does not compile" in _refusal(sensors=nowhere)
    assert "proximity index 8 must be in [0, 7]" in _refusal(proximity=(0, 8))
    assert "has no geom 'fangs'" in _refusal(parts=RobotParts(teeth_geom="fangs"))
    register_sensor_kind(SensorKind("probe_gyro", "gyro", 2, "rad/s", np.copyto, signed=True))
    try:
        wrong = (SensorRow("range_front", "probe_gyro", 1.0), *CYBER_RODENT_SENSORS[1:])
        assert "'range_front' is not a gyro" in _refusal(sensors=wrong)
        with pytest.raises(ValueError, match="already registered"):
            register_sensor_kind(SensorKind("probe_gyro", "gyro", 2, "rad/s", np.copyto))
    finally:
        unregister_sensor_kind("probe_gyro")
    with pytest.raises(ValueError, match="not a MuJoCo sensor"):
        register_sensor_kind(SensorKind("probe", "telepathy", 0, "", np.copyto))


def test_an_unknown_robot_is_refused_naming_the_choices() -> None:
    with pytest.raises(ValueError, match=r"robot must be one of cyber_rodent, small_disc"):
        WorldConfig(robot="e-puck")


def test_two_bodies_drive_side_by_side_in_one_process() -> None:
    """Both worlds commanded far above any top speed for 0.75 s: each robot is capped by its
    own motors, and reads its own sensors' ranges."""
    paper = World(WorldConfig(n_robots=1, n_packs=0), np.random.default_rng(0))
    disc = World(WorldConfig(n_robots=1, n_packs=0, robot="small_disc"))
    speeds = []
    for world in (paper, disc):
        world.set_robot_pose(0, -1.0, 0.0, 0.0)  # 1.15 m of floor ahead
        world.set_wheel_speeds(np.array([5.0]), np.array([5.0]))
        world.step(30)  # settle 0.25 s
        start = world.poses()[0, :2].copy()
        world.step(60)
        speeds.append(float(np.hypot(*(world.poses()[0, :2] - start))) / 0.5)
    assert 0.95 * 1.3 < speeds[0] <= 1.3 and 0.95 * 0.13 < speeds[1] <= 0.13
    assert paper.range_readings()[0, 0] == 1.0 and disc.range_readings()[0, 0] == 0.08
    assert paper.robot is cyber_rodent() and disc.robot is robot_model("small_disc")


def test_what_derives_from_the_robot() -> None:
    disc = robot_model("small_disc")
    assert command_speeds(cyber_rodent()) is COMMAND_SPEEDS  # the paper's, untouched
    np.testing.assert_allclose(command_speeds(disc), COMMAND_SPEEDS * 0.1)
    assert command_speeds(disc)[0, 0] == pytest.approx(0.05)  # forward: 0.5 of 1.3 m/s
    assert observation_table(cyber_rodent().sensors).names == OBSERVATION_NAMES
    # The reflex spin, 0.3 m/s on the Cyber Rodent, is 0.03 m/s on the small disc.
    survival = SurvivalWorld(WorldConfig(n_robots=1, n_packs=0, robot="small_disc"))
    survival.docking.start_reflex(0, np.random.default_rng(0))
    assert np.abs(survival.reflex_wheels[0]).tolist() == [0.3 * 0.1, 0.3 * 0.1]
    env = CyberRodentEnv("forage", robot="small_disc", observation="raw")
    assert env.observation_bounds.high[0] == pytest.approx(0.08)
    with pytest.raises(ValueError, match=r"max_wheel_speed must be in \(0, 0.13\] m/s"):
        CyberRodentEnv("forage", robot="small_disc", action="continuous")
    env.close()


def test_the_retraining_commands_run(tmp_path: Path) -> None:
    """docs/extending.md §9's two commands, made short: 2 Search episodes, and one short
    generation that runs on the values they wrote."""
    from evolution.cli import main

    section = PAGE.read_text().split("## 9. Another robot")[1]
    (block,) = re.findall(r"```sh\n(.*?)```", section, flags=re.S)
    train, evolve = (line.split()[1:] for line in block.replace("\\\n", " ").splitlines())
    assert train[:3] == ["train-behaviours", "--robot", "small_disc"]
    values = tmp_path / "values"
    train[train.index("--out") + 1] = str(values)
    for behaviour in ("mate", "forage", "search"):
        assert main([*train, "--behaviour", behaviour, "--episodes", "2", "--no-progress"]) == 0
    assert load_values("search", values).metadata["robot"] == "small_disc"
    evolve[evolve.index("--policies") + 1] = str(values)
    evolve[evolve.index("--out") + 1] = str(tmp_path / "run")
    short = ["--generations", "1", "--no-progress", "--set", "evolution.population_size=8",
             "--set", "evolution.lifetime_steps=40",
             "--set", "evolution.time_sharing_steps=20"]  # fmt: skip
    assert main([*evolve, *short]) == 0
    assert (tmp_path / "run" / "statistics.csv").read_text().count("\n") == 2
