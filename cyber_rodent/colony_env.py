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
reward's terms are the reward. Any registered task runs the same way (``task="forage"``, or
one a user registered): its learners are the agents (the others parked), its open switches
follow the wheel command in each action, its start condition and termination are the task's,
and its sparse reward is each agent's. The episode loop is the one every interface shares,
:class:`~cyber_rodent.tasks.episode.TaskEpisode`.

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

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv  # type: ignore[import-untyped]  # no type hints

from cyber_rodent.colony_baseline import BaselinePolicy, baseline_policy  # noqa: F401
from cyber_rodent.observations import nearest_frame
from cyber_rodent.rl_env import EnvConfig, FieldEnv, action_names, action_space
from cyber_rodent.tasks.episode import EpisodeOptions, TaskEpisode, task_rules
from cyber_rodent.tasks.rewards import RewardScales
from cyber_rodent.tasks.spec import SURVIVAL, Field, task_names, task_spec
from cyber_rodent.validation import check_integer, choice, number

#: The task of the colony: Survival, every robot an agent (its field, rewards, switches and
#: episode length are the defaults here).
TASK = SURVIVAL
#: The switches of a colony agent's action, after the wheel command.
SWITCHES = TASK.switches
#: The most control steps ``max_cycles`` allows.
MAX_CYCLES = 10_000_000


def agent_name(robot: int) -> str:
    """The agent of robot ``robot``: ``robot_0``, ``robot_1``, …"""
    return f"robot_{robot}"


@dataclass(frozen=True)
class ColonyConfig(EnvConfig):
    """The options of a :class:`ColonyEnv`: those of :class:`~cyber_rodent.rl_env.EnvConfig`
    (``action``, ``observation``, ``vision``, ``camera``, ``survival``, ``max_wheel_speed``,
    ``render_mode``, ``render_width``, ``render_height``, ``backend``) and these.

    Attributes:
        task: a registered task (:func:`~cyber_rodent.tasks.spec.task_names`); its learners
            are the agents.
        n_robots: robots in the field, ≥ the task's learners (None: the task's field).
        n_packs: battery packs (None: the task's field).
        max_cycles: control steps after which every agent is truncated, ≥ 1 (None: the task's
            episode length).
        dock_reward: reward of a captured battery (term ``capture``).
        mate_reward: reward of an IR exchange, to each partner (term ``mating``).

    Raises:
        ValueError: one line naming the first invalid field and what it allows.
    """

    task: str = choice(TASK.name, task_names)
    n_robots: int | None = None
    n_packs: int | None = None
    max_cycles: int | None = None
    dock_reward: float = number(1.0)
    mate_reward: float = number(1.0)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.max_cycles is not None:
            check_integer("max_cycles", self.max_cycles, 1, MAX_CYCLES)


class ColonyEnv(FieldEnv, ParallelEnv):  # type: ignore[misc]  # pettingzoo has no type hints
    """The colony: every learner an agent of one survival world (see the module docstring).

    Args:
        config: the options (:class:`ColonyConfig`; default: its defaults, the paper's colony).
        **options: any field of :class:`ColonyConfig` by name, over ``config``: ``task``,
            ``n_robots``, ``n_packs``, ``action`` (``"discrete"`` or ``"continuous"``),
            ``observation`` (``"normalised"`` or ``"raw"``), ``survival``, ``max_cycles``,
            ``dock_reward``, ``mate_reward``, ``vision``, ``camera``, ``max_wheel_speed``,
            ``render_mode``, ``render_width``, ``render_height``, ``backend``.

    Attributes:
        config: the options.
        task_spec: the task.
        task_episode: its episode loop (:class:`~cyber_rodent.tasks.episode.TaskEpisode`).
        max_cycles: control steps after which every agent is truncated (settable, as
            PettingZoo's ``parallel_api_test`` does).
        steps: control steps of the current episode.

    Raises:
        ValueError: for an invalid option (the message names it).
    """

    metadata: dict[str, Any] = {
        "render_modes": ["rgb_array"],
        "name": "cyber_rodent_colony_v0",
        "render_fps": 5,
        "is_parallelizable": True,
    }

    def __init__(self, config: ColonyConfig | None = None, **options: Any) -> None:
        config = config or ColonyConfig()
        if options:
            config = dataclasses.replace(config, **options)
        spec = task_spec(config.task)
        self.task_spec = spec
        self.dock_reward = config.dock_reward
        self.mate_reward = config.mate_reward
        field = Field(
            robots=spec.field.robots if config.n_robots is None else config.n_robots,
            packs=spec.field.packs if config.n_packs is None else config.n_packs,
        )
        self._build_field(config, field, task_rules(spec, config.survival))
        self.task_episode = TaskEpisode(
            spec,
            self.survival,
            functools.partial(nearest_frame, self.vision),
            EpisodeOptions(
                scales=RewardScales(dock_reward=self.dock_reward, mate_reward=self.mate_reward),
                episode_steps=(
                    spec.episode_steps if config.max_cycles is None else config.max_cycles
                ),
                max_range=self.max_range,
            ),
        )
        switches = spec.switches
        self.possible_agents = [agent_name(i) for i in range(self.task_episode.k)]
        self.agents: list[str] = []
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        self.action_names = action_names(self.action_kind, switches)
        # One space object per agent, returned as is (PettingZoo seeds them per agent).
        self.observation_spaces = {
            agent: self.observation_limits.space(self.observation_kind)
            for agent in self.possible_agents
        }
        self.action_spaces = {
            agent: action_space(self.action_kind, switches, self.max_wheel_speed)
            for agent in self.possible_agents
        }
        self._switches = np.zeros(len(switches), dtype=bool)
        self._rng: np.random.Generator | None = None

    @property
    def max_cycles(self) -> int:
        """Control steps after which every agent is truncated."""
        return self.task_episode.episode_steps

    @max_cycles.setter
    def max_cycles(self, steps: int) -> None:
        self.task_episode.episode_steps = check_integer("max_cycles", steps, 1, MAX_CYCLES)

    @property
    def steps(self) -> int:
        """Control steps of the current episode."""
        return self.task_episode.steps

    # --- pettingzoo API ---------------------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Space[Any]:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Space[Any]:
        return self.action_spaces[agent]

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """New placement (re-drawn until the task's start condition holds), newborn energies,
        every learner an agent again."""
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        rng = self._rng
        self._reseed_vision(rng)
        self.task_episode.reset(rng)
        self.agents = list(self.possible_agents)
        states = self._observe()
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
        episode = self.task_episode
        episode.stop()
        for agent in self.agents:
            i = self._index[agent]
            self._act(i, actions[agent], self.action_spaces[agent], self._switches)
        step = episode.step()
        states = self._observe()
        truncate = step.steps >= self.max_cycles
        sw, events = self.survival, step.events
        observations: dict[str, np.ndarray] = {}
        rewards: dict[str, float] = {}
        terminations: dict[str, bool] = {}
        truncations: dict[str, bool] = {}
        infos: dict[str, dict[str, Any]] = {}
        for agent in self.agents:
            i = self._index[agent]
            partner = int(events.mate_partner[i])
            observations[agent] = states[i].copy()
            rewards[agent] = float(step.reward[i])
            terminations[agent] = step.terminated or not bool(sw.alive[i])
            truncations[agent] = truncate and not terminations[agent]
            infos[agent] = {
                "captured": bool(events.captured[i]),
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


def parallel_env(**options: Any) -> ColonyEnv:
    """The colony environment (PettingZoo's naming); ``options`` as :class:`ColonyEnv`'s."""
    return ColonyEnv(**options)


__all__ = [
    "MAX_CYCLES",
    "SWITCHES",
    "TASK",
    "BaselinePolicy",
    "ColonyConfig",
    "ColonyEnv",
    "agent_name",
    "baseline_policy",
    "parallel_env",
]
