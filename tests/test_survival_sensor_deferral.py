"""SurvivalWorld evaluates its rangefinders once per control step, without changing anything.

:meth:`SurvivalWorld.advance_physics` runs the first substeps with MuJoCo's sensor stage off
(the sensors are rays that do not act on the dynamics). These tests compare it bit for bit with
plain ``mj_step(nstep=n_substeps)`` over a long random drive with contacts, docking and mating.
"""

from __future__ import annotations

import mujoco
import numpy as np

from cyber_rodent import commands
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.world import World, WorldConfig


def _pair(seed: int) -> tuple[SurvivalWorld, SurvivalWorld]:
    config = SurvivalConfig(energy_decay=0.0)
    worlds = []
    for _ in range(2):
        world = World(WorldConfig(), np.random.default_rng(seed))
        worlds.append(SurvivalWorld(world, config, np.random.default_rng(seed)))
    return worlds[0], worlds[1]


def test_deferred_sensors_give_the_same_trajectory_and_readings() -> None:
    fast, reference = _pair(3)
    rng = np.random.default_rng(4)
    n = fast.n_robots
    contacts = 0
    for _ in range(400):
        wheels = commands.wheel_speeds(rng.integers(commands.N_COMMANDS, size=n))
        led, mate = rng.random(n) < 0.5, rng.random(n) < 0.5
        recharge = rng.random(n) < 0.9
        fast.step(wheels, led, mate, recharge)
        reference.begin_step(wheels, led, mate, recharge)
        m, d = reference.world.model, reference.world.data
        mujoco.mj_step(m, d, nstep=reference.n_substeps)
        reference.end_step()
        a, b = fast.world.data, reference.world.data
        np.testing.assert_array_equal(a.qpos, b.qpos)
        np.testing.assert_array_equal(a.qvel, b.qvel)
        np.testing.assert_array_equal(a.sensordata, b.sensordata)
        np.testing.assert_array_equal(fast.energy, reference.energy)
        np.testing.assert_array_equal(fast.docked, reference.docked)
        contacts += a.ncon
    assert fast.n_substeps > 1  # the deferral was exercised
    assert contacts > 0
    assert (fast.world.range_readings() < fast.world.range_max).any()  # sensors see things


def test_sensor_flag_is_restored_and_a_user_setting_kept() -> None:
    fast, _ = _pair(0)
    m = fast.world.model
    wheels = np.zeros((fast.n_robots, 2))
    flags = np.zeros(fast.n_robots, dtype=bool)
    before = m.opt.disableflags
    fast.step(wheels, flags, flags, flags)
    assert m.opt.disableflags == before
    sensor_off = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
    m.opt.disableflags = before | sensor_off
    stale = fast.world.data.sensordata.copy()
    fast.step(wheels + 0.1, flags, flags, flags)
    assert m.opt.disableflags == before | sensor_off  # still off: the user's choice
    np.testing.assert_array_equal(fast.world.data.sensordata, stale)  # not evaluated
