"""The Cyber Rodent tasks in dm-control: one task class, driven by the task's spec.

A task owns one :class:`~cyber_rodent.survival.SurvivalWorld` (the same object the evolution
runner steps on its lean path) and its :class:`~cyber_rodent.tasks.episode.TaskEpisode`, the
episode loop every interface shares, and drives them from dm-control: :meth:`before_step` turns
the action into the episode's commands (``TaskEpisode.begin``), dm-control advances the physics
by the world's substeps (``mj_step``, no legacy split step, so the trajectory is the lean
path's), and :meth:`after_step` ends the step (``TaskEpisode.end``: the mechanics, the vision
provider once, success, termination, reward).

What makes a task that task (field, start condition, termination, rewards, the robots'
switches, episode length) is its :class:`~cyber_rodent.tasks.spec.TaskSpec`;
:class:`CyberRodentTask` reads it and nothing else, so a registered spec is a task.

Multi-robot convention, the same in every task: a task *controls* ``k`` robots, its learners
(robots ``0..k-1``; the others, if any, are parked obstacles with wheels stopped and LEDs off).
Every observation and action array has a leading axis of length ``k``, and the reward is a
``(k,)`` array, one per controlled robot. Forage and Search control one robot (``k = 1``), Mate
two, Survival all of them. One shape rule for all tasks lets a learner treat "one robot" and
"two robots running the same behaviour" alike.

Observations (per controlled robot; raw physical units, bounds in the specs): the entries of
the one observation table, :mod:`cyber_rodent.observations`, in float64 and grouped by name
(:data:`~cyber_rodent.observations.OBSERVATION_GROUPS`):

==================  =========  ===============================================================
name                shape      meaning
==================  =========  ===============================================================
``range``           (k, 8)     IR range readings, m, in the order of the robot's range sensors
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

Actions are a dict: ``wheels`` (k, 2) wheel rim speeds in m/s within the motor limit, ± the
robot's top speed, and ``led`` (k,) in [0, 1] (on above 0.5; the spec's LED is the start
state).
A task whose learners decide their Mate signal or their recharge decision (the spec's ``mate``
or ``recharge`` is None: Survival) adds ``mate`` (k,) in [0, 1] (above 0.5 the robot's agent
runs Mate, willing to exchange) and ``recharge`` (k,) in [0, 1] (while docked, above 0.5
continues recharging, otherwise recharging stops this step). The discrete command set that
behaviours choose from is :mod:`cyber_rodent.commands`.

Reward: the spec's ``control_reward`` (``"sparse"``, or ``"shaped"`` for Search), one entry per
controlled robot; the fields of :class:`~cyber_rodent.tasks.rewards.RewardScales` its terms read
are options of the task, defaulting to the spec's ``control_scales`` (Search:
``reference_speed`` 0.5, ``collision_penalty`` 1; Survival: ``dock_reward`` and ``mate_reward``
1). A task with a start condition takes ``start_in_view`` (default True; False starts from any
placement).

Episode: ``episode_steps`` control steps (the spec's), cut with discount 1; it ends with discount
0 at the task's success (robot 0's goal) or at a death (:meth:`TaskSpec.dead`: any controlled
robot's, or Survival's every robot's). The dm-control tasks run the survival rules they are
given (default: the paper's, energy included), whatever the spec's ``endless_energy``. A task
whose spec says ``release_docking`` (Search) releases a learner's docking at the end of the
step in which it docked, without the reflex, as the Gymnasium environments and the behaviours'
episodes do (:mod:`cyber_rodent.tasks.episode`; before the episode loop was shared, a Search
robot that docked here stopped recharging on the next step, with the reflex).
"""

from __future__ import annotations

import dataclasses
from collections import OrderedDict
from typing import Any, ClassVar

import numpy as np
from dm_control.mjcf import Physics
from dm_control.rl import control
from dm_env import specs

from cyber_rodent.observations import OBSERVATION_GROUPS, ObservationLimits, observation_table
from cyber_rodent.survival import StepEvents, SurvivalConfig, SurvivalWorld
from cyber_rodent.tasks.episode import EpisodeOptions, TaskEpisode
from cyber_rodent.tasks.spec import TaskSpec
from cyber_rodent.vision import CameraConfig, VisionFrame, make_provider
from cyber_rodent.world import World, WorldConfig

#: The Cyber Rodent's observation names in a stable order (also the order of a flattened
#: observation); another robot's: its table's groups (``observations.observation_table``).
OBSERVATION_NAMES = tuple(name for name, _ in OBSERVATION_GROUPS)
#: Threshold of the [0, 1] switch actions (``led``, ``mate``, ``recharge``): on above it.
SWITCH_ON = 0.5
#: Options of every task (``tasks.load(name, **options)``).
BASE_OPTIONS = (
    "n_robots",
    "n_packs",
    "episode_steps",
    "survival",
    "vision",
    "camera",
    "timestep",
    "robot",
)
#: Placements drawn for a start condition before giving up.
START_ATTEMPTS = 200


class CyberRodentTask(control.Task):  # type: ignore[misc]  # dm_control has no type hints
    """A task of its :attr:`task_spec`: field, start, termination, reward and switches.

    The class of a registered task is :func:`cyber_rodent.tasks.task_class`'s subclass with its
    spec set; :func:`cyber_rodent.tasks.load` builds it.

    Args:
        rng: the task's generator (placement, reflexes, start conditions, vision noise).
        n_robots: robots in the field (default: the spec's).
        n_packs: battery packs in the field (default: the spec's).
        episode_steps: control steps per episode (default: the spec's); the episode is cut
            there with discount 1.
        survival: the survival rules (energy, docking, mating).
        vision: vision provider, ``"geometric"`` (default) or ``"rendered"``.
        camera: the camera config shared by both providers.
        timestep: physics timestep, s (default: ``WorldConfig``'s).
        robot: the robots' kind (``WorldConfig.robot``; default the Cyber Rodent): its sensor
            table gives the observation, its top speed the wheels' bounds.
        **options: ``start_in_view`` (tasks with a start condition: re-draw the initial
            placement until the condition holds; default True) and the reward's scales
            (:meth:`TaskSpec.reward_options`), e.g. ``collision_penalty`` for Search,
            ``dock_reward`` for Survival.

    Raises:
        ValueError: for an unknown or invalid option (the message names it and its allowed
            range).
    """

    #: The task's spec (set by :func:`cyber_rodent.tasks.task_class`).
    task_spec: ClassVar[TaskSpec]

    def __init__(
        self,
        rng: np.random.Generator,
        *,
        n_robots: int | None = None,
        n_packs: int | None = None,
        episode_steps: int | None = None,
        survival: SurvivalConfig | None = None,
        vision: str = "geometric",
        camera: CameraConfig | None = None,
        timestep: float | None = None,
        robot: str = "cyber_rodent",
        **options: Any,
    ):
        spec = self.task_spec
        unknown = sorted(set(options) - set(self.option_names()))
        if unknown:
            raise ValueError(
                f"unknown option(s) {unknown} for task {spec.name!r}; allowed options: "
                f"{', '.join(self.option_names())}"
            )
        n_robots = spec.field.robots if n_robots is None else n_robots
        n_packs = spec.field.packs if n_packs is None else n_packs
        episode_steps = spec.episode_steps if episode_steps is None else episode_steps
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
        self.start_in_view = spec.start is not None and bool(options.pop("start_in_view", True))
        self.scales = dataclasses.replace(spec.control_scales, **options)
        self.episode_steps = int(episode_steps)
        self._rng = rng
        world_cfg = WorldConfig(n_robots=n_robots, n_packs=n_packs, robot=robot)
        if timestep is not None:
            world_cfg = dataclasses.replace(world_cfg, timestep=timestep)
        start = spec.start
        if self.start_in_view and start is not None and n_packs < start.min_packs:
            raise ValueError(
                f"n_packs must be >= {start.min_packs} for {spec.title} with start_in_view=True"
            )
        world = World(world_cfg, rng)
        self.survival = SurvivalWorld(world, survival, rng)
        self.world = world
        self._table = observation_table(world.robot.sensors)
        self._groups = self._table.groups
        # The provider gets its own stream, so its noise never shifts the placement draws.
        self.vision = make_provider(vision, world, camera, rng.spawn(1)[0])
        self.camera = self.vision.config
        self.max_range = float(self.camera.max_range)
        # The action sets every learner's LED, and the switches the spec leaves open.
        switches = ("led", *(name for name in spec.switches if name != "led"))
        self.episode = TaskEpisode(
            spec,
            self.survival,
            self.vision.observe,
            EpisodeOptions(
                reward=spec.control_reward,
                scales=self.scales,
                switches=switches,
                episode_steps=self.episode_steps,
                start=self.start_in_view,
                max_start_draws=START_ATTEMPTS,
                max_range=self.max_range,
            ),
        )
        self.k = self.episode.k
        self.rewards = self.episode.rewards
        self._reward = np.zeros(self.k)
        self.success = False
        self._terminated = False
        self.last_events: StepEvents = self.survival.events
        self._action_spec = self._make_action_spec()
        self._observation_spec = self._make_observation_spec()

    @property
    def name(self) -> str:
        """The task's name (:func:`cyber_rodent.tasks.load`)."""
        return self.task_spec.name

    # --- specs -------------------------------------------------------------------------------
    @property
    def physics(self) -> Physics:
        """The dm-control ``Physics`` of the world (its MjModel/MjData are the world's)."""
        return self.world.physics

    def _make_action_spec(self) -> OrderedDict[str, specs.BoundedArray]:
        k = self.k
        spec = OrderedDict()
        top = self.world.robot.top_speed
        spec["wheels"] = specs.BoundedArray((k, 2), np.float64, -top, top, name="wheels")
        spec["led"] = specs.BoundedArray((k,), np.float64, 0.0, 1.0, name="led")
        for switch in self.task_spec.switches:
            if switch != "led":
                spec[switch] = specs.BoundedArray((k,), np.float64, 0.0, 1.0, name=switch)
        return spec

    def _make_observation_spec(self) -> OrderedDict[str, specs.BoundedArray]:
        """The bounds of the observation table's entries, grouped as the observation."""
        k = self.k
        limits = ObservationLimits.of(
            self.world.range_max[0], self.max_range, self.survival.config, self._table
        )
        low, high = limits.intervals()
        spec = OrderedDict()
        for name, columns in self._table.groups:
            shape = (k,) if isinstance(columns, int) else (k, columns.stop - columns.start)
            spec[name] = specs.BoundedArray(
                shape, np.float64, _bound(low[columns], k), _bound(high[columns], k), name=name
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
    @property
    def frame(self) -> VisionFrame | None:
        """What every robot saw at the end of the last step (or at the episode's start)."""
        return self.episode.frame

    def initialize_episode(self, physics: Physics) -> None:
        """New placement and newborn energies, re-drawn until the start condition holds."""
        self.episode.reset(self._rng)
        self.success = self._terminated = False

    def before_step(self, action: Any, physics: Physics | None = None) -> None:
        """Validate the action and hand the commands to the world (``TaskEpisode.begin``)."""
        self._read_action(action)
        self.episode.begin()

    def after_step(self, physics: Physics | None = None) -> None:
        """Energy, docking, mating, what every robot sees, the termination and the reward
        (``TaskEpisode.end``)."""
        step = self.episode.end()
        self.last_events = step.events
        self.success = step.success
        self._terminated = step.terminated
        self._reward = step.reward

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
        episode = self.episode
        episode.wheels[:k] = values["wheels"]
        episode.wheels[k:] = 0.0
        for name, target in zip(episode.switches, episode.action_switches, strict=True):
            np.greater(values[name], SWITCH_ON, out=target[:k])
            target[k:] = False

    # --- observations --------------------------------------------------------------------------
    def get_observation(self, physics: Physics | None = None) -> OrderedDict[str, np.ndarray]:
        """The controlled robots' entries of the observation table, grouped by name."""
        table = self.episode.observations(np.float64)[: self.k]
        return OrderedDict((name, table[:, columns].copy()) for name, columns in self._groups)

    # --- reward and termination ---------------------------------------------------------------
    def get_reward(self, physics: Physics | None = None) -> np.ndarray:
        """The step's reward, one per controlled robot (the spec's ``control_reward``)."""
        return self._reward

    def get_termination(self, physics: Physics | None = None) -> float | None:
        """Discount 0 at the task's success or at a death that ends it, else continue."""
        return 0.0 if self._terminated else None

    @classmethod
    def option_names(cls) -> tuple[str, ...]:
        """The keyword options the task accepts (for :func:`cyber_rodent.tasks.load`)."""
        spec = cls.task_spec
        start = ("start_in_view",) if spec.start is not None else ()
        return (*BASE_OPTIONS, *start, *spec.reward_options(spec.control_reward))


def _bound(values: np.ndarray, k: int) -> float | np.ndarray:
    """A spec's bound of ``k`` robots: one number where the group's entries share it, else the
    entries' bounds for each robot."""
    if values.ndim == 0 or (values == values[0]).all():
        return float(values.flat[0])
    return np.tile(values, (k, 1))


def task_class(spec: TaskSpec) -> type[CyberRodentTask]:
    """The dm-control task class of ``spec`` (one class per spec, made on first use)."""
    cls = _CLASSES.get(spec)
    if cls is None:
        cls = type(
            spec.title,
            (CyberRodentTask,),
            {"task_spec": spec, "__doc__": f"The {spec.name} task: {spec.summary}."},
        )
        _CLASSES[spec] = cls
    return cls


_CLASSES: dict[TaskSpec, type[CyberRodentTask]] = {}
