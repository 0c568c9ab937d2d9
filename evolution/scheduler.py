"""Time sharing of virtual agents on physical robots: the EE scheduler and the CE baseline.

Both schedulers are pure logic. They do not step physics; a runner steps the world and reports,
once per control step, what happened to each robot's active agent, as (n_robots,) arrays passed
to :meth:`TimeSharingScheduler.on_step`: energy after the step, death, a battery capture, and a
mating with another robot's active agent.
The scheduler answers with whose controller each robot runs next (:attr:`active_weights`) and
which robots switched agent (:attr:`switched`), so the runner can load the new agent's energy into
the world. This narrow interface lets the rules be tested with scripted event sequences, and keeps
the per-step cost to a handful of vectorised numpy operations on (n_robots,) arrays; Python-level
work happens only on the rare steps with an event.

Rules (paper §2, §3.3, §4.1; docs/design.md §5), common to both methods:

- Each robot runs one of its ``subpopulation_size`` agents at a time, in round-robin order,
  starting from slot 0. The active agent's age, energy and batteries are tracked per step.
- A robot switches to the next agent after ``time_sharing_steps`` steps of the current one, after
  a successful mating, when the agent dies, or when it completes its lifetime.
- At a mating, both agents store the other's genome and its fitness at that moment,
  batteries / (age / 100), computed after the step's own capture is counted.
- Within one step: ages, energies and captures are updated first, then matings are recorded, then
  each robot (in index order) handles its slot's end. Death takes precedence over a completed
  lifetime: an agent whose energy reaches 0 on its last step died.

**EE** (:class:`EmbodiedEvolution`): when an agent completes its lifetime, its slot's generation
counter rises and the agent is replaced by its offspring if it mated (see
:func:`evolution.reproduction.make_offspring`, the unused child goes to the robot's spare list),
or by a spare-list or random genome if it did not. An agent that died is replaced the same way,
and its slot's counter does not rise. Each robot has its own random generator (spawned from the
run's), because each robot makes its reproduction decisions alone; the robots are asynchronous.

**CE** (:class:`CentralisedEvolution`): an agent that completes its lifetime or dies is finished
for this generation and leaves the round robin. A robot whose agents have all finished idles
(:attr:`active` is False: the runner parks it with its LED off and no Mate signal) until every
robot has finished; then the whole population is replaced by tournament selection
(:func:`evolution.reproduction.next_generation`) and every robot restarts at slot 0.

**The agent's own state.** A controller with memory (:mod:`evolution.controllers`,
``state_size`` > 0) keeps per agent, not per robot, a vector of ``state_size`` numbers: zero at
birth (every newborn, whatever its origin: offspring, spare, random or selected), saved in
:attr:`slot_state` when a robot switches the agent out, restored into the live buffer
(:attr:`controller_state`, which the controller reads and writes every step) when it switches
it back in. The counters the controller's inputs may read (steps since the agent's last
recharge and last mating) follow it the same way.

A scheduler's complete state (agents, spare lists, life records, counters, random generator
states, statistics) is plain data from :meth:`TimeSharingScheduler.state`, restored in place by
:meth:`TimeSharingScheduler.load_state`: what checkpoints store (docs/design.md §10).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cyber_rodent.backend import DEFAULT_BACKEND, Backend, bind, check_backend, pick
from evolution.agent import (
    GenomePool,
    MatingRecord,
    Origin,
    VirtualAgent,
    genome_at,
    genomes_from_array,
)
from evolution.agent import fitness as fitness_rule
from evolution.checkpoint import restore_array
from evolution.config import EvolutionConfig
from evolution.controllers import resolve
from evolution.genome import Genome, GenomeLayout
from evolution.kernels import ScheduleRules, SlotCounters, StepOutcome, tick, tick_reference
from evolution.reproduction import draw_replacement, make_offspring, next_generation
from evolution.stats import StatisticsRecorder

#: ``mated_with`` value for "no mating this step" (as in the survival world's events).
NO_PARTNER = -1

#: The scheduler arrays of the agents' own state (absent from states written before it).
AGENT_STATE_ARRAYS = ("state", "slot_state", "since_recharge", "since_mating", "slot_since")

#: :attr:`TimeSharingScheduler.completed_lives` keeps the lives of the generations from this
#: many below the newest closed one upwards: a checkpoint written when a generation closes
#: still holds that generation's lives (what :func:`evolution.lab.transfer.fittest_individuals`
#: ranks), and the state does not grow over a long run. EE slots run ahead of the last closed
#: generation by several generations, so this counts from the closed generations, not from
#: the newest lives.
LIFE_RECORD_GENERATIONS = 2


@dataclass(frozen=True)
class LifeRecord:
    """One agent that lived the full lifetime: who it was and how it did.

    The agent itself is replaced by its offspring as soon as its life ends, so this is the
    only place its genome and final record survive ("the fittest individuals of generation
    40" are agents that lived in generation 40, not the newborns that replaced them).

    Attributes:
        generation: the generation of its slot when it lived.
        robot, slot: where it lived.
        genome: its controller weights.
        batteries: batteries captured in its life.
        matings: matings in its life.
        fitness: batteries / (lifetime / 100), the paper's fitness.
    """

    generation: int
    robot: int
    slot: int
    genome: Genome
    batteries: int
    matings: int
    fitness: float

    def state(self, pool: GenomePool) -> dict[str, Any]:
        """Plain state; the genome as its index in ``pool``."""
        return {
            "generation": self.generation,
            "robot": self.robot,
            "slot": self.slot,
            "genome": pool.index(self.genome),
            "batteries": self.batteries,
            "matings": self.matings,
            "fitness": self.fitness,
        }

    @classmethod
    def from_state(cls, state: dict[str, Any], genomes: Sequence[Genome]) -> LifeRecord:
        """Rebuild a record from :meth:`state` and the pool's genomes."""
        return cls(
            generation=int(state["generation"]),
            robot=int(state["robot"]),
            slot=int(state["slot"]),
            genome=genome_at(genomes, state["genome"]),
            batteries=int(state["batteries"]),
            matings=int(state["matings"]),
            fitness=float(state["fitness"]),
        )


class TimeSharingScheduler:
    """Round-robin time sharing shared by the EE and CE schedulers (see the module docstring).

    Args:
        config: the evolution configuration.
        rng: the run's random generator; it draws the initial population and then stays with the
            scheduler (subclasses may spawn children from it).
        initial_genomes: optional initial population, robot-major (robot ``r`` gets
            ``initial_genomes[r * k : (r + 1) * k]``); random U[-1, 1] genomes if None.
        backend: ``"numba"`` or ``"numpy"``: which implementation of the per-step bookkeeping
            (:func:`evolution.kernels.tick`) runs.
        robot_arena: (n_robots,) the arena of each robot (``World.robot_arena``); None: all in
            one. Schemes whose rules are local to an arena read it.

    Attributes:
        active_weights: (n_robots, controller genes) the controller genes of each robot's
            active agent (read-only view).
        layout: the genomes' layout (the run's controller, learning mode).
        active_energy: (n_robots,) energy of each robot's active agent; after a switch, the
            energy the runner must load into the world.
        active_slot: (n_robots,) slot index of each robot's active agent.
        active: (n_robots,) bool, the robot runs an agent (always True in EE).
        switched: (n_robots,) bool, the robot's active agent changed in the last
            :meth:`on_step` (all True before the first step, so a runner loads every agent the
            same way).
        slot_generation: (n_robots, k) generation counter of each slot.
        steps: control steps processed.
        stats: the per-generation statistics.
        completed_lives: generation -> :class:`LifeRecord` of each agent that completed its
            lifetime in it, for the generations from :data:`LIFE_RECORD_GENERATIONS` below the
            newest closed one upwards.
        birth_log: ``(step, robot, slot, generation, origin)`` of every agent created since the
            log was last emptied (the initial population is not logged). A runner drains it
            into its event log after each step; it is part of the picklable state.
    """

    def __init__(
        self,
        config: EvolutionConfig,
        rng: np.random.Generator,
        initial_genomes: Sequence[Genome] | None = None,
        backend: Backend = DEFAULT_BACKEND,
        robot_arena: np.ndarray | None = None,
    ) -> None:
        if not isinstance(config, EvolutionConfig):
            raise ValueError(f"config must be an EvolutionConfig, got {type(config)!r}")
        n_robots = config.n_robots
        arena = np.zeros(n_robots, dtype=np.int64) if robot_arena is None else robot_arena
        if np.shape(arena) != (n_robots,):
            raise ValueError(f"robot_arena must have one arena per robot ({n_robots})")
        #: (n_robots,) each robot's arena.
        self.robot_arena = np.asarray(arena, dtype=np.int64).copy()
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng)!r}")
        self.config = config
        self.layout = GenomeLayout.of(config)
        n, k = config.n_robots, config.subpopulation_size
        self.n_robots, self.subpopulation_size = n, k
        if initial_genomes is None:
            genomes = [
                Genome.random(rng, config.genetics, layout=self.layout) for _ in range(n * k)
            ]
        else:
            genomes = list(initial_genomes)
            if len(genomes) != n * k or not all(isinstance(g, Genome) for g in genomes):
                raise ValueError(
                    f"initial_genomes must be {n * k} Genome objects (population_size), "
                    f"got {len(genomes)}"
                )
            length = self.layout.length
            if any(g.layout != self.layout for g in genomes):
                raise ValueError(
                    f"initial_genomes must have {length} genes each "
                    f"({'learning mode' if config.learning.enabled else 'the controller'}: "
                    f"evolution.controller = {config.controller})"
                )
        self._rng = rng
        self.slots: list[list[VirtualAgent]] = [
            [VirtualAgent(genomes[r * k + s], float(config.initial_energy)) for s in range(k)]
            for r in range(n)
        ]
        self.slot_generation = np.zeros((n, k), dtype=np.int64)
        self.stats = StatisticsRecorder()
        self.steps = 0
        self.birth_log: list[tuple[int, int, int, int, int]] = []
        self.completed_lives: dict[int, list[LifeRecord]] = {}
        #: CE: per new individual of the last generational replacement (robot-major), the index
        #: (robot-major) of its first parent in the population before it (``next_generation``);
        #: what Lamarckian learning inherits from. EE leaves it empty.
        self.selection_parents: list[int] = []

        self.active_slot = np.zeros(n, dtype=np.intp)
        self.active = np.ones(n, dtype=bool)
        self.switched = np.ones(n, dtype=bool)
        self._weights = np.zeros((n, self.layout.controller_genes))
        self.active_energy = np.zeros(n)
        self._age = np.zeros(n, dtype=np.int64)
        self._batteries = np.zeros(n, dtype=np.int64)
        self._matings = np.zeros(n, dtype=np.int64)
        self._slice = np.zeros(n, dtype=np.int64)
        self._end = np.zeros(n, dtype=bool)
        # The agents' own state (a controller with memory) and input counters, per slot and live.
        size = resolve(config).state_size
        self.slot_state = np.zeros((n, k, size))
        self._state = np.zeros((n, size))
        self.slot_since = np.zeros((n, k, 2), dtype=np.int64)
        self._since_recharge = np.zeros(n, dtype=np.int64)
        self._since_mating = np.zeros(n, dtype=np.int64)
        self._not_recharging = np.zeros(n, dtype=bool)
        #: The per-step bookkeeping's buffers (views of the arrays above).
        self.counters = SlotCounters(
            self.active, self._age, self._slice, self.active_energy, self._batteries, self.switched,
            self._since_recharge, self._since_mating,
        )  # fmt: skip
        self._rules = ScheduleRules(config.time_sharing_steps, config.lifetime_steps)
        self.backend = check_backend(backend)
        self._tick = pick(self.backend, tick, tick_reference)
        self._bound_arrays: tuple[np.ndarray, ...] | None = None
        self._bound_tick: Callable[[], bool] = lambda: True
        for r in range(n):
            self._load(r)

    # --- views ----------------------------------------------------------------------------
    @property
    def active_weights(self) -> np.ndarray:
        """(n_robots, controller genes) live read-only view of the active genomes (fetch once,
        it updates)."""
        view = self._weights.view()
        view.flags.writeable = False
        return view

    @property
    def controller_state(self) -> np.ndarray:
        """(n_robots, state size) the active agents' own controller state: the live, writeable
        buffer the controller reads and updates every step (fetch once)."""
        return self._state

    @property
    def since_view(self) -> tuple[np.ndarray, np.ndarray]:
        """(n_robots,) live read-only views of the steps since the active agents' last
        recharge (0 while docked) and last mating (fetch once)."""
        views = (self._since_recharge.view(), self._since_mating.view())
        for view in views:
            view.flags.writeable = False
        return views

    @property
    def active_age(self) -> np.ndarray:
        """(n_robots,) age of each robot's active agent (a copy)."""
        return self._age.copy()

    @property
    def age_view(self) -> np.ndarray:
        """(n_robots,) live read-only view of the active agents' ages (fetch once)."""
        view = self._age.view()
        view.flags.writeable = False
        return view

    def newborn_genomes(self) -> list[Genome]:
        """The genomes of the agents in :attr:`birth_log`, in its order (before it is drained)."""
        return [self.slots[robot][slot].genome for _, robot, slot, _, _ in self.birth_log]

    @property
    def slice_steps(self) -> np.ndarray:
        """(n_robots,) steps the active agent has run in its current time-sharing slot (a copy)."""
        return self._slice.copy()

    def agent(self, robot: int, slot: int) -> VirtualAgent:
        """The agent in ``slot`` of ``robot``, with its record up to date."""
        if self.active[robot] and self.active_slot[robot] == slot:
            self._store(robot)
        return self.slots[robot][slot]

    def active_agent(self, robot: int) -> VirtualAgent | None:
        """The agent ``robot`` runs now (None if the robot idles)."""
        if not self.active[robot]:
            return None
        return self.agent(robot, int(self.active_slot[robot]))

    def population(self) -> list[Genome]:
        """All genomes, robot-major."""
        return [agent.genome for slots in self.slots for agent in slots]

    # --- the per-step update ---------------------------------------------------------------
    def on_step(
        self,
        energy: np.ndarray,
        died: np.ndarray,
        captured: np.ndarray,
        mated_with: np.ndarray,
        recharging: np.ndarray | None = None,
    ) -> np.ndarray:
        """Apply one control step's outcome for every robot; return :attr:`switched`.

        The arrays are read, never kept, so a runner can pass the same buffers every step (e.g.
        the survival world's per-step event arrays).

        Args:
            energy: (n,) float, each active agent's energy after the step.
            died: (n,) bool, the energy reached 0 this step.
            captured: (n,) bool, the robot's active agent captured a battery this step
                (``StepEvents.captured``: by default, it docked onto a pack).
            mated_with: (n,) int, the robot whose active agent this robot's active agent mated
                with this step, or :data:`NO_PARTNER`; must be symmetric.
            recharging: (n,) bool, the robot is docked after the step (the world's ``docked``);
                None: nobody is (it only feeds the steps-since-recharge counter).

        Returns:
            The :attr:`switched` buffer (overwritten by the next call).

        Raises:
            ValueError: inconsistent events (an asymmetric mating, a mating with itself, an
                event for an idle robot).
        """
        active = self.active
        self.steps += 1
        if recharging is None:
            recharging = self._not_recharging
        if not self._bookkeep(energy, died, captured, mated_with, recharging):
            return self.switched
        cfg = self.config
        any_mating = bool(mated_with.max() >= 0)
        if not active.all() and (died[~active].any() or captured[~active].any()):
            raise ValueError("an event (death or capture) was reported for an idle robot")
        if any_mating:
            self._record_matings(mated_with)
        end = self._end
        np.greater_equal(self._slice, cfg.time_sharing_steps, out=end)
        end |= self._age >= cfg.lifetime_steps
        end |= mated_with >= 0
        end |= died
        end &= active
        for robot in np.flatnonzero(end):
            self._end_slot(int(robot), bool(died[robot]))
        self._after_step()
        return self.switched

    def _bookkeep(
        self,
        energy: np.ndarray,
        died: np.ndarray,
        captured: np.ndarray,
        mated_with: np.ndarray,
        recharging: np.ndarray,
    ) -> bool:
        """The step's bookkeeping (:func:`evolution.kernels.tick`); True if a slot may end.

        A runner passes the same event buffers every step, so the kernel is bound to them once
        (and rebound whenever other arrays arrive).
        """
        bound = self._bound_arrays
        if (
            bound is None
            or energy is not bound[0]
            or died is not bound[1]
            or captured is not bound[2]
            or mated_with is not bound[3]
            or recharging is not bound[4]
        ):
            arrays = (energy, died, captured, mated_with, recharging)
            self._bound_tick = bind(self._tick, self.counters, StepOutcome(*arrays), self._rules)
            self._bound_arrays = arrays
        return bool(self._bound_tick())

    def _record_matings(self, mated: np.ndarray) -> None:
        n = self.n_robots
        partners = np.flatnonzero(mated >= 0)
        for r in partners:
            m = int(mated[r])
            if not 0 <= m < n or m == r or mated[m] != r:
                raise ValueError(
                    f"mated_with must pair robots symmetrically (robot {r} -> {m}, "
                    f"robot {m if 0 <= m < n else '?'} -> "
                    f"{int(mated[m]) if 0 <= m < n else '?'})"
                )
            if not (self.active[r] and self.active[m]):
                raise ValueError(f"mating between robots {r} and {m} involves an idle robot")
        unit = self.config.fitness_time_unit
        reproduction = self.config.reproduction
        fitness = {int(r): fitness_rule(self._batteries[r], self._age[r], unit) for r in partners}
        for r in partners:
            m = int(mated[r])
            partner_agent = self.slots[m][int(self.active_slot[m])]
            own_agent = self.slots[r][int(self.active_slot[r])]
            self._matings[r] += 1
            if reproduction.energy_dependent:
                # One draw per side, from the robot that keeps (or not) the candidate.
                chance = reproduction.candidate_probability(self.active_energy[m])
                if not self._mating_rng(int(r)).random() < chance:
                    continue
            own_agent.partners.append(MatingRecord(partner_agent.genome, fitness[m]))

    def _mating_rng(self, robot: int) -> np.random.Generator:
        """The generator of ``robot``'s energy-dependent candidate draws."""
        return self._rng

    def _end_slot(self, robot: int, died: bool) -> None:
        slot = int(self.active_slot[robot])
        agent = self._store(robot)
        generation = int(self.slot_generation[robot, slot])
        if died:
            agent.dead = True
            self.stats.record_death(generation)
            self._on_death(robot, slot)
        elif agent.age >= self.config.lifetime_steps:
            self.stats.record_full_life(generation, agent.batteries, agent.matings, robot)
            self._record_life(generation, robot, slot, agent)
            self._on_full_life(robot, slot)
        self._advance(robot)

    def _record_life(self, generation: int, robot: int, slot: int, agent: VirtualAgent) -> None:
        lives = self.completed_lives
        record = LifeRecord(
            generation, robot, slot, agent.genome, agent.batteries, agent.matings,
            agent.fitness(self.config.fitness_time_unit),
        )  # fmt: skip
        lives.setdefault(generation, []).append(record)
        oldest = self.completed_generations() - LIFE_RECORD_GENERATIONS
        for old in [g for g in lives if g < oldest]:
            del lives[old]

    def lives_of(self, generation: int) -> list[LifeRecord]:
        """The recorded full lives of ``generation`` (empty if none, or no longer kept)."""
        return list(self.completed_lives.get(generation, []))

    # --- moving counters between the per-robot arrays and the agent objects --------------
    def _store(self, robot: int) -> VirtualAgent:
        agent = self.slots[robot][int(self.active_slot[robot])]
        agent.age = int(self._age[robot])
        agent.energy = float(self.active_energy[robot])
        agent.batteries = int(self._batteries[robot])
        agent.matings = int(self._matings[robot])
        slot = int(self.active_slot[robot])
        self.slot_state[robot, slot] = self._state[robot]
        self.slot_since[robot, slot, 0] = self._since_recharge[robot]
        self.slot_since[robot, slot, 1] = self._since_mating[robot]
        return agent

    def _load(self, robot: int) -> None:
        slot = int(self.active_slot[robot])
        agent = self.slots[robot][slot]
        self._weights[robot] = agent.genome.controller
        self._state[robot] = self.slot_state[robot, slot]
        self._since_recharge[robot] = self.slot_since[robot, slot, 0]
        self._since_mating[robot] = self.slot_since[robot, slot, 1]
        self.active_energy[robot] = agent.energy
        self._age[robot] = agent.age
        self._batteries[robot] = agent.batteries
        self._matings[robot] = agent.matings
        self._slice[robot] = 0
        self.switched[robot] = True

    def _park(self, robot: int) -> None:
        """Leave ``robot`` without an agent (CE: all its agents finished; mEDEA: silent): the
        runner parks it (energy 0: it stands still, LED dark, no docking, no mating)."""
        self.active[robot] = False
        self.switched[robot] = True
        self._state[robot] = 0.0
        self._since_recharge[robot] = 0
        self._since_mating[robot] = 0
        self.active_energy[robot] = 0.0
        self._age[robot] = 0
        self._slice[robot] = 0
        self._batteries[robot] = 0
        self._matings[robot] = 0

    def _new_agent(self, robot: int, slot: int, genome: Genome, origin: Origin) -> None:
        generation = int(self.slot_generation[robot, slot])
        self.slots[robot][slot] = VirtualAgent(
            genome, float(self.config.initial_energy), generation=generation, origin=origin
        )
        self.slot_state[robot, slot] = 0.0  # a newborn's own state starts from zero
        self.slot_since[robot, slot] = 0
        self.stats.record_birth(generation, origin)
        self.birth_log.append((self.steps, robot, slot, generation, int(origin)))

    # --- method-specific hooks -------------------------------------------------------------
    def completed_generations(self) -> int:
        """Generations whose statistics are final (EE: a quorum of slots passed; CE: the
        population was replaced)."""
        raise NotImplementedError

    def _on_death(self, robot: int, slot: int) -> None:
        raise NotImplementedError

    def _on_full_life(self, robot: int, slot: int) -> None:
        raise NotImplementedError

    def _advance(self, robot: int) -> None:
        raise NotImplementedError

    def _after_step(self) -> None:
        """Called once per step after every robot's slot end was handled."""

    # --- checkpoint state ------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """The scheduler's complete state as plain data (docs/design.md §10).

        Every genome is stored once, in ``genomes`` (a (G, L) array), and referred to by its
        index from the agents, their partner records, the life records and the spare lists, so
        a restore shares genome objects exactly as the run did. The per-robot arrays are saved
        as they are (the active agent's counters live there, not in its agent object), the
        random generators as their bit-generator states.
        """
        pool = GenomePool()
        state: dict[str, Any] = {
            "rng": self._rng.bit_generator.state,
            "slots": [[agent.state(pool) for agent in agents] for agents in self.slots],
            "stats": self.stats.state(),
            "steps": self.steps,
            "birth_log": [list(entry) for entry in self.birth_log],
            "completed_lives": [
                [generation, [life.state(pool) for life in lives]]
                for generation, lives in self.completed_lives.items()
            ],
            "arrays": {name: array.copy() for name, array in self._state_arrays().items()},
            **self._method_state(pool),
        }
        state["genomes"] = pool.array(self.layout.length)
        return state

    def load_state(self, state: dict[str, Any]) -> None:
        """Replace this scheduler's state with the :meth:`state` of one of the same class and
        config. Arrays are restored in place: the step kernel and the runner's controller hold
        views of them.

        Raises:
            ValueError: the state does not fit this scheduler (another population layout, a
                generator of another kind, an array of another shape or dtype).
            KeyError: a part of the state is missing.
        """
        genomes = genomes_from_array(state["genomes"], self.layout)
        slots = [
            [VirtualAgent.from_state(agent, genomes) for agent in agents]
            for agents in state["slots"]
        ]
        if [len(agents) for agents in slots] != [self.subpopulation_size] * self.n_robots:
            raise ValueError("the saved population has another layout of robots and slots")
        arrays = state["arrays"]
        targets = self._state_arrays()
        # States written before the agents' own state existed lack its arrays: they were runs
        # of stateless controllers whose inputs never read the counters, so zeros continue them.
        missing = sorted(set(targets) - set(arrays))
        if sorted(set(arrays) - set(targets)) or not set(missing) <= set(AGENT_STATE_ARRAYS):
            raise ValueError(f"scheduler arrays {sorted(arrays)}, expected {sorted(targets)}")
        if any(name.endswith("state") and targets[name].size for name in missing):
            raise ValueError("the saved state has no controller state, this controller has one")
        for name, target in targets.items():
            if name in arrays:
                restore_array(target, arrays[name], f"scheduler {name}")
            else:
                target[...] = 0
        self._rng.bit_generator.state = state["rng"]
        self.slots = slots
        self.stats.load_state(state["stats"])
        self.steps = int(state["steps"])
        self.birth_log = [
            (int(step), int(robot), int(slot), int(generation), int(origin))
            for step, robot, slot, generation, origin in state["birth_log"]
        ]
        self.completed_lives = {
            int(generation): [LifeRecord.from_state(life, genomes) for life in lives]
            for generation, lives in state["completed_lives"]
        }
        self._load_method_state(state, genomes)

    def _state_arrays(self) -> dict[str, np.ndarray]:
        """The live per-robot and per-slot arrays a state saves, by name."""
        return {
            "slot_generation": self.slot_generation,
            "active_slot": self.active_slot,
            "active": self.active,
            "switched": self.switched,
            "weights": self._weights,
            "active_energy": self.active_energy,
            "age": self._age,
            "batteries": self._batteries,
            "matings": self._matings,
            "slice": self._slice,
            "state": self._state,
            "slot_state": self.slot_state,
            "since_recharge": self._since_recharge,
            "since_mating": self._since_mating,
            "slot_since": self.slot_since,
        }

    def _method_state(self, pool: GenomePool) -> dict[str, Any]:
        """The method's own part of :meth:`state`."""
        return {}

    def _load_method_state(self, state: dict[str, Any], genomes: Sequence[Genome]) -> None:
        """Restore what :meth:`_method_state` saved."""


def spare_groups(rule: str, robot_arena: np.ndarray) -> np.ndarray:
    """(n_robots,) the spare list each robot's agents share, by ``evolution.spare_list``:
    ``robot`` (the paper: one list per robot's subpopulation), ``colony`` (one list for all) or
    ``position`` (the robots at the same position within their arenas share one: robot ``r``
    is the ``p``-th robot of its arena, ``p`` its group; with one arena, as ``robot``)."""
    n = len(robot_arena)
    if rule == "robot":
        return np.arange(n, dtype=np.int64)
    if rule == "colony":
        return np.zeros(n, dtype=np.int64)
    if rule == "position":
        groups = np.zeros(n, dtype=np.int64)
        seen: dict[int, int] = {}
        for r, arena in enumerate(robot_arena.tolist()):
            groups[r] = seen.get(arena, 0)
            seen[arena] = int(groups[r]) + 1
        return groups
    raise ValueError(f"evolution.spare_list must be one of robot, colony, position, got {rule!r}")


class EmbodiedEvolution(TimeSharingScheduler):
    """The paper's embodied evolution: local, asynchronous reproduction through mating.

    Attributes:
        spare_lists: per spare-list group, the unused children of earlier reproductions (one
            group per robot by default, the paper's rule: ``evolution.spare_list``).
        spare_group: (n_robots,) the group whose spare list each robot's agents use.
        robot_rngs: per robot, the generator of its reproduction and replacement draws.
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
        self.spare_group = spare_groups(config.spare_list, self.robot_arena)
        n_groups = int(self.spare_group.max()) + 1
        self.spare_lists: list[list[Genome]] = [[] for _ in range(n_groups)]
        self.robot_rngs: list[np.random.Generator] = rng.spawn(self.n_robots)
        self._next_to_close = 0
        n_slots = self.slot_generation.size
        # Rows close once this many slots have passed a generation (EvolutionConfig).
        self._quorum = max(1, math.ceil(config.ee_close_quorum * n_slots - 1e-9))
        self.stats.accept_late = self._quorum < n_slots

    def completed_generations(self) -> int:
        """Generations a quorum of slots has completed (the closed rows of :attr:`stats`)."""
        return self._next_to_close

    @property
    def close_quorum(self) -> int:
        """Slots that must have passed a generation for its row to close."""
        return self._quorum

    def _quorum_generation(self) -> int:
        """The highest generation that at least the quorum of slots has reached."""
        flat = self.slot_generation.ravel()
        return int(np.partition(flat, flat.size - self._quorum)[flat.size - self._quorum])

    def _mating_rng(self, robot: int) -> np.random.Generator:
        return self.robot_rngs[robot]

    def _spares(self, robot: int) -> list[Genome]:
        """The spare list ``robot``'s agents use."""
        return self.spare_lists[int(self.spare_group[robot])]

    def _on_death(self, robot: int, slot: int) -> None:
        cfg = self.config
        genome, origin = draw_replacement(
            self._spares(robot), self.robot_rngs[robot], cfg.genetics, layout=self.layout
        )
        self._new_agent(robot, slot, genome, origin)

    def _on_full_life(self, robot: int, slot: int) -> None:
        cfg = self.config
        agent = self.slots[robot][slot]
        generation = int(self.slot_generation[robot, slot])
        partner = agent.fittest_partner()
        rng = self.robot_rngs[robot]
        if partner is None:
            genome, origin = draw_replacement(
                self._spares(robot), rng, cfg.genetics, layout=self.layout
            )
        else:
            result = make_offspring(
                agent.genome, agent.fitness(cfg.fitness_time_unit), partner, rng, cfg.genetics
            )
            self._spares(robot).append(result.spare)
            self.stats.record_reproduction(generation, result.crossover)
            genome, origin = result.offspring, Origin.OFFSPRING
        self.slot_generation[robot, slot] = generation + 1
        self._new_agent(robot, slot, genome, origin)
        self._close_rows()

    def _close_rows(self) -> None:
        """Close every statistics row a quorum of slots has passed."""
        while self._quorum_generation() > self._next_to_close:
            spare = sum(len(spares) for spares in self.spare_lists)
            self.stats.close(self._next_to_close, spare)
            self._next_to_close += 1

    def _advance(self, robot: int) -> None:
        self.active_slot[robot] = (self.active_slot[robot] + 1) % self.subpopulation_size
        self._load(robot)

    def _method_state(self, pool: GenomePool) -> dict[str, Any]:
        return {
            "spare_lists": [[pool.index(g) for g in spares] for spares in self.spare_lists],
            "robot_rngs": [rng.bit_generator.state for rng in self.robot_rngs],
            "next_to_close": self._next_to_close,
        }

    def _load_method_state(self, state: dict[str, Any], genomes: Sequence[Genome]) -> None:
        spare_lists = [[genome_at(genomes, i) for i in spares] for spares in state["spare_lists"]]
        rng_states = state["robot_rngs"]
        if len(spare_lists) != len(self.spare_lists) or len(rng_states) != self.n_robots:
            raise ValueError(
                "the saved spare lists or generators are not one per group and one per robot"
            )
        for rng, saved in zip(self.robot_rngs, rng_states, strict=True):
            rng.bit_generator.state = saved
        self.spare_lists = spare_lists
        self._next_to_close = int(state["next_to_close"])


class CentralisedEvolution(TimeSharingScheduler):
    """The centralised GA baseline (paper §4.1): same time sharing, generational replacement.

    Attributes:
        generation: the population's current generation.
        finished: (n_robots, k) bool, the slot's agent has completed its lifetime or died.
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
        self.generation = 0
        self.finished = np.zeros((self.n_robots, self.subpopulation_size), dtype=bool)

    def completed_generations(self) -> int:
        """Generations the whole population has completed."""
        return self.generation

    def ce_fitness(self, agent: VirtualAgent) -> float:
        """Selection fitness: batteries / (age / 100) if the agent mated (and, by default,
        survived its lifetime), else 0.

        "Mated" means a mating that yielded an offspring candidate: every mating under the
        paper's rule, only the lucky draws under ``reproduction.energy_dependent``.
        """
        cfg = self.config
        if not agent.partners or (cfg.ce_fitness_requires_survival and agent.dead):
            return 0.0
        return agent.fitness(cfg.fitness_time_unit)

    def _on_death(self, robot: int, slot: int) -> None:
        self.finished[robot, slot] = True

    def _on_full_life(self, robot: int, slot: int) -> None:
        self.finished[robot, slot] = True

    def _advance(self, robot: int) -> None:
        k = self.subpopulation_size
        start = int(self.active_slot[robot])
        for offset in range(1, k + 1):
            slot = (start + offset) % k
            if not self.finished[robot, slot]:
                self.active_slot[robot] = slot
                self._load(robot)
                return
        self._park(robot)

    def _after_step(self) -> None:
        if self.active.any():
            return
        cfg = self.config
        agents = [agent for slots in self.slots for agent in slots]
        fitness = np.array([self.ce_fitness(agent) for agent in agents])
        genomes, crossed = next_generation(
            [a.genome for a in agents], fitness, self._rng, cfg.genetics, self.selection_parents
        )
        previous = self.generation
        for was_crossed in crossed:
            self.stats.record_reproduction(previous, crossover=was_crossed)
        self.stats.close(previous, 0)
        self.generation += 1
        self.slot_generation[:] = self.generation
        self.finished[:] = False
        k = self.subpopulation_size
        for r in range(self.n_robots):
            for s in range(k):
                self._new_agent(r, s, genomes[r * k + s], Origin.SELECTED)
            self.active[r] = True
            self.active_slot[r] = 0
            self._load(r)

    def _state_arrays(self) -> dict[str, np.ndarray]:
        return {**super()._state_arrays(), "finished": self.finished}

    def _method_state(self, pool: GenomePool) -> dict[str, Any]:
        return {"generation": self.generation}

    def _load_method_state(self, state: dict[str, Any], genomes: Sequence[Genome]) -> None:
        self.generation = int(state["generation"])
