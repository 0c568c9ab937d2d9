"""A ready policy for the PettingZoo colony: the shipped behaviours with evolved controllers.

::

    from cyber_rodent.colony_env import baseline_policy, parallel_env

    env = parallel_env(max_cycles=500)
    observations, infos = env.reset(seed=0)
    policy = baseline_policy(env)
    while env.agents:
        observations, rewards, terminations, truncations, infos = env.step(policy(observations))

Random actions never dock, so a random colony dies at step 100 and never mates. The baseline
docks, recharges and mates from its first steps: each robot runs one agent evolved with
embodied evolution (the fittest agents that mated of a run's late generation) over the shipped
Mate, Forage and Search behaviours, exactly as the simulator's runner decides (behaviour, LED,
Mate signal, recharge decision, wheel command).

It runs on data, not on the ``behaviours`` or ``evolution`` packages (``cyber_rodent`` never
imports them): ``cyber_rodent/baseline/`` is a deployment bundle written by ``cyber-rodent deploy
--portable-only`` (``bundle.json``, ``controller_weights.npy``, the behaviours' greedy tables
``behaviours.json``/``behaviours.npz``, ``test_vectors.npz``; ``baseline.json`` says where the
agents came from), and the step is :mod:`cyber_rodent.robot_step`, the file every bundle carries
as ``reference_step.py``.

What it reads: :meth:`~cyber_rodent.colony_env.ColonyEnv.raw_observations`, each agent's
observation in physical units whatever form the returned observations take, with every entry
found by its name in ``env.observation_names`` and its unit checked against
``env.observation_units`` when the policy is built (a renamed entry or another unit fails
there, with the name).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from cyber_rodent.robot_step import MATE, ReferenceController

if TYPE_CHECKING:
    from cyber_rodent.survival import SurvivalWorld

#: The entries of an observation the step reads, and their units.
_TARGETS = ("led", "face", "battery")
_UNITS = {
    **{f"{t}_bearing": "rad" for t in _TARGETS},
    **{f"{t}_distance": "m" for t in _TARGETS},
    **{f"{t}_visible": "flag" for t in _TARGETS},
    "energy": "energy",
    "led_on": "flag",
    "docked": "flag",
    "recharge_steps": "control steps",
}


class Colony(Protocol):
    """What the policy reads of its environment (:class:`~cyber_rodent.colony_env.ColonyEnv`
    has it; this module does not import that one, which re-exports this)."""

    observation_names: Sequence[str]
    observation_units: Sequence[str]
    action_names: Sequence[str]
    action_kind: str
    max_wheel_speed: float
    possible_agents: list[str]
    agents: list[str]
    survival: SurvivalWorld

    def raw_observations(self) -> dict[str, np.ndarray]: ...


def baseline_dir() -> Path:
    """Where the baseline bundle lives (``cyber_rodent/baseline``, package data)."""
    return Path(str(resources.files("cyber_rodent") / "baseline"))


class BaselinePolicy:
    """The colony's baseline: every robot runs one evolved agent through the robot step.

    Call it with the observations of the environment's latest ``reset`` or ``step``; it returns
    an action for every live agent (``env.agents``), in the environment's action space.

    Args:
        env: the colony (:class:`~cyber_rodent.colony_env.ColonyEnv`).
        agents: for each robot, the row of the bundle's ``controller_weights.npy`` it runs
            (default: robot i runs row i mod the number of rows; row 0 is the fittest).
        bundle_dir: the bundle (default: :func:`baseline_dir`).

    Raises:
        ValueError: an observation entry the step needs is missing or in another unit, a bad
            agent row, or a bundle whose rules (energy, recharge) differ from the env's.
    """

    def __init__(
        self,
        env: Colony,
        agents: list[int] | None = None,
        bundle_dir: str | Path | None = None,
    ) -> None:
        self.env = env
        self.step_ = ReferenceController(bundle_dir if bundle_dir is not None else baseline_dir())
        names, units = list(env.observation_names), list(env.observation_units)
        ranges = self.step_.spec["normalisation"]["range_sensors"]
        wanted = {**dict.fromkeys(ranges, "m"), **_UNITS}
        self._column: dict[str, int] = {}
        for name, unit in wanted.items():
            if name not in names or units[names.index(name)] != unit:
                have = units[names.index(name)] if name in names else "missing"
                raise ValueError(
                    f"observation {name!r}: the baseline reads it in {unit!r} from "
                    f"env.raw_observations(), the env has {have!r}"
                )
            self._column[name] = names.index(name)
        self._ranges = [self._column[n] for n in ranges]
        self._targets = {part: [self._column[f"{t}_{part}"] for t in _TARGETS]
                         for part in ("bearing", "distance", "visible")}  # fmt: skip
        rules = env.survival.config
        norm = self.step_.spec["normalisation"]
        if (rules.max_energy, rules.max_recharge_steps) != (
            norm["max_energy"], norm["max_recharge_steps"],
        ):  # fmt: skip
            raise ValueError(
                f"the baseline's agents evolved under max_energy {norm['max_energy']:g} and "
                f"max_recharge_steps {norm['max_recharge_steps']}; the env has "
                f"{rules.max_energy:g} and {rules.max_recharge_steps}"
            )
        n = len(self.step_.all_weights)
        robots = env.possible_agents
        rows = agents if agents is not None else [i % n for i in range(len(robots))]
        if len(rows) != len(robots):
            raise ValueError(f"agents must give one row per robot ({len(robots)}), got {rows!r}")
        for row in rows:
            if isinstance(row, bool) or not isinstance(row, int | np.integer) or not 0 <= row < n:
                raise ValueError(f"agents: every row must be an integer in [0, {n - 1}], got "
                                 f"{row!r}")  # fmt: skip
        self.rows = dict(zip(robots, (int(r) for r in rows), strict=True))
        self._action_names = list(env.action_names)

    def decide(self, agent: str, raw: np.ndarray) -> Any:
        """The step's decision for ``agent`` from its physical observation ``raw``."""
        self.step_.use_agent(self.rows[agent])
        x = np.asarray(raw, dtype=np.float64)
        # float32 rounds pi up by 1e-7: bring a bearing of +-pi back into [-pi, pi]
        bearing = np.clip(x[self._targets["bearing"]], -math.pi, math.pi)
        return self.step_.step(
            ranges=x[self._ranges],
            bearing=bearing,
            distance=x[self._targets["distance"]],
            visible=x[self._targets["visible"]] > 0.5,
            energy=float(np.clip(x[self._column["energy"]], 0.0, self.step_.max_energy)),
            led_previous=bool(x[self._column["led_on"]] > 0.5),
            docked=bool(x[self._column["docked"]] > 0.5),
            recharge_steps=int(round(x[self._column["recharge_steps"]])),
        )

    def action(self, agent: str, raw: np.ndarray) -> np.ndarray:
        """``agent``'s action in the env's action space."""
        d = self.decide(agent, raw)
        switches = {"led": d.led, "mate": d.behaviour == MATE, "recharge": d.continue_recharge}
        if self.env.action_kind == "discrete":
            values = [d.command, *(int(switches[n]) for n in self._action_names[1:])]
            return np.array(values, dtype=np.int64)
        limit = self.env.max_wheel_speed
        wheels = [min(max(w, -limit), limit) for w in d.wheels]
        values = [*wheels, *(1.0 if switches[n] else -1.0 for n in self._action_names[2:])]
        return np.array(values, dtype=np.float32)

    def __call__(self, observations: dict[str, Any] | None = None) -> dict[str, np.ndarray]:
        """Actions of every live agent (``observations`` may be those of the latest ``reset``
        or ``step``; the physical ones are read from the env)."""
        raw = self.env.raw_observations()
        return {agent: self.action(agent, raw[agent]) for agent in self.env.agents}


def baseline_policy(env: Colony, **options: Any) -> BaselinePolicy:
    """The colony's ready policy (module docstring); ``options`` as :class:`BaselinePolicy`'s."""
    return BaselinePolicy(env, **options)


__all__ = ["BaselinePolicy", "Colony", "baseline_dir", "baseline_policy"]
