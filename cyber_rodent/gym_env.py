"""Gymnasium environments of the Cyber Rodent: one robot, a flat observation, a scalar reward.

``import cyber_rodent`` registers four ids (entry-point strings, so registering imports nothing
heavy); each builds a :class:`CyberRodentEnv`::

    import gymnasium as gym
    import cyber_rodent  # noqa: F401  (registers the ids)

    env = gym.make("CyberRodent/Forage-v0", action="discrete", reward="shaped")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

The dm-control tasks (:mod:`cyber_rodent.tasks`) return per-robot arrays and take dict actions;
these environments give learners such as Stable-Baselines3 what they consume. Like the behaviour
episodes (``behaviours.episodes``, where the shipped behaviours were trained), they step a
:class:`~cyber_rodent.survival.SurvivalWorld` one control step (``control_dt``, 0.2 s) at a time
on its lean path, with the geometric vision by default.

Tasks: each environment runs the spec of its task (:mod:`cyber_rodent.tasks.spec`, the one
definition the dm-control tasks and the behaviour episodes read too; its ``gym`` variant, which
for Survival is one robot alone) through the episode loop every interface shares
(:class:`~cyber_rodent.tasks.episode.TaskEpisode`: reset and start draws, step, termination,
reward terms, observation), and nothing here depends on a task's name. A task added to the
registry is an environment at once (``CyberRodentEnv(name)``). The built-in ones:

* ``CyberRodent/Forage-v0``: 1 robot, 5 packs; the start is re-drawn until the robot sees a
  pack. Terminates with success when the robot docks onto a pack.
* ``CyberRodent/Mate-v0``: 2 robots, no packs, both LEDs on, both signalling Mate; the start is
  re-drawn until each sees the other's LED or face. Terminates with success at the first IR
  exchange. The learner is robot 0; robot 1, the partner, is moved by ``partner_policy``.
* ``CyberRodent/Search-v0``: 4 robots (3 parked: wheels stopped, LEDs off), 5 packs; any start.
  Never terminates; a docking is released at once (recharging is not Search's job).
* ``CyberRodent/Survival-v0``: 1 robot, 5 packs and the survival world's rules (energy 100,
  capped at 200, −1 per step, +5 per recharge step, at most 40 steps per docking, the rotation
  reflex after it). Terminates when the energy reaches 0 (death).

Forage, Mate and Search use the behaviour episodes' rules (:func:`~cyber_rodent.tasks.rewards.
episode_rules`: endless energy, 1e6, so no robot dies; a learner's death would end the episode,
as the spec's ``death`` says) and are truncated after ``episode.max_steps`` (the spec's episode
length, 100) control steps; Survival after 400 (one agent lifetime of the paper's simulation, as
the dm-control ``Survival`` task).

**The Mate partner.** The behaviours train Mate by self-play: both robots are learners acting on
their own inputs with one shared action-value table (``behaviours.training``). Here robot 1 acts
through ``partner_policy``, a callable that receives robot 1's own observation (the same layout
as the learner's) and returns an action of this environment's action space; pass the policy
being trained (for example ``lambda obs: model.predict(obs)[0]``) to train as the behaviours
were. Without one the partner stands still, LED on, signalling Mate.

Observation: ``Box((21,), float32)``, normalised by default (``observation="normalised"``):
every entry mapped linearly by its bounds into [0, 1], the bearings into [−1, 1] (0 straight
ahead); ``observation="raw"`` gives the same entries in physical units. Names in
``env.unwrapped.observation_names``, raw units in ``observation_units``, raw bounds in
``observation_bounds``, the normalisation in ``observation_scale``; the one table of them is
:mod:`cyber_rodent.observations`:

=======================================  =====================  ================================
name                                     raw                    normalised
=======================================  =====================  ================================
``range_front``                          [0, 1.0] m, IR range   proximity ``1 − range / 1.0``
``range_front_left30``, ``..._right30``  [0, 0.3] m             proximity ``1 − range / 0.3``
``range_front_left60``, ``..._right60``  [0, 0.3] m             as above
``range_back``, ``range_left``,          [0, 0.3] m             as above
``range_right``
``led_bearing``                          [−π, π] rad, + left;   ``bearing / π`` in [−1, 1]
                                         0 unseen
``led_distance``                         [0, max_range] m;      ``distance / max_range``
                                         max_range (3.25)
                                         unseen
``led_visible``                          {0, 1} flag            as is
``face_bearing`` / ``_distance`` /       as the LED's           as the LED's (nearest red face)
``_visible``
``battery_bearing`` / ``_distance`` /    as the LED's           as the LED's (nearest pack)
``_visible``
``energy``                               [0, max_energy]        ``energy / max_energy``: 0.5 at
                                         (200; 1e6 in Forage,   birth in Survival; 1 (full) in
                                         Mate, Search)          Forage, Mate and Search
``led_on``                               {0, 1} own LED         as is
``docked``                               {0, 1} recharging      as is
``recharge_steps``                       [0, 40] control steps  ``recharge_steps / 40``
=======================================  =====================  ================================

The range sensors are the robot's (``RobotModel.range_sensors``) in that order; the nearest LED,
face and pack are the vision's (``camera.max_range`` is the field's diagonal by default).

Actions:

* ``action="discrete"``: ``Discrete(8)``, an index into the behaviours' command table
  (:data:`cyber_rodent.commands.WHEEL_COMMANDS`: forward, forward_slow, arc_left, arc_right,
  spin_left, spin_right, reverse, stop). Survival: ``MultiDiscrete([8, 2])``, the command and
  the recharge decision (1 = keep recharging while docked, 0 = stop now).
* ``action="continuous"``: ``Box((2,), float32)``, left and right wheel rim speeds in m/s within
  ±``max_wheel_speed`` (default 1.0 m/s, inside the motor limit, the robot's ``top_speed`` = 1.3;
  the fastest command drives 0.5). Survival adds the recharge decision in [−1, 1] (keep
  recharging above 0), so the whole action lies in [−1, 1] as Gymnasium's and
  Stable-Baselines3's checkers recommend. ``env.unwrapped.action_names`` names the entries.

Rewards (a float per step, robot 0's; the sum of the spec's named terms,
:mod:`cyber_rodent.tasks.rewards`):

* ``reward="sparse"`` (default): the task's success as a reward. Forage: 1 at the docking; Mate:
  1 at the IR exchange (term ``success``); Search: 1 each time the robot's centre enters a 10 cm
  cell of the field it has not visited in this episode (``new_cell``, the area-covered measure
  of the behaviour evaluation, :func:`~cyber_rodent.tasks.rewards.coverage_cells`); Survival: 1
  per captured battery (``capture``; and ``mating``, which one robot alone never earns).
* ``reward="shaped"`` (Forage, Mate, Search): exactly the reward the behaviours were trained
  with (the terms ``behaviours.episodes`` sums, with the settings of ``episode``, an
  :class:`~cyber_rodent.tasks.rewards.EpisodeConfig`): distance shaping, step cost and goal
  reward for Forage and Mate (``shaping``, ``step_cost``, ``goal``), forward progress minus a
  collision penalty (3) for Search (``progress``, ``collision``). With the default settings,
  geometric vision and the same placement, it equals ``BehaviourEpisode``'s reward of robot 0
  step by step (``tests/test_gym_env.py``). Survival has no training reward and refuses it.

Pixels: ``pixels=True`` makes the observation a ``Dict`` with ``"state"`` (the vector above,
normalised or raw) and ``"pixels"``, robot 0's omni strip as the camera renders it (``Box(0,
255, (height, n_views · view_width, 3), uint8)``, 192 × 512 by default;
:mod:`cyber_rodent.vision.rendering`); ``masks=True`` adds ``"masks"``, its colour segmentation
(same shape, channel c is 255 on the pixels of class c: LED, face, battery;
:mod:`cyber_rodent.vision.segmentation`). Images stay ``uint8`` in [0, 255] in either kind:
image learners (Stable-Baselines3's ``CnnPolicy``, ``MultiInputPolicy``) recognise an image by
that type and scale it to [0, 1] themselves. The state part still comes from ``vision``
(geometric by default), so pixels never change the dynamics or the reward.

``info`` holds ``steps`` (control steps so far) and, after a step, ``collided`` (robot 0's body
touches a wall, a pack or a robot), the task's measure (the spec's ``measure``): ``is_success``
(Forage, Mate), ``coverage_cells`` (Search: cells visited) or ``captures`` (Survival: batteries
captured so far), and ``reward_terms``, each term of the step's reward by name (they sum to the
reward, in this order).

Rendering: ``render_mode="rgb_array"`` returns the top-down view of the field
(:class:`cyber_rodent.render.FieldRenderer`, off-screen MuJoCo).

Options: a :class:`GymConfig` (``CyberRodentEnv(config=GymConfig(...))``), or its fields as
keywords (``CyberRodentEnv("forage", action="continuous")``, and ``gymnasium.make``'s kwargs);
what the PettingZoo colony shares with these environments (its options' base
:class:`~cyber_rodent.rl_env.EnvConfig`, actions, render, close) is :mod:`cyber_rodent.rl_env`.

Seeding: ``reset(seed=...)`` seeds ``env.np_random``, the one generator of the placement, the
start re-draws and the rotation reflexes (vision noise, if configured, draws from a child of it);
the same seed and actions give the same trajectory, bit for bit.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from cyber_rodent.observations import (
    N_OBSERVATIONS,
    OBSERVATION_KINDS,
    OBSERVATION_NAMES,
    OBSERVATION_UNITS,
    ObservationBounds,
    nearest_frame,
    observation_bounds,
    robot_observations,
)
from cyber_rodent.rl_env import (
    ACTION_KINDS,
    DEFAULT_MAX_WHEEL_SPEED,
    SWITCH_ON,
    EnvConfig,
    FieldEnv,
    action_names,
    action_space,
    check_max_wheel_speed,
    decode_action,
)
from cyber_rodent.tasks.episode import EpisodeOptions, TaskEpisode, task_rules
from cyber_rodent.tasks.rewards import EpisodeConfig, RewardScales
from cyber_rodent.tasks.spec import BUILT_IN, SURVIVAL, TaskSpec, task_names, task_spec
from cyber_rodent.validation import boolean, choice
from cyber_rodent.vision import VisionFrame, VisionNoise

if TYPE_CHECKING:
    from cyber_rodent.vision.rendered import RenderedVision

#: The built-in tasks' names, in registry order (``tasks.spec.task_names()`` lists every
#: registered task; each is an environment).
TASK_NAMES = BUILT_IN
REWARD_KINDS = ("sparse", "shaped")
#: Control steps of a Survival episode (one agent lifetime of the paper's simulation).
SURVIVAL_STEPS = SURVIVAL.episode_steps

Observation = np.ndarray | dict[str, np.ndarray]
PartnerPolicy = Callable[[Observation], Any]


@dataclass(frozen=True)
class GymConfig(EnvConfig):
    """The options of a :class:`CyberRodentEnv`: those of :class:`~cyber_rodent.rl_env.
    EnvConfig` and these.

    Attributes:
        task: a registered task (:func:`~cyber_rodent.tasks.spec.task_names`; the spec's
            ``gym`` variant runs).
        reward: ``"sparse"`` (the task's success) or ``"shaped"`` (the behaviours' training
            reward; not for Survival).
        pixels: add robot 0's omni strip to the observation (a ``Dict`` observation).
        masks: also add the strip's colour-segmentation masks (needs ``pixels``).
        episode: length, start draws and shaped-reward settings (None: ``EpisodeConfig()`` with
            the task's episode length, ``max_steps=400`` for Survival).
        partner_policy: a task of two learners only (Mate): robot 1's policy, from its
            observation to an action of the environment's action space (None: it stands
            still).

    Raises:
        ValueError: one line naming the first invalid field and what it allows.
    """

    task: str = choice("forage", task_names)
    reward: str = choice("sparse", REWARD_KINDS)
    pixels: bool = boolean(False)
    masks: bool = boolean(False)
    episode: EpisodeConfig | None = None
    partner_policy: PartnerPolicy | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.masks and not self.pixels:
            raise ValueError("masks=True needs pixels=True (the masks segment the pixels)")
        if self.episode is not None and not isinstance(self.episode, EpisodeConfig):
            raise ValueError(
                f"episode must be an EpisodeConfig, got {type(self.episode).__name__}"
            )


def _listed(names: list[str]) -> str:
    """``"A"``, ``"A and B"``, ``"A, B and C"``."""
    return " and ".join([", ".join(names[:-1]), names[-1]] if len(names) > 1 else names)


class CyberRodentEnv(FieldEnv, gym.Env[Observation, Any]):
    """One Cyber Rodent task as a Gymnasium environment (see the module docstring).

    Args:
        task: ``"forage"``, ``"mate"``, ``"search"``, ``"survival"`` or another registered
            task (:mod:`cyber_rodent.tasks.spec`; the spec's ``gym`` variant runs); overrides
            ``config.task``.
        config: the options (:class:`GymConfig`; default: its defaults).
        **options: any field of :class:`GymConfig` by name, over ``config``: ``action``
            (``"discrete"`` or ``"continuous"``), ``reward`` (``"sparse"`` or ``"shaped"``),
            ``observation`` (``"normalised"`` or ``"raw"``), ``pixels``, ``masks``, ``vision``
            (``"geometric"``, as in training, or ``"rendered"``), ``camera`` (vision and
            pixels), ``survival`` (the rules; Forage, Mate and Search replace the energy fields
            by endless energy, as the behaviour episodes do), ``episode``, ``partner_policy``,
            ``max_wheel_speed``, ``render_mode``, ``render_width``, ``render_height``,
            ``backend``, ``robot`` (the body: ``cyber_rodent.robot.ROBOTS``).

    Attributes:
        config: the options.
        task_spec: the task's spec (:class:`~cyber_rodent.tasks.spec.TaskSpec`), its ``gym``
            variant.
        task_episode: the task's episode loop (:class:`~cyber_rodent.tasks.episode.
            TaskEpisode`).
        episode: the episode settings (:class:`~cyber_rodent.tasks.rewards.EpisodeConfig`).
        observation_kind: ``"normalised"`` or ``"raw"``.
        observation_names: the names of the state vector's entries.
        observation_units: the units of their raw values.
        observation_bounds: the raw values' bounds (:class:`ObservationBounds`).
        observation_scale: the normalisation (:class:`~cyber_rodent.observations.
            ObservationScale`; ``observation_scale.raw(obs)`` turns a normalised state back
            into physical units).
        action_names: the names of an action's entries.
        world, survival, vision: the simulation objects.
        steps: control steps of the current episode.

    Raises:
        ValueError: for an unknown or invalid option (the message names it).
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 5}

    def __init__(
        self, task: str | None = None, config: GymConfig | None = None, **options: Any
    ) -> None:
        if task is not None:
            options["task"] = task
        config = config or GymConfig()
        if options:
            config = dataclasses.replace(config, **options)
        spec = task_spec(config.task).gym
        self.task_spec: TaskSpec = spec
        self.task = spec.name
        self.reward_kind = config.reward
        registered = [task_spec(name) for name in task_names()]
        if not spec.rewards(config.reward):
            offering = [other.title for other in registered if other.shaped]
            raise ValueError(
                f"reward='shaped' is the behaviours' training reward of "
                f"{_listed(offering)}; {spec.title} has none (use reward='sparse')"
            )
        # Robots that act: robot 0, and robot 1 (the partner) in a task of two learners.
        self.n_learners = spec.n_learners(spec.field.robots)
        partner_policy = config.partner_policy
        if partner_policy is not None and (self.n_learners < 2 or not callable(partner_policy)):
            partnered = [
                other.title
                for other in registered
                if other.gym.n_learners(other.gym.field.robots) >= 2
            ]
            raise ValueError(
                f"partner_policy must be a callable, and only {_listed(partnered)} "
                f"{'has' if len(partnered) == 1 else 'have'} a partner"
            )
        episode = config.episode or EpisodeConfig(max_steps=spec.episode_steps)
        self.episode = episode
        self.partner_policy = partner_policy
        rules = task_rules(spec, config.survival)
        self._build_field(config, spec.field, rules)
        self._pixels: RenderedVision | None = None
        self._own_pixels = False
        if config.pixels:
            self._pixels, self._own_pixels = self._pixel_source()
        self._masks = config.masks

        # Robot 0's reward, term by term; the episode loop of the task.
        shaped = config.reward == "shaped"
        self.task_episode = TaskEpisode(
            spec,
            self.survival,
            self._nearest,
            EpisodeOptions(
                reward=config.reward,
                scales=RewardScales.from_episode(episode) if shaped else RewardScales(),
                rewarded=1,
                episode_steps=episode.max_steps,
                max_start_draws=episode.max_start_draws,
                collisions=True,
                track_cells=spec.measure == "coverage_cells",
                max_range=self.max_range,
            ),
        )
        self.rewards = self.task_episode.rewards
        self._wheels = self.task_episode.wheels
        switches = spec.switches
        self._switches = np.zeros(len(switches), dtype=bool)
        self.action_space = action_space(self.action_kind, switches, self.max_wheel_speed)
        self.action_names = action_names(self.action_kind, switches)
        state_space = self.observation_limits.space(self.observation_kind)
        if config.pixels:
            shape = (self.camera.height, self.camera.strip_width, 3)
            image = {"pixels": spaces.Box(0, 255, shape, dtype=np.uint8)}
            if config.masks:
                image["masks"] = spaces.Box(0, 255, shape, dtype=np.uint8)
            self.observation_space: spaces.Space[Any] = spaces.Dict(
                {"state": state_space, **image}
            )
        else:
            self.observation_space = state_space
        n_robots = spec.field.robots
        self._states = np.zeros((n_robots, len(self.observation_names)), dtype=np.float32)
        self._started = False

    @property
    def steps(self) -> int:
        """Control steps of the current episode."""
        return self.task_episode.steps

    # --- gymnasium API ---------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]:
        """Start an episode from a placement drawn with ``np_random`` (seeded by ``seed``).

        Raises:
            RuntimeError: no placement met the task's start condition in
                ``episode.max_start_draws`` draws.
        """
        super().reset(seed=seed)
        rng = self.np_random
        self._reseed_vision(rng)
        self.task_episode.reset(rng)
        self._started = True
        self._look()
        info = {"steps": 0}
        return self._observation(0), info

    def step(self, action: Any) -> tuple[Observation, SupportsFloat, bool, bool, dict[str, Any]]:
        """One control step with robot 0's ``action`` (and the partner's, in Mate)."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        self._act(0, action, self.action_space, self._switches)
        if self.partner_policy is not None:
            partner = self.partner_policy(self._observation(1))
            self._act(1, partner, self.action_space, self._switches)
        step = self.task_episode.step()
        self._look()
        reward = float(step.reward[0])
        return self._observation(0), reward, step.terminated, step.truncated, step.info()

    # --- internals -------------------------------------------------------------------------------
    def _nearest(self) -> VisionFrame:
        """What the robots see, as the episode loop looks (the module's :func:`nearest_frame`,
        looked up at each call: ``benchmarks/rl_throughput.py --before-after`` swaps it)."""
        return nearest_frame(self.vision)

    def _pixel_source(self) -> tuple[RenderedVision, bool]:
        """The renderer of the omni strips: the vision itself if it renders, else its own one."""
        from cyber_rodent.vision.rendered import RenderedVision  # needs OpenGL: import lazily

        if isinstance(self.vision, RenderedVision):
            return self.vision, False
        camera = dataclasses.replace(self.camera, noise=VisionNoise())  # images only
        return RenderedVision(self.world, camera, backend=self.config.backend), True

    def _release(self) -> None:
        if self._pixels is not None and self._own_pixels:
            self._pixels.close()
        self._pixels = None

    def _look(self) -> None:
        """Every robot's state vector, and the strips if the observation has pixels."""
        self._states = self._observe()
        if self._pixels is not None and self._pixels is not self.vision:
            self._pixels.observe()

    def _observation(self, robot: int) -> Observation:
        state: np.ndarray = self._states[robot].copy()
        if self._pixels is None:
            return state
        strips, classes = self._pixels.last_strips, self._pixels.last_classes
        assert strips is not None and classes is not None  # rendered by _look
        obs = {"state": state, "pixels": strips[robot].copy()}
        if self._masks:
            masks = self._pixels.segmenter.masks_from_classes(classes[robot])
            obs["masks"] = np.moveaxis(masks, 0, -1).copy()
        return obs


__all__ = [
    "ACTION_KINDS",
    "DEFAULT_MAX_WHEEL_SPEED",
    "N_OBSERVATIONS",
    "OBSERVATION_KINDS",
    "OBSERVATION_NAMES",
    "OBSERVATION_UNITS",
    "REWARD_KINDS",
    "SURVIVAL_STEPS",
    "SWITCH_ON",
    "TASK_NAMES",
    "CyberRodentEnv",
    "GymConfig",
    "Observation",
    "ObservationBounds",
    "PartnerPolicy",
    "action_names",
    "action_space",
    "check_max_wheel_speed",
    "decode_action",
    "observation_bounds",
    "robot_observations",
]
