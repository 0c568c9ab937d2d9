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
for Survival is one robot alone), and nothing here depends on a task's name. A task added to
the registry is an environment at once (``CyberRodentEnv(name)``). The built-in ones:

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

The range sensors are those of ``constants.RANGE_SENSORS`` in that order; the nearest LED, face
and pack are the vision's (``camera.max_range`` is the field's diagonal by default).

Actions:

* ``action="discrete"``: ``Discrete(8)``, an index into the behaviours' command table
  (:data:`cyber_rodent.commands.WHEEL_COMMANDS`: forward, forward_slow, arc_left, arc_right,
  spin_left, spin_right, reverse, stop). Survival: ``MultiDiscrete([8, 2])``, the command and
  the recharge decision (1 = keep recharging while docked, 0 = stop now).
* ``action="continuous"``: ``Box((2,), float32)``, left and right wheel rim speeds in m/s within
  ±``max_wheel_speed`` (default 1.0 m/s, inside the motor limit ``constants.TOP_SPEED`` = 1.3;
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

Seeding: ``reset(seed=...)`` seeds ``env.np_random``, the one generator of the placement, the
start re-draws and the rotation reflexes (vision noise, if configured, draws from a child of it);
the same seed and actions give the same trajectory, bit for bit.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from cyber_rodent import constants as C
from cyber_rodent.backend import DEFAULT_BACKEND, Backend, check_backend
from cyber_rodent.commands import COMMAND_SPEEDS, N_COMMANDS
from cyber_rodent.observations import (
    N_OBSERVATIONS,
    OBSERVATION_KINDS,
    OBSERVATION_NAMES,
    OBSERVATION_UNITS,
    ObservationBounds,
    ObservationLimits,
    check_observation,
    nearest_frame,
    observation_bounds,
    robot_observations,
)
from cyber_rodent.render import FieldRenderer, check_image_size
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.tasks.rewards import (
    EpisodeConfig,
    RewardScales,
    TaskRewards,
    episode_rules,
    total_reward,
)
from cyber_rodent.tasks.spec import SURVIVAL, TaskSpec, task_names, task_spec
from cyber_rodent.validation import check_boolean, check_choice, check_number
from cyber_rodent.vision import (
    PROVIDER_NAMES,
    CameraConfig,
    VisionFrame,
    VisionNoise,
    VisionProvider,
    make_provider,
)
from cyber_rodent.world import World, WorldConfig

if TYPE_CHECKING:
    from cyber_rodent.vision.rendered import RenderedVision

#: The built-in tasks' names, in the order of the registered ids (a task registered later in
#: :mod:`cyber_rodent.tasks.spec` is offered too).
TASK_NAMES = ("forage", "mate", "search", "survival")
ACTION_KINDS = ("discrete", "continuous")
REWARD_KINDS = ("sparse", "shaped")
#: Control steps of a Survival episode (one agent lifetime of the paper's simulation).
SURVIVAL_STEPS = SURVIVAL.episode_steps
#: Default bound of the continuous wheel speeds, m/s.
DEFAULT_MAX_WHEEL_SPEED = 1.0
#: A switch entry of a continuous action, in [-1, 1], is on above this.
SWITCH_ON = 0.0

Observation = np.ndarray | dict[str, np.ndarray]
PartnerPolicy = Callable[[Observation], Any]


# --- actions -------------------------------------------------------------------------------------
def action_space(kind: str, switches: tuple[str, ...], max_wheel_speed: float) -> spaces.Space[Any]:
    """The action space of one robot: a wheel command, then on/off ``switches``.

    Discrete: ``Discrete(N_COMMANDS)`` without switches, else ``MultiDiscrete([N_COMMANDS, 2,
    ...])``. Continuous: ``Box`` of the two wheel speeds (m/s, ±``max_wheel_speed``), then one
    entry in [-1, 1] per switch (on above :data:`SWITCH_ON`).
    """
    if kind == "discrete":
        if not switches:
            return spaces.Discrete(N_COMMANDS)
        return spaces.MultiDiscrete([N_COMMANDS, *(2,) * len(switches)])
    low = np.array([-max_wheel_speed] * 2 + [-1.0] * len(switches), dtype=np.float32)
    high = np.array([max_wheel_speed] * 2 + [1.0] * len(switches), dtype=np.float32)
    return spaces.Box(low, high, dtype=np.float32)


def action_names(kind: str, switches: tuple[str, ...]) -> tuple[str, ...]:
    """Names of the entries of an action of :func:`action_space`."""
    wheels = ("command",) if kind == "discrete" else ("left_wheel", "right_wheel")
    return (*wheels, *switches)


def decode_action(
    action: Any, space: spaces.Space[Any], wheels: np.ndarray, switches: np.ndarray
) -> None:
    """Write an action of ``space`` (:func:`action_space`) as wheel speeds and switch states.

    Args:
        action: the action.
        space: its space.
        wheels: (2,) out: left and right wheel rim speeds, m/s.
        switches: (n_switches,) bool out.

    Raises:
        ValueError: the action is not in the space (the message says why).
    """
    if isinstance(space, spaces.Box):
        value = np.asarray(action, dtype=np.float32)
        if value.shape != space.shape:
            raise ValueError(f"action must have shape {space.shape}, got {value.shape}")
        if not np.isfinite(value).all():
            raise ValueError("action must be finite (got NaN or inf)")
        if (value < space.low).any() or (value > space.high).any():
            raise ValueError(
                f"action must lie in [{space.low.tolist()}, {space.high.tolist()}], "
                f"got {value.tolist()}"
            )
        wheels[:] = value[:2]
        np.greater(value[2:], SWITCH_ON, out=switches)
        return
    value = np.asarray(action)
    nvec = space.nvec if isinstance(space, spaces.MultiDiscrete) else np.array([N_COMMANDS])
    flat = value.reshape(-1)
    if value.dtype.kind not in "iu" or flat.shape != nvec.shape:
        raise ValueError(
            f"action must be {'an integer' if flat.size == 1 else 'integers'} of {space}, "
            f"got {action!r}"
        )
    if (flat < 0).any() or (flat >= nvec).any():
        raise ValueError(f"action must lie in {space}, got {action!r}")
    wheels[:] = COMMAND_SPEEDS[int(flat[0])]
    switches[:] = flat[1:] != 0


def check_max_wheel_speed(value: object) -> float:
    """A continuous action's wheel-speed bound, m/s, in (0, ``TOP_SPEED``]."""
    return check_number("max_wheel_speed", value, 0.0, C.TOP_SPEED, low_open=True)


def _listed(names: list[str]) -> str:
    """``"A"``, ``"A and B"``, ``"A, B and C"``."""
    return " and ".join([", ".join(names[:-1]), names[-1]] if len(names) > 1 else names)


class CyberRodentEnv(gym.Env[Observation, Any]):
    """One Cyber Rodent task as a Gymnasium environment (see the module docstring).

    Args:
        task: ``"forage"``, ``"mate"``, ``"search"``, ``"survival"`` or another registered
            task (:mod:`cyber_rodent.tasks.spec`; the spec's ``gym`` variant runs).
        action: ``"discrete"`` (the command table) or ``"continuous"`` (wheel speeds, m/s).
        reward: ``"sparse"`` (the task's success) or ``"shaped"`` (the behaviours' training
            reward; not for Survival).
        observation: ``"normalised"`` (the state in [0, 1], bearings in [−1, 1]) or ``"raw"``
            (physical units); :mod:`cyber_rodent.observations`.
        pixels: add robot 0's omni strip to the observation (a ``Dict`` observation).
        masks: also add the strip's colour-segmentation masks (needs ``pixels``).
        vision: provider of the state's nearest LED, face and pack, ``"geometric"`` (as in
            training) or ``"rendered"``.
        camera: the omni camera (vision and pixels); default :class:`CameraConfig`.
        survival: the survival rules (default: the paper's). Forage, Mate and Search replace
            the energy fields by endless energy, as the behaviour episodes do.
        episode: length, start draws and shaped-reward settings; default ``EpisodeConfig()``
            with the task's episode length (``max_steps=400`` for Survival).
        partner_policy: Mate only (a task with two learners): robot 1's policy, from its
            observation to an action of this environment's action space (None: it stands
            still).
        max_wheel_speed: bound of the continuous wheel speeds, m/s, in (0, 1.3].
        render_mode: None or ``"rgb_array"`` (top-down view).
        render_width, render_height: size of a rendered image, px.
        backend: ``"numba"`` or ``"numpy"`` kernels (the same trajectories).

    Attributes:
        task_spec: the task's spec (:class:`~cyber_rodent.tasks.spec.TaskSpec`), its ``gym``
            variant.
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
        self,
        task: str = "forage",
        *,
        action: str = "discrete",
        reward: str = "sparse",
        observation: str = "normalised",
        pixels: bool = False,
        masks: bool = False,
        vision: str = "geometric",
        camera: CameraConfig | None = None,
        survival: SurvivalConfig | None = None,
        episode: EpisodeConfig | None = None,
        partner_policy: PartnerPolicy | None = None,
        max_wheel_speed: float = DEFAULT_MAX_WHEEL_SPEED,
        render_mode: str | None = None,
        render_width: int = 480,
        render_height: int = 480,
        backend: Backend = DEFAULT_BACKEND,
    ) -> None:
        check_choice("task", task, task_names())
        spec = task_spec(task).gym
        self.task_spec: TaskSpec = spec
        self.task = spec.name
        self.action_kind = check_choice("action", action, ACTION_KINDS)
        self.reward_kind = check_choice("reward", reward, REWARD_KINDS)
        self.observation_kind = check_observation(observation)
        registered = [task_spec(name) for name in task_names()]
        if not spec.rewards(reward):
            offering = [other.title for other in registered if other.shaped]
            raise ValueError(
                f"reward='shaped' is the behaviours' training reward of "
                f"{_listed(offering)}; {spec.title} has none (use reward='sparse')"
            )
        check_boolean("pixels", pixels)
        check_boolean("masks", masks)
        if masks and not pixels:
            raise ValueError("masks=True needs pixels=True (the masks segment the pixels)")
        check_choice("vision", vision, PROVIDER_NAMES)
        if camera is not None and not isinstance(camera, CameraConfig):
            raise ValueError(f"camera must be a CameraConfig, got {type(camera).__name__}")
        if survival is not None and not isinstance(survival, SurvivalConfig):
            raise ValueError(f"survival must be a SurvivalConfig, got {type(survival).__name__}")
        if episode is not None and not isinstance(episode, EpisodeConfig):
            raise ValueError(f"episode must be an EpisodeConfig, got {type(episode).__name__}")
        n_robots, n_packs = spec.field.robots, spec.field.packs
        # Robots that act: robot 0, and robot 1 (the partner) in a task of two learners.
        self.n_learners = spec.n_learners(n_robots)
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
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        check_image_size(render_width, render_height)
        self._render_size = (render_width, render_height)
        self.max_wheel_speed = check_max_wheel_speed(max_wheel_speed)
        backend = check_backend(backend)
        if episode is None:
            episode = EpisodeConfig(max_steps=spec.episode_steps)
        self.episode = episode
        self.partner_policy = partner_policy
        rules = episode_rules(survival) if spec.endless_energy else (survival or SurvivalConfig())

        fixed = np.random.default_rng(0)  # construction only; every reset re-draws
        self.world = World(WorldConfig(n_robots=n_robots, n_packs=n_packs), fixed)
        self.survival = SurvivalWorld(self.world, rules, fixed, backend=backend)
        self.camera = camera or CameraConfig()
        self.vision: VisionProvider = make_provider(
            vision, self.world, self.camera, np.random.default_rng(0), backend=backend
        )
        self.max_range = float(self.camera.max_range)
        self._pixels: RenderedVision | None = None
        self._own_pixels = False
        if pixels:
            self._pixels, self._own_pixels = self._pixel_source(backend)
        self._masks = masks
        self.metadata = {**self.metadata, "render_fps": 1.0 / rules.control_dt}
        self.dt = rules.control_dt

        # Commands of every robot: the spec's switches; the learners' actions set the wheels
        # and the switches the spec leaves to them.
        switch_values = spec.switch_values(n_robots)
        self._wheels = np.zeros((n_robots, 2))
        self._led = switch_values["led"]
        self._mate = switch_values["mate"]
        self._recharge = switch_values["recharge"]
        switches = spec.switches
        self._switch_targets = tuple(switch_values[name] for name in switches)
        self._switches = np.zeros(len(switches), dtype=bool)
        self.action_space = action_space(self.action_kind, switches, self.max_wheel_speed)
        self.action_names = action_names(self.action_kind, switches)

        limits = ObservationLimits.of(self.world.range_max[0], self.max_range, rules)
        self.observation_names = OBSERVATION_NAMES
        self.observation_units = OBSERVATION_UNITS
        self.observation_bounds: ObservationBounds = limits.bounds()
        self.observation_scale = limits.scale()
        state_space = limits.space(self.observation_kind)
        if pixels:
            shape = (self.camera.height, self.camera.strip_width, 3)
            image = {"pixels": spaces.Box(0, 255, shape, dtype=np.uint8)}
            if masks:
                image["masks"] = spaces.Box(0, 255, shape, dtype=np.uint8)
            self.observation_space: spaces.Space[Any] = spaces.Dict(
                {"state": state_space, **image}
            )
        else:
            self.observation_space = state_space

        # Robot 0's reward, term by term.
        scales = RewardScales.from_episode(episode) if reward == "shaped" else RewardScales()
        self.rewards = TaskRewards(
            spec.rewards(reward),
            scales,
            self.survival,
            1,
            spec.target,
            track_cells=spec.measure == "coverage_cells",
        )
        self._collided = np.zeros(n_robots, dtype=bool)
        self._frame = VisionFrame.empty(n_robots)
        self._states = np.zeros((n_robots, N_OBSERVATIONS), dtype=np.float32)
        self._captures = 0
        self.steps = 0
        self._renderer: FieldRenderer | None = None
        self._started = False

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
        if self.camera.noise.enabled:
            self.vision.rng = rng.spawn(1)[0]
        start = self.task_spec.start
        for _ in range(self.episode.max_start_draws):
            self.survival.reset(rng)
            self.world.set_led(self._led)
            frame = nearest_frame(self.vision)
            if start is None or start.holds(frame):
                break
        else:
            raise RuntimeError(
                f"{self.task}: no start placement met the start condition in "
                f"{self.episode.max_start_draws} draws"
            )
        self._frame = frame
        self._wheels[:] = 0.0  # a robot no action moves stands still
        self.steps = 0
        self._captures = 0
        self._started = True
        self.rewards.reset(frame)
        self._look()
        info = {"steps": 0}
        return self._observation(0), info

    def step(self, action: Any) -> tuple[Observation, SupportsFloat, bool, bool, dict[str, Any]]:
        """One control step with robot 0's ``action`` (and the partner's, in Mate)."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        self._act(0, action)
        if self.partner_policy is not None:
            self._act(1, self.partner_policy(self._observation(1)))
        self.rewards.begin()
        events = self.survival.step(self._wheels, self._led, self._mate, self._recharge)
        self.steps += 1
        self._frame = nearest_frame(self.vision)
        self.survival.collisions(out=self._collided)
        spec = self.task_spec
        success = spec.reached(events)
        terminated = success or spec.dead(self.survival.alive, self.n_learners)
        if spec.release_docking:  # recharging is not the task's job
            for robot in range(self.n_learners):
                self.survival.end_recharge(robot, reflex=False)
        self._captures += bool(events.captured[0])
        terms = self.rewards.end(events, self._frame, success, self._collided)
        reward = float(total_reward(terms)[0])
        truncated = not terminated and self.steps >= self.episode.max_steps
        self._look()
        info: dict[str, Any] = {"steps": self.steps, "collided": bool(self._collided[0])}
        if spec.measure == "is_success":
            info["is_success"] = success
        elif spec.measure == "coverage_cells":
            info["coverage_cells"] = self.rewards.cells_visited[0]
        else:
            info["captures"] = self._captures
        info["reward_terms"] = {name: float(value[0]) for name, value in terms.items()}
        return self._observation(0), reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """The top-down view of the field, (render_height, render_width, 3) uint8."""
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            self._renderer = FieldRenderer(self.world, *self._render_size)
        return self._renderer.top_down()

    def close(self) -> None:
        """Free the OpenGL contexts (idempotent)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._pixels is not None and self._own_pixels:
            self._pixels.close()
        self._pixels = None
        close = getattr(self.vision, "close", None)
        if close is not None:  # the rendered provider's GL context
            close()

    # --- internals -------------------------------------------------------------------------------
    def _pixel_source(self, backend: Backend) -> tuple[RenderedVision, bool]:
        """The renderer of the omni strips: the vision itself if it renders, else its own one."""
        from cyber_rodent.vision.rendered import RenderedVision  # needs OpenGL: import lazily

        if isinstance(self.vision, RenderedVision):
            return self.vision, False
        camera = dataclasses.replace(self.camera, noise=VisionNoise())  # images only
        return RenderedVision(self.world, camera, backend=backend), True

    def _act(self, robot: int, action: Any) -> None:
        """Robot ``robot``'s action: its wheels, and the switches its action sets."""
        decode_action(action, self.action_space, self._wheels[robot], self._switches)
        for target, on in zip(self._switch_targets, self._switches, strict=True):
            target[robot] = on

    def _look(self) -> None:
        """Every robot's state vector, and the strips if the observation has pixels."""
        self._states = robot_observations(self.survival, self._frame, self.max_range)
        if self.observation_kind == "normalised":
            self._states = self.observation_scale.normalise(self._states)
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
