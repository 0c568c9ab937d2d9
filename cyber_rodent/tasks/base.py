"""What every Cyber Rodent task shares: the world, vision, observations and actions.

A task owns one :class:`~cyber_rodent.survival.SurvivalWorld` (the same object the evolution
runner steps on its lean path) and drives it from dm-control: :meth:`before_step` applies the
action (``SurvivalWorld.begin_step``), dm-control advances the physics by the world's substeps
(``mj_step``, no legacy split step, so the trajectory is the lean path's), and
:meth:`after_step` runs the mechanics (``SurvivalWorld.end_step``) and the vision provider once.

Multi-robot convention, the same in every task: a task *controls* ``k`` robots (robots
``0..k-1``; the others, if any, are parked obstacles with wheels stopped and LEDs off). Every
observation and action array has a leading axis of length ``k``, and the reward is a ``(k,)``
array, one per controlled robot. Forage and Search control one robot (``k = 1``), Mate two,
Survival all of them. One shape rule for all tasks lets a learner treat "one robot" and "two
robots running the same behaviour" alike.

Observations (per controlled robot; raw physical units, bounds in the specs):

==================  =========  ===============================================================
name                shape      meaning
==================  =========  ===============================================================
``range``           (k, 8)     IR range readings, m, sensor order of ``constants.RANGE_SENSORS``
``nearest_led``     (k, 3)     nearest green LED: bearing (rad, + left), distance (m), visible
``nearest_face``    (k, 3)     nearest red face, same layout
``nearest_battery`` (k, 3)     nearest blue battery pack, same layout
``energy``          (k,)       virtual energy
``led_on``          (k,)       own LED state (1 = green)
``docked``          (k,)       1 while docked and recharging
``recharge_steps``  (k,)       consecutive steps recharged in the current docking
==================  =========  ===============================================================

An unseen target has bearing 0, distance ``camera.max_range`` and visible 0 (docs/design.md §5 maps
an unseen target's normalised distance to 1; ``vision.normalise_distance`` does that).

Actions are a dict: ``wheels`` (k, 2) wheel rim speeds in m/s within the motor limit
±``TOP_SPEED``, and ``led`` (k,) in [0, 1] (on above 0.5). Survival adds ``mate`` and
``recharge`` (see there). The discrete command set that behaviours choose from is
:mod:`cyber_rodent.commands`.
"""

from __future__ import annotations

import inspect
import math
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import numpy as np
from dm_control.mjcf import Physics
from dm_control.rl import control
from dm_env import specs

from cyber_rodent import constants as C
from cyber_rodent.survival import StepEvents, SurvivalConfig, SurvivalWorld
from cyber_rodent.vision import BATTERY, FACE, LED, CameraConfig, VisionFrame, make_provider
from cyber_rodent.world import World, WorldConfig

#: Observation names in a stable order (also the order of a flattened observation).
OBSERVATION_NAMES = (
    "range",
    "nearest_led",
    "nearest_face",
    "nearest_battery",
    "energy",
    "led_on",
    "docked",
    "recharge_steps",
)
_TARGET_OBSERVATIONS = (("nearest_led", LED), ("nearest_face", FACE), ("nearest_battery", BATTERY))
#: Threshold of the [0, 1] switch actions (``led``, ``mate``, ``recharge``): on above it.
SWITCH_ON = 0.5


class CyberRodentTask(control.Task):  # type: ignore[misc]  # dm_control has no type hints
    """Base class of the tasks; subclasses set defaults and rewards.

    Args:
        rng: the task's generator (placement, reflexes, start conditions, vision noise).
        n_robots: robots in the field.
        n_packs: battery packs in the field.
        episode_steps: control steps per episode (the episode's lifetime); the episode is cut
            there with discount 1.
        survival: the survival rules (energy, docking, mating).
        vision: vision provider, ``"geometric"`` (default) or ``"rendered"``.
        camera: the camera config shared by both providers.
        timestep: physics timestep, s (default: ``WorldConfig``'s).

    Raises:
        ValueError: for an invalid option (the message names it and its allowed range).
    """

    #: Robots controlled by the action (``None`` = all robots); subclasses override.
    n_controlled: int | None = None
    #: Task name for :func:`cyber_rodent.tasks.load`.
    name = "base"

    def __init__(
        self,
        rng: np.random.Generator,
        *,
        n_robots: int = 4,
        n_packs: int = 5,
        episode_steps: int = 100,
        survival: SurvivalConfig | None = None,
        vision: str = "geometric",
        camera: CameraConfig | None = None,
        timestep: float | None = None,
    ):
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng must be a numpy Generator, got {type(rng).__name__}")
        if isinstance(episode_steps, bool) or not isinstance(episode_steps, int | np.integer):
            raise ValueError(f"episode_steps must be an integer >= 1, got {episode_steps!r}")
        if episode_steps < 1:
            raise ValueError(
                f"episode_steps (the episode's lifetime in control steps) must be >= 1, "
                f"got {episode_steps!r}"
            )
        if survival is not None and not isinstance(survival, SurvivalConfig):
            raise ValueError(f"survival must be a SurvivalConfig, got {type(survival).__name__}")
        self.episode_steps = int(episode_steps)
        self._rng = rng
        world_cfg = WorldConfig(n_robots=n_robots, n_packs=n_packs)
        if timestep is not None:
            world_cfg = WorldConfig(n_robots=n_robots, n_packs=n_packs, timestep=timestep)
        k = n_robots if self.n_controlled is None else self.n_controlled
        if k > n_robots:
            raise ValueError(
                f"n_robots must be >= {k} for the {self.name} task (it controls {k}), "
                f"got {n_robots}"
            )
        self.k = k
        world = World(world_cfg, rng)
        self.survival = SurvivalWorld(world, survival, rng)
        self.world = world
        # The provider gets its own stream, so its noise never shifts the placement draws.
        self.vision = make_provider(vision, world, camera, rng.spawn(1)[0])
        self.camera = self.vision.config
        self.max_range = float(self.camera.max_range)
        self.frame: VisionFrame | None = None
        n = world.config.n_robots
        # Commands of all robots, rebuilt from the action every step (preallocated).
        self._wheels = np.zeros((n, 2))
        self._led = np.zeros(n, dtype=bool)
        self._mate = np.zeros(n, dtype=bool)
        self._recharge = np.zeros(n, dtype=bool)
        self.last_events: StepEvents = self.survival.events
        self._action_spec = self._make_action_spec()
        self._observation_spec = self._make_observation_spec()

    # --- specs -------------------------------------------------------------------------------
    @property
    def physics(self) -> Physics:
        """The dm-control ``Physics`` of the world (its MjModel/MjData are the world's)."""
        return self.world.physics

    def _make_action_spec(self) -> OrderedDict[str, specs.BoundedArray]:
        k = self.k
        spec = OrderedDict()
        spec["wheels"] = specs.BoundedArray(
            (k, 2), np.float64, -C.TOP_SPEED, C.TOP_SPEED, name="wheels"
        )
        spec["led"] = specs.BoundedArray((k,), np.float64, 0.0, 1.0, name="led")
        return spec

    def _make_observation_spec(self) -> OrderedDict[str, specs.BoundedArray]:
        k = self.k
        cfg = self.survival.config
        spec = OrderedDict()
        spec["range"] = specs.BoundedArray(
            (k, C.N_RANGE), np.float64, 0.0, self.world.range_max[:k].copy(), name="range"
        )
        lo = np.tile([-math.pi, 0.0, 0.0], (k, 1))
        hi = np.tile([math.pi, self.max_range, 1.0], (k, 1))
        for key, _ in _TARGET_OBSERVATIONS:
            spec[key] = specs.BoundedArray((k, 3), np.float64, lo, hi, name=key)
        spec["energy"] = specs.BoundedArray((k,), np.float64, 0.0, cfg.max_energy, name="energy")
        spec["led_on"] = specs.BoundedArray((k,), np.float64, 0.0, 1.0, name="led_on")
        spec["docked"] = specs.BoundedArray((k,), np.float64, 0.0, 1.0, name="docked")
        spec["recharge_steps"] = specs.BoundedArray(
            (k,), np.float64, 0.0, float(cfg.max_recharge_steps), name="recharge_steps"
        )
        return spec

    def action_spec(self, physics: Physics | None = None) -> OrderedDict[str, specs.BoundedArray]:
        return self._action_spec

    def observation_spec(
        self, physics: Physics | None = None
    ) -> OrderedDict[str, specs.BoundedArray]:
        return self._observation_spec

    def reward_spec(self) -> specs.Array:
        """One reward per controlled robot."""
        return specs.Array((self.k,), np.float64, name="reward")

    # --- episode -----------------------------------------------------------------------------
    def initialize_episode(self, physics: Physics) -> None:
        """New placement and newborn energies; subclasses add start conditions."""
        self.survival.reset(self._rng)
        self.world.set_led(False)
        self._start_episode()
        self.frame = self.vision.observe()
        self.survival.events.clear()

    def _start_episode(self) -> None:
        """Hook: task-specific initial state (placement is already drawn)."""

    def _redraw_until(
        self, condition: Callable[[VisionFrame], object], what: str, attempts: int = 200
    ) -> None:
        """Re-draw the placement until ``condition(frame)`` holds (a start condition)."""
        for _ in range(attempts):
            if condition(self.vision.observe()):
                return
            self.survival.reset(self._rng)
            self._start_state()
        raise RuntimeError(f"no placement with {what} in {attempts} draws")

    def _start_state(self) -> None:
        """Hook: state to restore after every re-draw of the placement (e.g. LEDs)."""

    def before_step(self, action: Any, physics: Physics | None = None) -> None:
        """Validate the action and hand the commands to the world (``begin_step``)."""
        self._read_action(action)
        self.survival.begin_step(self._wheels, self._led, self._mate, self._recharge)

    def after_step(self, physics: Physics | None = None) -> None:
        """Energy, docking, mating (``end_step``), then what every robot sees."""
        self.last_events = self.survival.end_step()
        self.frame = self.vision.observe()

    # --- actions -------------------------------------------------------------------------------
    def _read_action(self, action: Any) -> None:
        if not isinstance(action, dict | OrderedDict):
            raise ValueError(
                f"action must be a dict with keys {list(self._action_spec)}, "
                f"got {type(action).__name__}"
            )
        unknown = set(action) - set(self._action_spec)
        missing = set(self._action_spec) - set(action)
        if unknown or missing:
            raise ValueError(
                f"action keys must be {list(self._action_spec)}; "
                f"missing {sorted(missing)}, unknown {sorted(unknown)}"
            )
        k = self.k
        values = {}
        for key, spec in self._action_spec.items():
            value = np.asarray(action[key], dtype=np.float64)
            if value.shape != spec.shape:
                raise ValueError(f"action {key!r} must have shape {spec.shape}, got {value.shape}")
            if not np.isfinite(value).all():
                raise ValueError(f"action {key!r} must be finite (got NaN or inf)")
            if (value < spec.minimum).any() or (value > spec.maximum).any():
                raise ValueError(
                    f"action {key!r} must be in [{float(np.min(spec.minimum))}, "
                    f"{float(np.max(spec.maximum))}], got values from {value.min():.4g} to "
                    f"{value.max():.4g}"
                )
            values[key] = value
        self._wheels[:k] = values["wheels"]
        self._wheels[k:] = 0.0
        np.greater(values["led"], SWITCH_ON, out=self._led[:k])
        self._led[k:] = False
        self._set_decisions(values)

    def _set_decisions(self, values: dict[str, np.ndarray]) -> None:
        """Hook: the mate signals and recharge decisions for this step."""
        self._mate[:] = False
        self._recharge[:] = False

    # --- observations --------------------------------------------------------------------------
    def get_observation(self, physics: Physics | None = None) -> OrderedDict[str, np.ndarray]:
        k = self.k
        sw = self.survival
        frame = self.frame
        if frame is None:
            raise RuntimeError("no observation before the first episode is initialised")
        obs = OrderedDict()
        obs["range"] = self.world.range_readings()[:k]
        for key, cls in _TARGET_OBSERVATIONS:
            target = np.empty((k, 3))
            visible = frame.visible[:k, cls]
            target[:, 0] = np.where(visible, frame.bearing[:k, cls], 0.0)
            target[:, 1] = np.where(
                visible, np.minimum(frame.distance[:k, cls], self.max_range), self.max_range
            )
            target[:, 2] = visible
            obs[key] = target
        obs["energy"] = sw.energy[:k].copy()
        obs["led_on"] = self.world.led_on[:k].astype(np.float64)
        obs["docked"] = sw.docked[:k].astype(np.float64)
        obs["recharge_steps"] = sw.recharge_steps[:k].astype(np.float64)
        return obs

    # --- reward and termination (subclasses) -----------------------------------------------------
    def get_reward(self, physics: Physics | None = None) -> np.ndarray:
        raise NotImplementedError

    def get_termination(self, physics: Physics | None = None) -> float | None:
        """Discount 0 if a controlled robot died (its energy reached 0), else continue."""
        if not self.survival.alive[: self.k].all():
            return 0.0
        return None

    @classmethod
    def option_names(cls) -> tuple[str, ...]:
        """The keyword options the task accepts (for :func:`cyber_rodent.tasks.load`)."""
        names = []
        for klass in cls.__mro__:
            if "__init__" in vars(klass):
                sig = inspect.signature(vars(klass)["__init__"])
                names += [
                    p.name
                    for p in sig.parameters.values()
                    if p.kind is p.KEYWORD_ONLY and p.name not in names
                ]
        return tuple(names)
