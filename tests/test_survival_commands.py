"""The discrete wheel-command set (cyber_rodent.commands): definition, lookup, physical effect."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from cyber_rodent import commands
from cyber_rodent.robot import cyber_rodent
from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.world import WorldConfig

#: The paper's robot, read from its MJCF file and sensor table.
CR = cyber_rodent()


def test_command_set_is_defined_once_and_within_the_motor_limit():
    assert commands.N_COMMANDS == len(commands.WHEEL_COMMANDS) == commands.COMMAND_SPEEDS.shape[0]
    assert len(set(commands.COMMAND_NAMES)) == commands.N_COMMANDS
    assert np.abs(commands.COMMAND_SPEEDS).max() <= CR.top_speed
    assert not commands.COMMAND_SPEEDS.flags.writeable
    with pytest.raises(ValueError):
        commands.COMMAND_SPEEDS[0, 0] = 1.0


def test_lookup_by_index_and_name():
    i = commands.command_index("spin_left")
    assert commands.WHEEL_COMMANDS[i].name == "spin_left"
    speeds = commands.wheel_speeds(np.array([0, i]))
    assert speeds.shape == (2, 2)
    assert speeds[1].tolist() == [-0.2, 0.2]
    out = np.empty((2, 2))
    assert commands.wheel_speeds(np.array([i, 0]), out=out) is out
    assert out[0].tolist() == [-0.2, 0.2]


@pytest.mark.parametrize(
    ("indices", "match"),
    [
        (np.array([0, commands.N_COMMANDS]), r"command indices must be in \[0, 8\)"),
        (np.array([-1]), r"command indices must be in \[0, 8\)"),
        (np.array([0.5]), "must be integers"),
    ],
)
def test_bad_indices_raise(indices, match):
    with pytest.raises(ValueError, match=match):
        commands.wheel_speeds(indices)


def test_unknown_name_and_over_limit_command_raise():
    with pytest.raises(ValueError, match="unknown wheel command 'jump'; known commands: forward"):
        commands.command_index("jump")
    with pytest.raises(ValueError, match=r"left must be a number in \[-1.3, 1.3\]"):
        commands.WheelCommand("rocket", 2.0, 2.0)


def _drive(name: str, steps: int) -> np.ndarray:
    sw = SurvivalWorld(WorldConfig(n_robots=1, n_packs=0))
    sw.world.set_robot_pose(0, -0.8, 0.0, 0.0)
    mujoco.mj_forward(sw.world.model, sw.world.data)
    no, yes = np.zeros(1, bool), np.ones(1, bool)
    wheels = commands.wheel_speeds(np.array([commands.command_index(name)]))
    start = sw.world.poses()[0].copy()
    for _ in range(steps):
        sw.step(wheels, no, no, yes)
    return sw.world.poses()[0] - start


def test_forward_moves_half_a_metre_per_second():
    # 0.5 m/s for 1 s (5 control steps of 0.2 s): 0.5 m, less a little for the motors
    # spinning up.
    dx, dy, dyaw = _drive("forward", 5)
    assert 0.42 < dx <= 0.5 and abs(dy) < 0.01 and abs(dyaw) < 0.02


def test_spin_left_turns_counter_clockwise_in_place():
    # Rim speeds ±0.2 m/s at a half wheel base of 8 cm: 2.5 rad/s, 0.5 rad per 0.2 s step.
    dx, dy, dyaw = _drive("spin_left", 2)
    assert 0.7 < dyaw <= 1.0 + 1e-6
    assert math.hypot(dx, dy) < 0.02
