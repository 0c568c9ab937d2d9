"""The compiled survival mechanics change nothing: a world on either backend runs the same.

:mod:`cyber_rodent.survival.kernels` holds the per-step rules of ``SurvivalWorld`` twice: the
compiled kernels (``backend="numba"``) and their numpy references (``backend="numpy"``):
``begin_step``'s commands, LEDs and mating signals, ``end_step``'s energy rules (recharge,
stopping rules, decay, deaths) and the scan of the contact list for captures. Scripted robots
that seek packs, seek each other and wander dock, end recharges, die and mate many times; a
world on each backend, given the same commands, must give the same trajectory, the same events
and the same state, bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cyber_rodent import constants as C
from cyber_rodent.backend import Backend
from cyber_rodent.survival import RechargeEnd, StepEvents, SurvivalConfig, SurvivalWorld
from cyber_rodent.world import World, WorldConfig

SEEK_PACK, SEEK_ROBOT, WANDER = 0, 1, 2
#: Net +4 per recharge step: a robot that docks with less than 40 reaches the step limit first.
CONFIG = SurvivalConfig(decay_while_recharging=True)
#: Below this energy a scripted robot seeks a pack whatever its mode.
HUNGRY = 20.0


def _world(backend: Backend, seed: int = 3) -> SurvivalWorld:
    world = World(WorldConfig(), np.random.default_rng(seed))
    return SurvivalWorld(world, CONFIG, np.random.default_rng(seed), backend=backend)


def _steer(pose: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """Wheel speeds that turn towards ``target`` and drive on once roughly facing it."""
    x, y, yaw = pose
    error = (math.atan2(target[1] - y, target[0] - x) - yaw + math.pi) % (2 * math.pi) - math.pi
    forward = 0.35 * max(math.cos(error), 0.0) ** 4
    turn = float(np.clip(0.4 * error, -0.3, 0.3))
    return forward - turn, forward + turn


def _commands(
    sw: SurvivalWorld, mode: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, ...]:
    """The scripted robots' commands, from the world's state and ``rng``."""
    n = sw.n_robots
    poses = sw.world.poses()
    packs = sw.world.pack_positions()
    wheels = np.zeros((n, 2))
    noise = rng.uniform(-0.05, 0.05, size=(n, 2))
    wander = rng.uniform(-C.TOP_SPEED, C.TOP_SPEED, size=(n, 2))
    for i in range(n):
        if mode[i] == SEEK_PACK or sw.energy[i] < HUNGRY:
            near = packs[np.argmin(np.linalg.norm(packs - poses[i, :2], axis=1))]
            wheels[i] = _steer(poses[i], near)
        elif mode[i] == SEEK_ROBOT:
            others = np.delete(np.arange(n), i)
            gaps = np.linalg.norm(poses[others, :2] - poses[i, :2], axis=1)
            wheels[i] = _steer(poses[i], poses[others[np.argmin(gaps)], :2])
        else:
            wheels[i] = wander[i]
    wheels = np.clip(wheels + noise, -C.TOP_SPEED, C.TOP_SPEED)
    led = rng.random(n) < 0.5
    mate = mode == SEEK_ROBOT
    continue_recharge = rng.random(n) < 0.985
    return wheels, led, mate, continue_recharge


def _assert_same(a: SurvivalWorld, b: SurvivalWorld) -> None:
    np.testing.assert_array_equal(a.world.data.qpos, b.world.data.qpos)
    np.testing.assert_array_equal(a.world.data.qvel, b.world.data.qvel)
    np.testing.assert_array_equal(a.world.data.ctrl, b.world.data.ctrl)
    for name in ("energy", "recharge_steps", "docked", "dock_pack", "reflex_steps_left", "alive"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for name in StepEvents.ARRAYS:
        np.testing.assert_array_equal(getattr(a.events, name), getattr(b.events, name), name)
    assert a.events.any == b.events.any
    np.testing.assert_array_equal(a.world.led_on, b.world.led_on)
    np.testing.assert_array_equal(a.world.model.geom_rgba, b.world.model.geom_rgba)


def test_compiled_mechanics_equal_numpy() -> None:
    compiled, reference = _world("numba"), _world("numpy")
    rng = np.random.default_rng(5)
    n = compiled.n_robots
    mode = np.full(n, SEEK_PACK)
    counts = dict.fromkeys(("dock", "recharge_end", "death", "mate"), 0)
    reasons: set[RechargeEnd] = set()
    for step in range(2500):
        if step % 60 == 0:
            mode = rng.choice([SEEK_PACK, SEEK_ROBOT, WANDER], size=n, p=[0.35, 0.55, 0.1])
        commands = _commands(compiled, mode, rng)
        a = compiled.step(*commands)
        b = reference.step(*commands)
        _assert_same(compiled, reference)
        counts["dock"] += len(a.dockings())
        counts["recharge_end"] += len(a.recharge_ends())
        reasons.update(reason for _, reason in a.recharge_ends())
        counts["mate"] += len(a.matings())
        for i in a.deaths():  # time sharing: the next agent takes over the robot
            counts["death"] += 1
            for sw in (compiled, reference):
                sw.set_energy(i, sw.config.initial_energy)
        assert a.dockings() == b.dockings() and a.recharge_ends() == b.recharge_ends()
        assert a.deaths() == b.deaths() and a.matings() == b.matings()
    # Not vacuous: every rule the kernels implement fired many times.
    for kind, k in counts.items():
        assert k >= 10, (kind, counts)
    assert reasons == {RechargeEnd.DECISION, RechargeEnd.MAX_STEPS, RechargeEnd.FULL}


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_invalid_wheels_change_nothing(backend: Backend) -> None:
    """A NaN or out-of-range command raises the named error and leaves the state as it was."""
    sw = SurvivalWorld(rng=np.random.default_rng(0), backend=backend)
    n = sw.n_robots
    ok = np.zeros((n, 2))
    flags = np.zeros(n, dtype=bool)
    sw.step(ok, flags, flags, flags)
    ctrl = sw.world.data.ctrl.copy()
    state = sw.state()
    for bad, message in ((np.nan, "finite"), (2.0, "motor limit")):
        wheels = ok.copy()
        wheels[n - 1, 1] = bad
        with pytest.raises(ValueError, match=message):
            sw.step(wheels, ~flags, flags, flags)
        np.testing.assert_array_equal(sw.world.data.ctrl, ctrl)
        after = sw.state()
        assert after["events"]["any"] == state["events"]["any"]
        for name in ("energy", "led_on", "recharging", "mate_signal", "step_count"):
            np.testing.assert_array_equal(after[name], state[name], err_msg=name)


def test_unknown_backend_is_refused() -> None:
    with pytest.raises(ValueError, match="backend must be one of numba, numpy"):
        SurvivalWorld(WorldConfig(n_robots=1, n_packs=0), backend="fortran")  # type: ignore[arg-type]
