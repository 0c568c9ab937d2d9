"""Learning mode: every virtual agent learns its behaviours during its life (docs/design.md §11).

:class:`LifetimeLearning` owns what the in-life learner needs beside the run's other state:

* every agent's private action values for Mate, Forage and Search (one table per agent slot,
  the stacked layout of the behaviours' greedy tables), kept across its time-sharing slots;
* its learning parameters, decoded from its genome's learning genes at birth: the step size
  α, the discount γ, the trace decay λ and the exploration rate ε, each a meta-gene in [0, 1]
  mapped linearly onto its range in :class:`~evolution.config.LearningConfig`, and the six
  weights of its potential-based shaping reward;
* each robot's open learning episode with its replacing traces;
* the exploration stream (one ``numpy.random.Generator``; four draws per robot per step);
* a per-generation record of the agents that lived their full lifetime: their captures and
  matings per :attr:`~evolution.config.EvolutionConfig.fitness_time_unit` steps of age (the
  within-life learning curve) and their learning parameters.

The update is the compiled :func:`behaviours.kernels.learn_commands` inside the step (or its
numpy reference), the algorithm of :class:`behaviours.sarsa.SarsaLambda`. Per control step the
runner calls :meth:`prepare` (which robots act, the draws), then the step's sense → decide →
act with the learner in place of the fixed greedy behaviours, then :meth:`observe` with the
world's events (the rewards, terminal transitions, ended lives), and :meth:`on_births` when
the scheduler replaced agents.

Rewards (the training rewards of ``behaviours/``, the shaped terms of each behaviour's task in
:mod:`cyber_rodent.tasks.spec` without their hand-designed ``shaping``, which the genome now
evolves): Forage ``goal_reward`` at the docking (terminal, the task's success) and
``-step_cost`` every step; Mate likewise at the IR exchange; Search ``clip(progress /
(reference_speed · dt), -1, 1) - collision_penalty · collided``, its progress the tasks' one
definition (:func:`cyber_rodent.tasks.rewards.heading_progress`). Each transition adds the
agent's shaping ``γ Φ_b(s') - Φ_b(s)`` with ``Φ_b(s) = w_b0 s_0 + w_b1 s_1`` over the
behaviour's two inputs (``Φ = 0`` after a terminal transition), which leaves the optimal policy
unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from behaviours.inputs import BEHAVIOUR_NAMES, SEARCH
from behaviours.kernels import (
    MAX_LEARNING_TILINGS,
    BehaviourInputs,
    GreedyTables,
    LearnedValues,
    LearningEpisodes,
    LearningOutcome,
    LearningStep,
    learn_commands,
    learn_commands_reference,
    learn_outcome,
    learn_outcome_reference,
)
from behaviours.policies import raise_for_status
from cyber_rodent.backend import DEFAULT_BACKEND, Backend, bind, check_backend, pick
from cyber_rodent.commands import COMMAND_NAMES
from cyber_rodent.survival import StepEvents, SurvivalWorld
from cyber_rodent.tasks.rewards import heading_progress, progress_reward
from cyber_rodent.tasks.spec import task_spec
from evolution.checkpoint import restore_array
from evolution.config import EvolutionConfig, LearningConfig
from evolution.genome import Genome

#: Command of a robot whose behaviour does not act (docked, in its reflex, idle): any command
#: would do, since the world ignores it; stopping is the honest one.
IDLE_COMMAND = COMMAND_NAMES.index("stop")
#: Exploration draws per robot and step: two for a cut episode's last choice, two for the
#: step's own choice.
DRAWS_PER_ROBOT = 4
#: The learning parameters a meta-gene encodes, in genome order.
META_PARAMETERS = ("alpha", "gamma", "lam", "epsilon")
#: The shaping weights, in genome order: each behaviour's two inputs.
SHAPING_WEIGHTS = (
    "mate_bearing",
    "mate_distance",
    "forage_bearing",
    "forage_distance",
    "search_largest",
    "search_second",
)


def decode_meta(meta: np.ndarray, config: LearningConfig) -> dict[str, float]:
    """The learning parameters of four meta-genes in [0, 1]: each ``low + u (high - low)``.

    Example: with the default ranges, meta-genes (0.5, 0.5, 0.5, 0.5) give α = 0.255,
    γ = 0.8995, λ = 0.495, ε = 0.15.
    """
    decoded = {}
    for name, u in zip(META_PARAMETERS, meta, strict=True):
        low, high = getattr(config, f"{name}_low"), getattr(config, f"{name}_high")
        decoded[name] = low + float(u) * (high - low)
    return decoded


class LifetimeLearning:
    """The in-life learner of every agent of a run (see the module docstring).

    Args:
        config: the run's evolution config (its ``learning`` section must be enabled).
        tables: the behaviours' stacked greedy tables: their tile coders index the learned
            values, and their action values are the ``"shipped"`` initial values.
        survival: the run's survival world (poses, contacts, docking and reflex state).
        rng: the exploration stream.
        backend: which implementation of the learner runs.

    Raises:
        ValueError: learning mode is off, or the coders have more tilings than the compiled
            update covers.
    """

    def __init__(
        self,
        config: EvolutionConfig,
        tables: GreedyTables,
        survival: SurvivalWorld,
        rng: np.random.Generator,
        backend: Backend = DEFAULT_BACKEND,
    ) -> None:
        cfg = config.learning
        if not cfg.enabled:
            raise ValueError("learning.enabled: the learner needs learning mode")
        n_tilings = int(tables.offsets.shape[1])
        if n_tilings > MAX_LEARNING_TILINGS:
            raise ValueError(
                f"the behaviours' coders have {n_tilings} tilings; learning mode covers at "
                f"most {MAX_LEARNING_TILINGS}"
            )
        self.config = config
        self.learning = cfg
        self.backend = check_backend(backend)
        self.rng = rng
        self.survival = survival
        n, k = config.n_robots, config.subpopulation_size
        self.n_robots, self.subpopulation_size = n, k
        n_tables = n * k
        rows, n_actions = tables.table.shape
        dtype = np.float32 if cfg.table_dtype == "float32" else np.float64
        #: A newborn's action values (zero, or the behaviours' own), (rows, actions).
        self.initial_values = (
            np.zeros((rows, n_actions), dtype)
            if cfg.init == "zero"
            else np.ascontiguousarray(tables.table, dtype=dtype)
        )
        self.tables = tables
        self.values = LearnedValues(
            values=np.empty((n_tables, rows, n_actions), dtype),
            alpha=np.zeros(n_tables),
            gamma=np.zeros(n_tables),
            lam=np.zeros(n_tables),
            epsilon=np.zeros(n_tables),
            shaping=np.zeros((n_tables, 3, 2)),
            serial=np.zeros(n_tables, dtype=np.int64),
        )
        self.values.values[:] = self.initial_values
        entries = rows * n_actions
        self.episodes = LearningEpisodes(
            open=np.zeros(n, dtype=bool),
            table=np.zeros(n, dtype=np.int64),
            serial=np.zeros(n, dtype=np.int64),
            behaviour=np.zeros(n, dtype=np.int64),
            rows=np.zeros((n, n_tilings), dtype=np.int64),
            action=np.zeros(n, dtype=np.int64),
            potential=np.zeros(n),
            reward=np.zeros(n),
            trace=np.zeros((n, entries)),
            active=np.zeros((n, entries), dtype=np.int64),
            n_active=np.zeros(n, dtype=np.int64),
        )
        self.step_buffers = LearningStep(
            table=np.full(n, -1, dtype=np.int64),
            acting=np.zeros(n, dtype=bool),
            uniforms=np.zeros((n, DRAWS_PER_ROBOT)),
            trace_cutoff=cfg.trace_cutoff,
            idle_command=IDLE_COMMAND,
            rows_next=np.zeros(n_tilings, dtype=np.int64),
            q_next=np.zeros(n_actions),
        )
        self.outcome = LearningOutcome(
            reward=np.zeros(n), goal=np.zeros(n, dtype=bool), ended=np.zeros(n, dtype=bool)
        )
        self._robot_base = np.arange(n, dtype=np.int64) * k
        self._learn_commands = pick(self.backend, learn_commands, learn_commands_reference)
        self._observe = bind(
            pick(self.backend, learn_outcome, learn_outcome_reference),
            self.values, self.episodes, self.outcome,
        )  # fmt: skip
        self._poses_before = np.zeros((n, 3))
        self._collided = np.zeros(n, dtype=bool)
        self._search_step = cfg.reference_speed * survival.config.control_dt
        # Each behaviour with a goal, and its task's success (the docking, the IR exchange).
        self._goals = tuple(
            (index, success)
            for index, name in enumerate(BEHAVIOUR_NAMES)
            if (success := task_spec(name).success) is not None
        )
        # Per table: the generation its agent was born into, and its captures and matings by
        # age bin (fitness_time_unit steps each).
        self._bin_steps = float(config.fitness_time_unit)
        self.n_age_bins = max(1, math.ceil(config.lifetime_steps / self._bin_steps))
        self._generation = np.zeros(n_tables, dtype=np.int64)
        self._died = np.zeros(n_tables, dtype=bool)
        self._batteries_by_age = np.zeros((n_tables, self.n_age_bins), dtype=np.int64)
        self._matings_by_age = np.zeros((n_tables, self.n_age_bins), dtype=np.int64)
        #: generation -> per-generation sums of the agents that lived their full lifetime.
        self.records: dict[int, dict[str, np.ndarray]] = {}

    # --- agents ------------------------------------------------------------------------------
    def load_agent(self, table: int, genome: Genome, generation: int, inherit: bool) -> None:
        """A newborn takes table ``table``: its parameters from ``genome``, its values from
        ``learning.init``, or, when it ``inherit``\\ s, the values the table holds (its
        parent's, the previous agent of the slot)."""
        v = self.values
        params = decode_meta(genome.meta, self.learning)
        v.alpha[table] = params["alpha"]
        v.gamma[table] = params["gamma"]
        v.lam[table] = params["lam"]
        v.epsilon[table] = params["epsilon"]
        v.shaping[table] = genome.shaping
        v.serial[table] += 1
        if not inherit:
            v.values[table] = self.initial_values
        self._generation[table] = generation
        self._died[table] = False
        self._batteries_by_age[table] = 0
        self._matings_by_age[table] = 0

    def load_population(self, genomes: Sequence[Genome], generations: np.ndarray) -> None:
        """Load the initial population, robot-major (one genome per table)."""
        for table, genome in enumerate(genomes):
            self.load_agent(table, genome, int(generations.flat[table]), inherit=False)

    def on_births(
        self,
        births: Sequence[tuple[int, int, int, int, int]],
        genomes: Sequence[Genome],
        selection_parents: Sequence[int] = (),
    ) -> None:
        """Apply the scheduler's births (``(step, robot, slot, generation, origin)``, with the
        newborns' genomes in the same order): record the lives that ended, load the newborns.

        Under Lamarckian inheritance an EE offspring (origin 1) keeps its slot's values: those
        its parent learned; a CE individual (origin 4) takes the values of its first parent,
        ``selection_parents[table]`` (:attr:`CentralisedEvolution.selection_parents`), as they
        were before the replacement. A newborn in a later generation than the table's agent
        means that agent lived its full lifetime, unless it died (a CE agent that died waits
        for the replacement of the whole population; an EE one is replaced at once, in its
        generation).
        """
        lamarckian = self.learning.inheritance == "lamarckian"
        before = None
        if lamarckian and any(origin == 4 for *_, origin in births):
            before = self.values.values.copy()  # the parents' values, before any is replaced
        for (_, robot, slot, generation, origin), genome in zip(births, genomes, strict=True):
            table = robot * self.subpopulation_size + slot
            previous = int(self._generation[table])
            if generation > previous and not self._died[table]:
                self._record_life(table, previous)
            self.load_agent(table, genome, generation, inherit=lamarckian and origin == 1)
            if before is not None and origin == 4:
                self.values.values[table] = before[selection_parents[table]]

    def _record_life(self, table: int, generation: int) -> None:
        bins = self.n_age_bins
        record = self.records.get(generation)
        if record is None:
            record = self.records[generation] = {
                "lives": np.zeros(1, dtype=np.int64),
                "batteries": np.zeros(bins, dtype=np.int64),
                "matings": np.zeros(bins, dtype=np.int64),
                "sum": np.zeros(10),
                "sum_squares": np.zeros(10),
            }
        v = self.values
        params = np.concatenate(
            ([v.alpha[table], v.gamma[table], v.lam[table], v.epsilon[table]],
             v.shaping[table].reshape(-1))
        )  # fmt: skip
        record["lives"] += 1
        record["batteries"] += self._batteries_by_age[table]
        record["matings"] += self._matings_by_age[table]
        record["sum"] += params
        record["sum_squares"] += params * params

    # --- the step ------------------------------------------------------------------------------
    def prepare(self, table_of_robot: np.ndarray, active: np.ndarray) -> None:
        """Before the step: each robot's agent table, whether its behaviour acts (the robot
        runs an agent, is not docked and not in its reflex), the exploration draws, and the
        poses that Search's progress is measured from.

        Args:
            table_of_robot: (n,) the active slot of each robot.
            active: (n,) the robot runs an agent.
        """
        s = self.step_buffers
        np.add(self._robot_base, table_of_robot, out=s.table)
        s.table[~active] = -1
        acting = s.acting
        np.logical_not(self.survival.docked, out=acting)
        acting &= self.survival.reflex_steps_left == 0
        acting &= active
        self.rng.random(out=s.uniforms)
        self._poses_before[:] = self.survival.world.poses()

    def commands(self, behaviour: np.ndarray, inputs: BehaviourInputs, out: np.ndarray) -> None:
        """The learner's commands on the step-by-step path (the fused step calls the kernel
        itself).

        Raises:
            ValueError: a behaviour index or an input out of range.
        """
        status = self._learn_commands(
            behaviour, inputs, self.tables, self.values, self.episodes, self.step_buffers, out
        )
        raise_for_status(status)

    def observe(self, events: StepEvents, ages: np.ndarray) -> None:
        """After the world's step: each open episode's reward, terminal transitions, ended
        lives; and the within-life record of captures and matings.

        Args:
            events: the step's events.
            ages: (n,) each robot's active agent's age before the step.
        """
        e, out, cfg = self.episodes, self.outcome, self.learning
        behaviour = e.behaviour
        mated = events.mate_partner >= 0
        goal = out.goal
        goal[:] = False
        for index, success in self._goals:
            goal |= (behaviour == index) & success(events)
        goal &= e.open
        np.copyto(out.ended, events.died)
        reward = out.reward
        reward[:] = -cfg.step_cost
        reward += cfg.goal_reward * goal
        searching = e.open & (behaviour == SEARCH)
        if searching.any():
            progress = heading_progress(self._poses_before, self.survival.world.poses())
            self.survival.collisions(out=self._collided)
            search = progress_reward(progress, self._search_step)
            search -= cfg.collision_penalty * self._collided
            np.copyto(reward, search, where=searching)
        self._observe()
        if events.any:
            tables = self.step_buffers.table
            for robot in np.flatnonzero(events.died & (tables >= 0)).tolist():
                self._died[int(tables[robot])] = True
            bins = np.minimum(ages // self._bin_steps, self.n_age_bins - 1).astype(np.int64)
            for robot in np.flatnonzero((events.captured | mated) & (tables >= 0)).tolist():
                table, age_bin = int(tables[robot]), int(bins[robot])
                if events.captured[robot]:
                    self._batteries_by_age[table, age_bin] += 1
                if mated[robot]:
                    self._matings_by_age[table, age_bin] += 1

    # --- results -------------------------------------------------------------------------------
    def record_rows(self) -> list[dict[str, float]]:
        """One row per generation with recorded lives: lives, mean captures and matings per
        age bin, mean and std of each learning parameter."""
        rows = []
        width = self._bin_steps
        names = (*META_PARAMETERS, *(f"shaping_{w}" for w in SHAPING_WEIGHTS))
        for generation in sorted(self.records):
            record = self.records[generation]
            lives = int(record["lives"][0])
            row: dict[str, float] = {"generation": generation, "lives": lives}
            for b in range(self.n_age_bins):
                span = f"{b * width:g}_{(b + 1) * width:g}"
                row[f"batteries_age_{span}"] = record["batteries"][b] / lives
                row[f"matings_age_{span}"] = record["matings"][b] / lives
            mean = record["sum"] / lives
            var = np.maximum(record["sum_squares"] / lives - mean * mean, 0.0)
            for j, name in enumerate(names):
                row[f"{name}_mean"] = float(mean[j])
                row[f"{name}_std"] = float(math.sqrt(var[j]))
            rows.append(row)
        return rows

    @property
    def memory_bytes(self) -> int:
        """Bytes held by the learned values and the traces."""
        e = self.episodes
        return int(self.values.values.nbytes + e.trace.nbytes + e.active.nbytes)

    # --- checkpoint state ----------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """The learner's complete state as plain data.

        Learned values are stored as the rows that differ from the initial values (most rows
        are never visited), traces as each robot's listed entries.
        """
        v, e = self.values, self.episodes
        n_tables, rows, n_actions = v.values.shape
        flat = v.values.reshape(n_tables * rows, n_actions)
        changed = np.flatnonzero(
            np.any(v.values != self.initial_values[None], axis=2).reshape(-1)
        )
        traces = []
        for robot in range(self.n_robots):
            listed = e.active[robot, : e.n_active[robot]].copy()
            traces.append({"entries": listed, "values": e.trace[robot, listed].copy()})
        return {
            "rng": self.rng.bit_generator.state,
            "changed_rows": changed,
            "changed_values": flat[changed].copy(),
            "parameters": {
                name: getattr(v, name).copy()
                for name in ("alpha", "gamma", "lam", "epsilon", "shaping", "serial")
            },
            "episodes": {
                name: getattr(e, name).copy()
                for name in ("open", "table", "serial", "behaviour", "rows", "action",
                             "potential", "reward")
            },  # fmt: skip
            "traces": traces,
            "generation": self._generation.copy(),
            "died": self._died.copy(),
            "batteries_by_age": self._batteries_by_age.copy(),
            "matings_by_age": self._matings_by_age.copy(),
            "records": [
                [generation, {name: array.copy() for name, array in record.items()}]
                for generation, record in sorted(self.records.items())
            ],
        }

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore a :meth:`state` in place (the bound kernels keep their buffers).

        Raises:
            ValueError: the state does not fit this learner.
        """
        v, e = self.values, self.episodes
        n_tables, rows, n_actions = v.values.shape
        changed = np.asarray(state["changed_rows"], dtype=np.int64)
        values = np.asarray(state["changed_values"])
        if changed.ndim != 1 or values.shape != (changed.size, n_actions):
            raise ValueError("learned values of another shape")
        if changed.size and (changed.min() < 0 or changed.max() >= n_tables * rows):
            raise ValueError("learned value rows out of range")
        v.values[:] = self.initial_values
        v.values.reshape(n_tables * rows, n_actions)[changed] = values
        for name, array in state["parameters"].items():
            restore_array(getattr(v, name), array, f"learning {name}")
        for name, array in state["episodes"].items():
            restore_array(getattr(e, name), array, f"learning episode {name}")
        e.trace[:] = 0.0
        if len(state["traces"]) != self.n_robots:
            raise ValueError("learning traces are not one per robot")
        for robot, saved in enumerate(state["traces"]):
            entries = np.asarray(saved["entries"], dtype=np.int64)
            if entries.size and (entries.min() < 0 or entries.max() >= e.trace.shape[1]):
                raise ValueError("learning trace entries out of range")
            e.active[robot, : entries.size] = entries
            e.n_active[robot] = entries.size
            e.trace[robot, entries] = saved["values"]
        restore_array(self._generation, state["generation"], "learning generation")
        restore_array(self._died, state["died"], "learning deaths")
        restore_array(self._batteries_by_age, state["batteries_by_age"], "learning batteries")
        restore_array(self._matings_by_age, state["matings_by_age"], "learning matings")
        self.records = {
            int(generation): {name: np.asarray(array) for name, array in record.items()}
            for generation, record in state["records"]
        }
        self.rng.bit_generator.state = state["rng"]


__all__ = [
    "DRAWS_PER_ROBOT",
    "IDLE_COMMAND",
    "META_PARAMETERS",
    "SHAPING_WEIGHTS",
    "LifetimeLearning",
    "decode_meta",
]
