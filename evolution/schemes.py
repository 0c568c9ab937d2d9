"""Evolution schemes as components: a registry of the rules that turn lives into new genomes.

A run's scheme is the setting ``method`` (``--method``; :class:`evolution.runner.RunConfig`).
Each name is an entry of :data:`SCHEMES`, a :class:`SchemeSpec` naming a scheduler class
(:class:`evolution.scheduler.TimeSharingScheduler`), which owns, for its scheme:

- **when an agent is replaced** (its ``_on_death``, ``_on_full_life``, ``_advance``),
- **where the newborn's genome comes from** (offspring, a spare list, a random genome, the
  tournament, a received genome: :class:`evolution.agent.Origin`, logged with every birth),
- **what mating does to the genomes** (the IR exchange stores the partner's genome and fitness
  for the paper's schemes; mEDEA's genomes travel by broadcast instead, and a mating only
  counts),
- **what it logs** (births with their origin; mEDEA also each first reception and each robot
  that falls silent: :class:`evolution.runner.events.EventKind`), and its checkpoint state.

Built in:

- ``ee``: the paper's embodied evolution (§2), with the spare list shared as
  ``evolution.spare_list`` says (``robot``, the paper's; ``colony``; ``position``);
- ``ce``: the paper's centralised GA baseline (§4.1);
- ``medea``: mEDEA (Bredeche and Montanier 2012, "Environment-driven embodied evolution in a
  population of autonomous agents", PPSN XI), the field's one-robot-per-agent algorithm
  (:class:`MedeaEvolution`; ``docs/design.md`` §9.34).

A scheme that needs each step's broadcasts sets ``broadcasts``: the runner then hands it, before
each step's schedule, which robots are within ``evolution.medea.broadcast_range`` of which
(:meth:`MedeaEvolution.receive`). A program (or a plugin) adds a scheme with
:func:`register_scheme`.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cyber_rodent.backend import DEFAULT_BACKEND, Backend
from evolution.agent import GenomePool, Origin, genome_at
from evolution.config import EvolutionConfig
from evolution.genome import Genome
from evolution.scheduler import (
    CentralisedEvolution,
    EmbodiedEvolution,
    TimeSharingScheduler,
)


@dataclass(frozen=True)
class SchemeSpec:
    """One evolution scheme (see the module docstring).

    Attributes:
        name: its value of ``method``.
        description: one line.
        scheduler: the scheduler class, built as ``scheduler(config, rng, initial_genomes,
            backend, robot_arena)``.
        check: ``check(config)`` refuses, in one ``ValueError`` line, an evolution config the
            scheme cannot run (None: any).
        broadcasts: the scheduler takes each step's broadcast contacts (``receive``).
    """

    name: str
    description: str
    scheduler: type[TimeSharingScheduler]
    check: Callable[[EvolutionConfig], None] | None = None
    broadcasts: bool = False

    def __post_init__(self) -> None:
        if not re.fullmatch(r"[a-z][a-z0-9_]*", self.name):
            raise ValueError(f"scheme name must be snake_case, got {self.name!r}")
        scheduler = self.scheduler
        if not (isinstance(scheduler, type) and issubclass(scheduler, TimeSharingScheduler)):
            raise ValueError(f"scheme {self.name}: scheduler must be a TimeSharingScheduler")

    def build(
        self,
        config: EvolutionConfig,
        rng: np.random.Generator,
        initial_genomes: Sequence[Genome] | None = None,
        backend: Backend = DEFAULT_BACKEND,
        robot_arena: np.ndarray | None = None,
    ) -> TimeSharingScheduler:
        """The scheme's scheduler for ``config`` (checked first)."""
        if self.check is not None:
            self.check(config)
        return self.scheduler(config, rng, initial_genomes, backend, robot_arena)


class MedeaEvolution(EmbodiedEvolution):
    """mEDEA (Bredeche and Montanier 2012), one agent per robot, in the survival world.

    Rules (``docs/design.md`` §9.34):

    - Each robot runs one genome for a lifetime (``lifetime_steps``). At every control step
      every active robot broadcasts its genome to the robots whose IR port is within
      ``evolution.medea.broadcast_range`` of its own, in the same arena; a receiver keeps the
      latest genome of each sender (:meth:`receive`), in the order it first heard them.
    - At the end of a lifetime (full, or cut short by death: energy and death follow the
      survival rules, as for every scheme) the robot picks one received genome uniformly at
      random (its own generator), mutates it (``evolution.medea.mutate``), empties its list
      and runs it as a new agent (origin ``RECEIVED``).
    - A robot that received none falls silent: it stands still (parked like a finished CE
      robot), broadcasts nothing and keeps listening for a lifetime; then it takes a received
      genome as above, or, after ``listen_lifetimes`` silent lifetimes with nothing heard, a
      fresh random genome (origin ``RANDOM``).
    - A slot's generation rises at the end of every full lifetime, active or silent (not at a
      death, as in EE); rows close by EE's quorum. The IR exchange (mating) still happens and
      counts, but carries no genome: the broadcasts do.

    Logged: every birth with its origin, each first reception of a sender's genome in a life
    (``RECEIVE``, value the sender) and each robot that falls silent (``LISTEN``).
    """

    def __init__(
        self,
        config: EvolutionConfig,
        rng: np.random.Generator,
        initial_genomes: Sequence[Genome] | None = None,
        backend: Backend = DEFAULT_BACKEND,
        robot_arena: np.ndarray | None = None,
    ) -> None:
        super().__init__(config, rng, initial_genomes, backend, robot_arena)
        n = self.n_robots
        #: per robot, the genomes received in this life, sender -> genome (first-heard order)
        self.received: list[dict[int, Genome]] = [{} for _ in range(n)]
        #: (n,) the robot is silent, listening (it runs no agent)
        self.listening = np.zeros(n, dtype=bool)
        #: (n,) steps of the current silent lifetime, and silent lifetimes in a row
        self.listen_steps = np.zeros(n, dtype=np.int64)
        self.silent_lifetimes = np.zeros(n, dtype=np.int64)
        #: ``(step, robot, sender)`` of every first reception since the runner last drained it
        self.receive_log: list[tuple[int, int, int]] = []
        #: ``(step, robot)`` of every robot that fell silent since the runner last drained it
        self.listen_log: list[tuple[int, int]] = []

    # --- broadcasts -----------------------------------------------------------------------
    def receive(self, in_range: np.ndarray) -> None:
        """Each receiver ``i`` keeps the genome of each active sender ``j`` with
        ``in_range[i, j]`` (its IR port within range, in the same arena; the diagonal is
        ignored). Called by the runner before each step's :meth:`on_step`."""
        senders = self.active
        step = self.steps + 1  # the step about to be scheduled
        for i, j in zip(*np.nonzero(in_range), strict=True):
            i, j = int(i), int(j)
            if i == j or not senders[j] or self.robot_arena[i] != self.robot_arena[j]:
                continue
            genome = self.slots[j][0].genome
            heard = self.received[i]
            if j not in heard:
                self.receive_log.append((step, i, j))
            heard[j] = genome

    # --- the scheme's rules -----------------------------------------------------------------
    def _take_received(self, robot: int) -> tuple[Genome, Origin] | None:
        """A received genome picked at random and mutated (the list emptied), or None."""
        heard = self.received[robot]
        if not heard:
            return None
        rng = self.robot_rngs[robot]
        genomes = list(heard.values())
        genome = genomes[int(rng.integers(len(genomes)))]
        if self.config.medea.mutate:
            genome = genome.mutate(rng, self.config.genetics)
        heard.clear()
        return genome, Origin.RECEIVED

    def _renew(self, robot: int, slot: int) -> None:
        taken = self._take_received(robot)
        if taken is None:
            self.listening[robot] = True
            self.listen_steps[robot] = 0
            self.listen_log.append((self.steps, robot))
            return
        self._new_agent(robot, slot, *taken)

    def _on_death(self, robot: int, slot: int) -> None:
        self._renew(robot, slot)

    def _on_full_life(self, robot: int, slot: int) -> None:
        self.slot_generation[robot, slot] += 1
        self._renew(robot, slot)
        self._close_rows()

    def _advance(self, robot: int) -> None:
        if not self.listening[robot]:
            self.silent_lifetimes[robot] = 0
            self._load(robot)
            return
        self._park(robot)

    def _record_matings(self, mated: np.ndarray) -> None:
        """A mating counts, but carries no genome (mEDEA's genomes travel by broadcast)."""
        for r in np.flatnonzero(mated >= 0):
            self._matings[r] += 1

    def on_step(
        self,
        energy: np.ndarray,
        died: np.ndarray,
        captured: np.ndarray,
        mated_with: np.ndarray,
        recharging: np.ndarray | None = None,
    ) -> np.ndarray:
        """:meth:`TimeSharingScheduler.on_step`, then the silent robots' lifetimes."""
        switched = super().on_step(energy, died, captured, mated_with, recharging)
        silent = self.listening
        if not silent.any():
            return switched
        self.listen_steps[silent] += 1
        lifetime = self.config.lifetime_steps
        ended = np.flatnonzero(silent & (self.listen_steps >= lifetime)).tolist()
        for robot in ended:
            self.silent_lifetimes[robot] += 1
            self.slot_generation[robot, 0] += 1
            taken = self._take_received(robot)
            if taken is None and self.silent_lifetimes[robot] >= self.config.medea.listen_lifetimes:
                taken = Genome.random(self.robot_rngs[robot], self.config.genetics,
                                      layout=self.layout), Origin.RANDOM  # fmt: skip
            if taken is None:
                self.listen_steps[robot] = 0  # another silent lifetime
                continue
            self.listening[robot] = False
            self.listen_steps[robot] = 0
            self._new_agent(robot, 0, *taken)
            self.active[robot] = True
            self._advance(robot)
        if ended:  # a silent lifetime passed: a slot's generation rose
            self._close_rows()
        return switched

    # --- checkpoint state -------------------------------------------------------------------
    def _state_arrays(self) -> dict[str, np.ndarray]:
        return {
            **super()._state_arrays(), "listening": self.listening,
            "listen_steps": self.listen_steps, "silent_lifetimes": self.silent_lifetimes,
        }  # fmt: skip

    def _method_state(self, pool: GenomePool) -> dict[str, Any]:
        return {
            **super()._method_state(pool),
            "received": [[[sender, pool.index(g)] for sender, g in heard.items()]
                         for heard in self.received],  # fmt: skip
            "receive_log": [list(entry) for entry in self.receive_log],
            "listen_log": [list(entry) for entry in self.listen_log],
        }

    def _load_method_state(self, state: dict[str, Any], genomes: Sequence[Genome]) -> None:
        super()._load_method_state(state, genomes)
        received = state["received"]
        if len(received) != self.n_robots:
            raise ValueError("the saved received genomes are not one list per robot")
        self.received = [
            {int(sender): genome_at(genomes, index) for sender, index in heard}
            for heard in received
        ]
        self.receive_log = [(int(a), int(b), int(c)) for a, b, c in state["receive_log"]]
        self.listen_log = [(int(a), int(b)) for a, b in state["listen_log"]]


def _check_medea(config: EvolutionConfig) -> None:
    if config.population_size != config.n_robots:
        raise ValueError(
            f"evolution.population_size ({config.population_size}) must equal "
            f"evolution.n_robots ({config.n_robots}) for method medea: one agent per robot"
        )
    if config.time_sharing_steps != config.lifetime_steps:
        raise ValueError(
            f"evolution.time_sharing_steps ({config.time_sharing_steps}) must equal "
            f"evolution.lifetime_steps ({config.lifetime_steps}) for method medea: a robot's "
            "slot is its agent's whole life"
        )


#: The paper's embodied evolution (§2).
EE = SchemeSpec(
    "ee", "embodied evolution (paper §2): offspring by mating, spare lists (evolution."
    "spare_list)", EmbodiedEvolution,
)  # fmt: skip
#: The paper's centralised GA baseline (§4.1).
CE = SchemeSpec("ce", "the centralised GA (paper §4.1): tournament selection of generations",
                CentralisedEvolution)  # fmt: skip
#: mEDEA (Bredeche and Montanier 2012).
MEDEA = SchemeSpec(
    "medea", "mEDEA (Bredeche and Montanier 2012): one agent per robot, genomes by broadcast",
    MedeaEvolution, check=_check_medea, broadcasts=True,
)  # fmt: skip
#: The built-in schemes, in the order ``cyber-rodent config`` lists them.
BUILT_IN: tuple[SchemeSpec, ...] = (EE, CE, MEDEA)
#: Every scheme by name: the built-in ones and any registered since.
SCHEMES: dict[str, SchemeSpec] = {spec.name: spec for spec in BUILT_IN}


def scheme_names() -> tuple[str, ...]:
    """The names ``method`` accepts now."""
    return tuple(SCHEMES)


def register_scheme(spec: SchemeSpec) -> None:
    """Make ``spec`` a value of ``method`` in this process.

    Raises:
        ValueError: a scheme of that name exists.
    """
    if not isinstance(spec, SchemeSpec):
        raise ValueError(f"spec must be a SchemeSpec, got {type(spec).__name__}")
    if spec.name in SCHEMES:
        raise ValueError(f"a scheme named {spec.name!r} exists")
    SCHEMES[spec.name] = spec


def unregister_scheme(name: str) -> None:
    """Remove a scheme added by :func:`register_scheme`.

    Raises:
        ValueError: ``name`` is built in or unknown.
    """
    if name not in SCHEMES or SCHEMES[name] in BUILT_IN:
        raise ValueError(f"{name!r} is not a registered scheme")
    del SCHEMES[name]


def scheme(name: str) -> SchemeSpec:
    """The scheme ``name``.

    Raises:
        ValueError: one line listing the schemes.
    """
    spec = SCHEMES.get(name)
    if spec is None:
        raise ValueError(f"method must be one of {', '.join(SCHEMES)}, got {name!r}")
    return spec


__all__ = [
    "BUILT_IN",
    "CE",
    "EE",
    "MEDEA",
    "SCHEMES",
    "MedeaEvolution",
    "SchemeSpec",
    "register_scheme",
    "scheme",
    "scheme_names",
    "unregister_scheme",
]
