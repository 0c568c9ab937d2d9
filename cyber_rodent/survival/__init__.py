"""The survival world: virtual energy, docking and recharging, the LED, and IR mating.

This is the paper's survival setting (Elfwing et al., section 3.2 and Table 1; docs/design.md §5) as
mechanics of the simulated world, on top of :class:`cyber_rodent.world.World`:

* **Energy** (:mod:`~cyber_rodent.survival.kernels` ``end``, :mod:`~cyber_rodent.survival.energy`).
  Each robot carries the virtual battery of its active agent: it starts at 100, is capped at
  200 and drains 1 per control step; a step spent recharging adds 5 instead. We read "gains 5
  per step" (docs/design.md §5) as the net change of a recharge step, because the paper's
  numbers fit that reading: 40 steps x 5 = 200, the maximum energy, exactly
  (``decay_while_recharging=True`` gives the other reading, +5 - 1). Energy 0 is death, which
  the world reports once; a dead robot stands still with its LED off until the caller loads
  the next agent's energy (:meth:`SurvivalWorld.set_energy`).
* **Docking** (:mod:`~cyber_rodent.survival.energy`). A capture happens when MuJoCo reports a
  contact between a robot's charging teeth and a pack's electrode ring *and* the pack lies
  ahead of the robot within ``dock_bearing_tolerance_deg``. Brushing a pack with the side or
  back is not a capture (no teeth contact), and neither is catching the electrode ring with a
  corner of the teeth on an off-centre approach: that contact has the pack 16-24° off the
  heading (measured in ``tests/test_survival_physics.py``) and is refused until the robot,
  still pushing, pivots its teeth onto the pack. While recharging the robot is held in place
  by a weld of its chassis to the world, an equality constraint of the world model
  (``world.dock_hold_name``); its wheels are stopped. Packs are static and never used up
  (``WorldConfig.pack_reactivation_steps`` makes a docked-onto pack inactive, dark and
  undockable, for a while: a later study's variant, docs/design.md §9.26).
* **Recharging** (:mod:`~cyber_rodent.survival.energy`). Every step the caller's recharge
  decision (the evolved recharge controller) says continue or stop. Recharging ends on "stop",
  after ``max_recharge_steps`` (40) consecutive steps, or at full energy. Then the weld is
  released and the robot performs a short rotation reflex of random direction and length
  (seeded), which turns its teeth away from the pack so that it does not simply dock again
  (the paper's "random rotating motion").
* **LED** (:mod:`~cyber_rodent.survival.kernels` ``begin``, with the motor commands). Green on
  or dark, per robot, set by the caller every step; other robots see it through vision.
* **IR mating** (:mod:`~cyber_rodent.survival.mating`). An exchange succeeds when both robots
  signal Mate and each one's IR port faces the other's within ``mate_angle_deg`` (±15°) at a
  port-to-port distance of at most ``mate_distance`` (0.35 m), for ``mate_consecutive_steps``
  consecutive control steps. The world reports the pair; what is exchanged is the caller's
  business.

:class:`SurvivalWorld` (:mod:`~cyber_rodent.survival.world`) composes these into the lean
stepping path; :class:`SurvivalConfig` holds the rules, :class:`StepEvents` reports a step.
"""

from __future__ import annotations

from cyber_rodent.survival.config import SurvivalConfig
from cyber_rodent.survival.events import RechargeEnd, StepEvents
from cyber_rodent.survival.world import SurvivalWorld

__all__ = ["RechargeEnd", "StepEvents", "SurvivalConfig", "SurvivalWorld"]
