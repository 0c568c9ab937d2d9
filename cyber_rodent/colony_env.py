"""The Cyber Rodent colony as a PettingZoo ``ParallelEnv``: each robot an agent, survival live.

::

    from cyber_rodent.colony_env import parallel_env

    env = parallel_env(n_robots=4, action="discrete")
    observations, infos = env.reset(seed=0)
    while env.agents:
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)

The field is the paper's simulation (4 robots, 5 packs by default) stepped one control step
(``control_dt``, 0.2 s) at a time on the :class:`~cyber_rodent.survival.SurvivalWorld`'s lean
path, with every rule of the survival world (:mod:`cyber_rodent.survival`, the paper's by
default): each robot's energy starts at 100, is capped at 200 and drains 1 per step; a robot that
docks onto a pack (teeth on the electrodes, aligned) recharges +5 per step while its recharge
decision says continue, for at most 40 steps or until full, then turns away with the rotation
reflex; two robots that both signal Mate with their IR ports facing within ±15° at ≤ 0.35 m for 2
consecutive steps exchange (an IR mating). Energy 0 is death.

Agents are ``robot_0`` … ``robot_{n-1}`` (``possible_agents``). A robot whose energy reaches 0
gets ``terminations[agent] = True`` on that step and leaves ``agents``; its body stays in the
field, wheels stopped and LED dark (an obstacle, as in the survival world). Every agent is
truncated after ``max_cycles`` control steps (default 400, one agent lifetime of the paper).

Observation (per agent): the flat ``Box((21,), float32)`` of the Gymnasium environments, same
names, order, units, bounds and normalisation (:mod:`cyber_rodent.observations`, the one table of
them): 8 IR ranges, the nearest green LED, red face and blue pack (bearing, distance, visible
flag; the LED and the face are the other robots', what a colony agent needs to find a mate), own
energy, LED state, docked flag and recharge step count. Normalised by default
(``observation="normalised"``: every entry in [0, 1] by its bounds, the ranges as proximities,
the bearings in [−1, 1]; energy ``energy / max_energy``, 0.5 at birth); ``observation="raw"``
gives physical units (m, rad, energy bounded by ``max_energy``, 200).

Action (per agent; ``env.action_names``):

* ``action="discrete"``: ``MultiDiscrete([8, 2, 2, 2])``: a command of the behaviours' table
  (:data:`cyber_rodent.commands.WHEEL_COMMANDS`), the LED (1 = green), the Mate signal (1 =
  willing to exchange) and the recharge decision (1 = keep recharging while docked, 0 = stop).
* ``action="continuous"``: ``Box((5,), float32)``: left and right wheel rim speeds in m/s within
  ±``max_wheel_speed`` (default 1.0, inside the motor limit of 1.3), then LED, Mate and recharge
  in [−1, 1] (on above 0).

The colony is the ``survival`` task of :mod:`cyber_rodent.tasks.spec` (:data:`TASK`) with every
robot an agent: its field, switches and episode length are the defaults here, and its sparse
reward's terms are the reward.

Reward (per agent and step), by default: +1 (``dock_reward``, term ``capture``) for each
captured battery (``StepEvents.captured``, by the rules' ``capture_rule``) and +1
(``mate_reward``, term ``mating``) for each IR exchange, for both partners; 0 otherwise, and no
cost for dying (a dead robot earns nothing more). These are the two measures the paper scores
the colony by, as in the dm-control ``Survival`` task.

``infos[agent]`` holds ``captured`` (bool), ``mate_partner`` (the partner's agent name or None)
and ``energy`` (float) of the step.

Seeding: ``reset(seed=...)`` makes the one generator of the placement and of the rotation
reflexes (vision noise, if configured, draws from a child of it); ``reset()`` without a seed
continues it. The same seed and actions give the same trajectories, bit for bit.

Rendering: ``render_mode="rgb_array"`` returns the top-down view of the field
(:class:`cyber_rodent.render.FieldRenderer`).

A ready policy: ``policy = baseline_policy(env)``, then ``actions = policy(observations)``
each step: the shipped behaviours with evolved controllers (:mod:`cyber_rodent.colony_baseline`),
which dock, recharge and mate from the first steps. It reads the physical observations of
:meth:`ColonyEnv.raw_observations`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv  # type: ignore[import-untyped]  # no type hints

from cyber_rodent.backend import DEFAULT_BACKEND, Backend, check_backend
from cyber_rodent.colony_baseline import BaselinePolicy, baseline_policy  # noqa: F401
from cyber_rodent.gym_env import (
    ACTION_KINDS,
    DEFAULT_MAX_WHEEL_SPEED,
    action_names,
    action_space,
    check_max_wheel_speed,
    decode_action,
)
from cyber_rodent.observations import (
    OBSERVATION_NAMES,
    OBSERVATION_UNITS,
    ObservationBounds,
    ObservationLimits,
    check_observation,
    nearest_frame,
    robot_observations,
)
from cyber_rodent.render import FieldRenderer, check_image_size
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.tasks.rewards import RewardScales, TaskRewards, total_reward
from cyber_rodent.tasks.spec import SURVIVAL
from cyber_rodent.validation import check_choice, check_integer, check_number
from cyber_rodent.vision import PROVIDER_NAMES, CameraConfig, VisionFrame, make_provider
from cyber_rodent.world import World, WorldConfig

#: The task of the colony: Survival, every robot an agent (its field, rewards, switches and
#: episode length are the defaults here).
TASK = SURVIVAL
#: The switches of a colony agent's action, after the wheel command.
SWITCHES = TASK.switches


def agent_name(robot: int) -> str:
    """The agent of robot ``robot``: ``robot_0``, ``robot_1``, …"""
    return f"robot_{robot}"


class ColonyEnv(ParallelEnv):  # type: ignore[misc]  # pettingzoo has no type hints
    """The colony: every robot an agent of one survival world (see the module docstring).

    Args:
        n_robots: robots (agents), ≥ 1.
        n_packs: battery packs.
        action: ``"discrete"`` or ``"continuous"``.
        observation: ``"normalised"`` (in [0, 1], bearings in [−1, 1]) or ``"raw"``
            (physical units); :mod:`cyber_rodent.observations`.
        survival: the survival rules (default: the paper's).
        max_cycles: control steps after which every agent is truncated, ≥ 1.
        dock_reward: reward of a captured battery.
        mate_reward: reward of an IR exchange, to each partner.
        vision: ``"geometric"`` (default) or ``"rendered"``.
        camera: the omni camera (default :class:`CameraConfig`).
        max_wheel_speed: bound of the continuous wheel speeds, m/s, in (0, 1.3].
        render_mode: None or ``"rgb_array"``.
        render_width, render_height: size of a rendered image, px.
        backend: ``"numba"`` or ``"numpy"`` kernels (the same trajectories).

    Raises:
        ValueError: for an invalid option (the message names it).
    """

    metadata: dict[str, Any] = {
        "render_modes": ["rgb_array"],
        "name": "cyber_rodent_colony_v0",
        "render_fps": 5,
        "is_parallelizable": True,
    }

    def __init__(
        self,
        n_robots: int = TASK.field.robots,
        n_packs: int = TASK.field.packs,
        *,
        action: str = "discrete",
        observation: str = "normalised",
        survival: SurvivalConfig | None = None,
        max_cycles: int = TASK.episode_steps,
        dock_reward: float = 1.0,
        mate_reward: float = 1.0,
        vision: str = "geometric",
        camera: CameraConfig | None = None,
        max_wheel_speed: float = DEFAULT_MAX_WHEEL_SPEED,
        render_mode: str | None = None,
        render_width: int = 480,
        render_height: int = 480,
        backend: Backend = DEFAULT_BACKEND,
    ) -> None:
        self.action_kind = check_choice("action", action, ACTION_KINDS)
        self.observation_kind = check_observation(observation)
        if survival is not None and not isinstance(survival, SurvivalConfig):
            raise ValueError(f"survival must be a SurvivalConfig, got {type(survival).__name__}")
        self.max_cycles = check_integer("max_cycles", max_cycles, 1, 10_000_000)
        self.dock_reward = check_number("dock_reward", dock_reward)
        self.mate_reward = check_number("mate_reward", mate_reward)
        scales = RewardScales(dock_reward=self.dock_reward, mate_reward=self.mate_reward)
        check_choice("vision", vision, PROVIDER_NAMES)
        if camera is not None and not isinstance(camera, CameraConfig):
            raise ValueError(f"camera must be a CameraConfig, got {type(camera).__name__}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        check_image_size(render_width, render_height)
        self._render_size = (render_width, render_height)
        self.max_wheel_speed = check_max_wheel_speed(max_wheel_speed)
        backend = check_backend(backend)
        rules = survival or SurvivalConfig()

        fixed = np.random.default_rng(0)  # construction only; every reset re-draws
        self.world = World(WorldConfig(n_robots=n_robots, n_packs=n_packs), fixed)
        self.survival = SurvivalWorld(self.world, rules, fixed, backend=backend)
        self.camera = camera or CameraConfig()
        self.vision = make_provider(
            vision, self.world, self.camera, np.random.default_rng(0), backend=backend
        )
        self.max_range = float(self.camera.max_range)
        self.metadata = {**self.metadata, "render_fps": 1.0 / rules.control_dt}

        n = self.world.config.n_robots
        self.possible_agents = [agent_name(i) for i in range(n)]
        self.agents: list[str] = []
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        limits = ObservationLimits.of(self.world.range_max[0], self.max_range, rules)
        self.observation_names = OBSERVATION_NAMES
        self.observation_units = OBSERVATION_UNITS
        self.observation_bounds: ObservationBounds = limits.bounds()
        self.observation_scale = limits.scale()
        self.action_names = action_names(self.action_kind, SWITCHES)
        # One space object per agent, returned as is (PettingZoo seeds them per agent).
        self.observation_spaces = {
            agent: limits.space(self.observation_kind) for agent in self.possible_agents
        }
        self.action_spaces = {
            agent: action_space(self.action_kind, SWITCHES, self.max_wheel_speed)
            for agent in self.possible_agents
        }

        self._wheels = np.zeros((n, 2))
        self._led = np.zeros(n, dtype=bool)
        self._mate = np.zeros(n, dtype=bool)
        self._recharge = np.zeros(n, dtype=bool)
        self._switches = np.zeros(len(SWITCHES), dtype=bool)
        self.rewards = TaskRewards(TASK.sparse, scales, self.survival, n, TASK.target)
        self._rng: np.random.Generator | None = None
        self._renderer: FieldRenderer | None = None
        self._raw: np.ndarray | None = None  # the latest observations in physical units
        self.steps = 0

    # --- pettingzoo API ---------------------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Space[Any]:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Space[Any]:
        return self.action_spaces[agent]

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """New placement, newborn energies, every robot an agent again."""
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        rng = self._rng
        if self.camera.noise.enabled:
            self.vision.rng = rng.spawn(1)[0]
        self.survival.reset(rng)
        self.world.set_led(False)
        self.agents = list(self.possible_agents)
        self.steps = 0
        frame = nearest_frame(self.vision)
        self.rewards.reset(frame)
        states = self._states(frame)
        observations = {agent: states[i].copy() for agent, i in self._index.items()}
        return observations, {agent: {} for agent in self.agents}

    def step(
        self, actions: dict[str, Any]
    ) -> tuple[
        dict[str, np.ndarray],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        """One control step of every live agent's action.

        Raises:
            ValueError: an action for an agent that is not live, a live agent without an
                action, or an action outside its space.
            RuntimeError: no live agent (call reset()).
        """
        if not self.agents:
            raise RuntimeError("no live agent: call reset()")
        unknown = set(actions) - set(self.agents)
        missing = set(self.agents) - set(actions)
        if unknown or missing:
            raise ValueError(
                f"actions must name exactly the live agents; missing {sorted(missing)}, "
                f"not live {sorted(unknown)}"
            )
        self._wheels[:] = 0.0
        self._led[:] = False
        self._mate[:] = False
        self._recharge[:] = False
        switches = {"led": self._led, "mate": self._mate, "recharge": self._recharge}
        for agent in self.agents:
            i = self._index[agent]
            space = self.action_spaces[agent]
            decode_action(actions[agent], space, self._wheels[i], self._switches)
            for name, on in zip(SWITCHES, self._switches, strict=True):
                switches[name][i] = on
        self.rewards.begin()
        events = self.survival.step(self._wheels, self._led, self._mate, self._recharge)
        self.steps += 1
        frame = nearest_frame(self.vision)
        reward = total_reward(self.rewards.end(events, frame, TASK.reached(events)))
        states = self._states(frame)
        truncate = self.steps >= self.max_cycles
        sw = self.survival
        observations: dict[str, np.ndarray] = {}
        rewards: dict[str, float] = {}
        terminations: dict[str, bool] = {}
        truncations: dict[str, bool] = {}
        infos: dict[str, dict[str, Any]] = {}
        for agent in self.agents:
            i = self._index[agent]
            captured = bool(events.captured[i])
            partner = int(events.mate_partner[i])
            observations[agent] = states[i].copy()
            rewards[agent] = float(reward[i])
            terminations[agent] = not bool(sw.alive[i])
            truncations[agent] = truncate and not terminations[agent]
            infos[agent] = {
                "captured": captured,
                "mate_partner": agent_name(partner) if partner >= 0 else None,
                "energy": float(sw.energy[i]),
            }
        self.agents = [a for a in self.agents if not (terminations[a] or truncations[a])]
        return observations, rewards, terminations, truncations, infos

    def raw_observations(self) -> dict[str, np.ndarray]:
        """Every live agent's latest observation (of the last ``reset`` or ``step``) in physical
        units: float32 (21,), names :attr:`observation_names`, units :attr:`observation_units`,
        whatever form the observations returned by ``reset`` and ``step`` take. The baseline
        policy (:func:`baseline_policy`) reads these.

        Raises:
            RuntimeError: before the first ``reset``.
        """
        if self._raw is None:
            raise RuntimeError("no observation yet: call reset()")
        return {agent: self._raw[self._index[agent]].copy() for agent in self.agents}

    def _states(self, frame: VisionFrame) -> np.ndarray:
        """Every robot's observation (normalised unless ``observation="raw"``); the physical
        units are kept for :meth:`raw_observations`."""
        self._raw = states = robot_observations(self.survival, frame, self.max_range)
        if self.observation_kind == "normalised":
            states = self.observation_scale.normalise(states)
        return states

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
        close = getattr(self.vision, "close", None)
        if close is not None:  # the rendered provider's GL context
            close()


def parallel_env(**options: Any) -> ColonyEnv:
    """The colony environment (PettingZoo's naming); ``options`` as :class:`ColonyEnv`'s."""
    return ColonyEnv(**options)
