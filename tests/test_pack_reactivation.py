"""Packs that go inactive after a docking: ``WorldConfig.pack_reactivation_steps``.

The rule (docs/design.md §9.26): a docking onto a pack during control step t makes the pack
inactive at once, for the rest of step t and the N control steps after it (t+1 .. t+N); from
step t+N+1 it is active again. Vision runs at the start of a step and the docking at its end,
so with N = 3 and a docking at step t = 4 the pack is unseen by the vision of steps 5, 6, 7
and refuses dockings in steps 4 (another robot), 5, 6, 7; step 8 sees it and can dock onto it.
The dockings are real (robots drive their teeth into the pack, as in
``test_survival_physics.py``); the step numbers follow from the rule by hand.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np
import pytest

from cyber_rodent.backend import Backend
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.vision import BATTERY, CameraConfig, GeometricVision
from cyber_rodent.world import PACK_INACTIVE_RGBA, World, WorldConfig
from evolution.runner.world_state import capture_world, restore_world

BACKENDS: list[Backend] = ["numba", "numpy"]
#: The step (0-based) at which robot 0, 0.5 m from the pack and driving at 0.4 m/s, docks.
DOCKING_STEP = 4
#: Robot 0 and robot 1 drive into the pack from either side; robot 2 stands and looks at it.
FORWARD = np.array([[0.4, 0.4], [0.4, 0.4], [0.0, 0.0]])
NO = np.zeros(3, dtype=bool)
YES = np.ones(3, dtype=bool)


def pack_scene(
    n: int, backend: Backend, robot_1_x: float = 0.6, capture_rule: str = "docking"
) -> SurvivalWorld:
    """Three robots around one pack at the origin: robot 0 at (-0.5, 0) and robot 1 at
    (``robot_1_x``, 0) facing it, robot 2 at (0, 0.8) looking at it from the side."""
    sw = SurvivalWorld(
        WorldConfig(n_robots=3, n_packs=1, pack_reactivation_steps=n),
        SurvivalConfig(capture_rule=capture_rule),
        backend=backend,
    )
    w = sw.world
    w.set_pack_position(0, 0.0, 0.0)
    sw.refresh_pack_positions()
    w.set_robot_pose(0, -0.5, 0.0, 0.0)
    w.set_robot_pose(1, robot_1_x, 0.0, math.pi)
    w.set_robot_pose(2, 0.0, 0.8, -math.pi / 2)
    mujoco.mj_forward(w.model, w.data)
    return sw


def teeth_on_electrode(sw: SurvivalWorld, robot: int) -> bool:
    pair = {int(sw.world.teeth_geom[robot]), int(sw.world.electrode_geom[0])}
    return any({int(a), int(b)} == pair for a, b in sw.world.data.contact.geom)


#: The model's colours are float32.
DARK = PACK_INACTIVE_RGBA.astype(np.float32)


def pack_rgba(sw: SurvivalWorld) -> np.ndarray:
    rgba: np.ndarray = sw.world.model.geom_rgba[sw.world.pack_geom[0]].copy()
    return rgba


def test_the_default_is_the_papers_rule_and_the_range_is_checked() -> None:
    assert WorldConfig().pack_reactivation_steps == 0
    bad: Any
    for bad in (-1, 1_000_001, 2.5, True):
        with pytest.raises(ValueError, match=r"pack_reactivation_steps must be an integer in \["):
            WorldConfig(pack_reactivation_steps=bad)


@pytest.mark.parametrize("capture_rule", ["docking", "recharge"])
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_docked_pack_is_dark_and_locked_for_n_steps(backend: Backend, capture_rule: str) -> None:
    # N = 3. Robot 0 docks at step 4: the pack is inactive for the rest of step 4 and steps
    # 5, 6, 7 (countdown 3, 2, 1, 0 after them), unseen by the vision of steps 5, 6, 7. Robot 1
    # pushes its teeth on the electrode from step 5 and docks at step 8, the first step the
    # pack takes a docking again, which makes it inactive for steps 9, 10, 11. The capture
    # rule does not matter: the docking, not the capture, starts the countdown.
    sw = pack_scene(3, backend, capture_rule=capture_rule)
    vision = GeometricVision(sw.world, backend=backend)
    lit = pack_rgba(sw)
    unseen = {5, 6, 7, 9}
    countdown = {4: 3, 5: 2, 6: 1, 7: 0, 8: 3, 9: 2}
    dockings: list[tuple[int, int]] = []
    for k in range(10):
        seen = bool(vision.nearest_targets().visible[2, BATTERY])
        assert seen == (k not in unseen), k
        assert bool(vision.measure_targets().visible[2, -1]) == seen, k  # the full pass too
        energy = sw.energy.copy()
        ev = sw.step(FORWARD, NO, NO, YES)
        dockings += [(k, i) for i, _ in ev.dockings()]
        left = countdown.get(k, 0)
        assert sw.pack_countdown[0] == left, k
        assert sw.world.pack_active[0] == (left == 0), k
        np.testing.assert_array_equal(pack_rgba(sw), DARK if left else lit)
        if k in (5, 6, 7):
            # Robot 1's teeth touch the electrode, its body held off by the pack's, but it
            # cannot dock; robot 0, docked, keeps recharging.
            assert teeth_on_electrode(sw, 1) and not sw.docked[1], k
            assert 0.1 < sw.world.poses()[1, 0] < 0.2, k
            assert sw.docked[0] and sw.energy[0] == energy[0] + 5.0, k
    assert dockings == [(4, 0), (8, 1)]


@pytest.mark.parametrize("backend", BACKENDS)
def test_two_robots_on_one_pack_in_one_step(backend: Backend) -> None:
    # Both robots reach the pack in the same step: without a reactivation time both dock (the
    # paper's rule); with one the first docking makes the pack inactive and the other waits.
    for n, expected in ((0, [(4, 0), (4, 1)]), (3, [(4, 0), (8, 1)])):
        sw = pack_scene(n, backend, robot_1_x=0.5)
        dockings = []
        for k in range(10):
            dockings += [(k, i) for i, _ in sw.step(FORWARD, NO, NO, YES).dockings()]
        assert dockings == expected, n


@pytest.mark.parametrize("backend", BACKENDS)
def test_without_a_reactivation_time_nothing_changes(backend: Backend) -> None:
    # N = 0: the pack never goes inactive, stays in its colour, is seen throughout, the
    # countdown never runs, and robot 1 docks as soon as its teeth reach the electrode.
    sw = pack_scene(0, backend)
    vision = GeometricVision(sw.world, backend=backend)
    lit = pack_rgba(sw)
    dockings = []
    for k in range(12):
        assert vision.nearest_targets().visible[2, BATTERY], k
        dockings += [(k, i) for i, _ in sw.step(FORWARD, NO, NO, YES).dockings()]
        assert sw.world.pack_active[0] and sw.pack_countdown[0] == 0
        assert sw.docking.inactive_packs == 0
        np.testing.assert_array_equal(pack_rgba(sw), lit)
    assert dockings == [(4, 0), (5, 1)]
    # Until the first docking a world with a reactivation time moves exactly as one without.
    a, b = pack_scene(0, backend), pack_scene(30, backend)
    for _ in range(DOCKING_STEP):
        a.step(FORWARD, NO, NO, YES)
        b.step(FORWARD, NO, NO, YES)
    assert a.world.data.qpos.tobytes() == b.world.data.qpos.tobytes()
    assert a.world.model.geom_rgba.tobytes() == b.world.model.geom_rgba.tobytes()


@pytest.mark.parametrize("backend", BACKENDS)
def test_an_inactive_pack_still_hides_what_is_behind_it(backend: Backend) -> None:
    # Robot 0 looks along +x at pack 0 (0.5 m ahead) and pack 1 right behind it.
    world = World(WorldConfig(n_robots=1, n_packs=2))
    world.set_robot_pose(0, -0.5, 0.0, 0.0)
    world.set_pack_position(0, 0.0, 0.0)
    world.set_pack_position(1, 0.12, 0.0)
    mujoco.mj_forward(world.model, world.data)
    vision = GeometricVision(world, backend=backend)
    lit = vision.measure_targets()
    world.set_pack_active(0, False)
    dark = vision.measure_targets()
    assert lit.visible[0, -2] and not dark.visible[0, -2]  # pack 0 is no target any more
    share = lit.visible_share[0, -1]
    assert 0.0 < share < 1.0  # pack 1 peeks over pack 0 ...
    assert dark.visible_share[0, -1] == share  # ... and pack 0 hides it as much when dark
    world.set_pack_active(0, True)
    np.testing.assert_array_equal(vision.measure_targets().visible, lit.visible)
    np.testing.assert_array_equal(
        world.model.geom_rgba[world.pack_geom], world.pack_rgba.astype(np.float32)
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_rendered_camera_sees_no_blue_on_an_inactive_pack(backend: Backend) -> None:
    from cyber_rodent.vision.rendered import RenderedVision

    world = World(WorldConfig(n_robots=1, n_packs=1))
    world.set_robot_pose(0, -0.5, 0.0, 0.0)
    world.set_pack_position(0, 0.0, 0.0)
    mujoco.mj_forward(world.model, world.data)
    config = CameraConfig(view_width=48, height=72)
    with RenderedVision(world, config, backend=backend) as camera:
        assert camera.observe().visible[0, BATTERY]
        world.set_pack_active(0, False)
        frame = camera.observe()
        masks = camera.last_masks
        assert masks is not None
        assert not frame.visible[0, BATTERY] and not masks[BATTERY].any()
        world.set_pack_active(0, True)
        assert camera.observe().visible[0, BATTERY]


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_resumed_world_continues_the_countdown_bit_identically(backend: Backend) -> None:
    n = 6
    original = pack_scene(n, backend)
    vision = GeometricVision(original.world, backend=backend)
    for _ in range(DOCKING_STEP + 3):  # mid-countdown: 4 steps still to go
        original.step(FORWARD, NO, NO, YES)
    assert original.pack_countdown[0] == 4 and not original.world.pack_active[0]
    saved = capture_world(original, vision)

    resumed = SurvivalWorld(
        WorldConfig(n_robots=3, n_packs=1, pack_reactivation_steps=n),
        rng=np.random.default_rng(9),  # another placement: everything comes from the state
        backend=backend,
    )
    resumed_vision = GeometricVision(resumed.world, backend=backend)
    restore_world(saved, resumed, resumed_vision)
    assert resumed.pack_countdown[0] == 4 and not resumed.world.pack_active[0]
    assert resumed.docking.inactive_packs == 1
    docked = []
    for k in range(DOCKING_STEP + 3, DOCKING_STEP + 12):
        seen = vision.nearest_targets()
        again = resumed_vision.nearest_targets()
        np.testing.assert_array_equal(seen.visible, again.visible)
        np.testing.assert_array_equal(seen.distance, again.distance)
        a = original.step(FORWARD, NO, NO, YES)
        b = resumed.step(FORWARD, NO, NO, YES)
        assert repr(a) == repr(b)
        docked += [(k, i) for i, _ in a.dockings()]
        for name in ("pack_countdown", "energy", "docked"):
            np.testing.assert_array_equal(getattr(original, name), getattr(resumed, name))
        np.testing.assert_array_equal(original.world.pack_active, resumed.world.pack_active)
        assert original.world.data.qpos.tobytes() == resumed.world.data.qpos.tobytes()
        assert original.world.model.geom_rgba.tobytes() == resumed.world.model.geom_rgba.tobytes()
    assert docked == [(DOCKING_STEP + n + 1, 1)]  # the countdown ran on in both


def test_a_state_without_countdowns_loads_with_every_pack_active() -> None:
    # A state written before packs could go inactive.
    sw = pack_scene(3, "numpy")
    state = sw.state()
    del state["pack_countdown"]
    for _ in range(DOCKING_STEP + 1):
        sw.step(FORWARD, NO, NO, YES)
    assert not sw.world.pack_active[0]
    sw.load_state(state)
    assert "pack_countdown" not in state  # the caller's state is not changed
    assert sw.pack_countdown[0] == 0 and sw.world.pack_active[0]
    assert sw.docking.inactive_packs == 0
    np.testing.assert_array_equal(pack_rgba(sw), sw.world.pack_rgba[0].astype(np.float32))


@pytest.mark.parametrize(("n", "countdown"), [(3, 5), (3, -1), (0, 1)])
def test_load_state_refuses_a_countdown_the_rule_cannot_reach(n: int, countdown: int) -> None:
    sw = pack_scene(n, "numpy")
    state = sw.state()
    state["pack_countdown"] = np.array([countdown], dtype=np.int64)
    with pytest.raises(ValueError, match=r"\['pack_countdown'\] must be in \[0, "):
        sw.load_state(state)
    assert sw.pack_countdown[0] == 0 and sw.world.pack_active[0]  # nothing was written
