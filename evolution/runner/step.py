"""The evolution runner: embodied evolution (EE) or the centralised GA (CE) in the physics world.

One :class:`EvolutionRunner` owns a :class:`~cyber_rodent.survival.SurvivalWorld` (robots,
packs, energy, docking, IR mating), its vision provider, the behaviour policies, the evolved
controller and a time-sharing scheduler (:class:`~evolution.scheduler.EmbodiedEvolution` or
:class:`~evolution.scheduler.CentralisedEvolution`). Both methods use the same world, population,
lifetime and time sharing; they differ only in the scheduler.

One control step, for all robots at once, is :meth:`EvolutionRunner.step`, which reads top to
bottom: sense → decide → act (one compiled call, :func:`evolution.kernels.sense_decide_act`, or
stage by stage), physics and the world's events (``SurvivalWorld.step``), then the schedule
(``scheduler.on_step``); ``docs/design.md`` §3 draws the data flow. The run loop (checkpoint
cadence, progress) is :mod:`evolution.runner.loop`, checkpoint I/O
:mod:`evolution.runner.checkpoints`.

Decisions the paper leaves open that the runner implements (``docs/design.md`` §9, items 9,
10, 12 and 14): a robot that keeps recharging runs only the recharge part of its controller,
its LED dark and its Mate signal and wheels ignored; the previous-LED input is the physical LED
(after an agent switch, the one the predecessor left on); a switched robot gets its new agent's
own energy, and a docked one ends its recharge with the rotation reflex (the newcomer is not
credited a capture it did not make); a CE robot whose agents have all finished is parked
(energy 0: it stands still, LED dark, cannot dock or mate) until the whole population has
finished.

Random streams: the run's seed makes a ``SeedSequence`` that spawns one generator for the world
(placement and reflexes), one for the scheduler (initial population; EE spawns one per robot
from it) and one for the vision noise. A run is a pure function of its :class:`RunConfig`, its
seed and its behaviour policies.

Checkpoints hold the complete state (physics, world, scheduler with agents, spare lists and
statistics, generator states, event log) as plain data and are written atomically
(:mod:`evolution.runner.checkpoints`); a run resumed from any checkpoint continues
bit-identically (see :mod:`evolution.runner.world_state` for what "complete" takes).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from behaviours import BehaviourPolicies
from behaviours.policies import raise_for_status
from cyber_rodent.backend import DEFAULT_BACKEND, Backend, bind, check_backend, pick
from cyber_rodent.commands import command_speeds
from cyber_rodent.profiles import ActuatorSample, RangeSensorNoise, apply_actuators
from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.survival.watchdog import Watchdog
from cyber_rodent.validation import check_integer
from cyber_rodent.vision import GeometricVision, make_provider
from evolution.controller import NeuralController
from evolution.controllers import resolve
from evolution.genome import Genome
from evolution.kernels import (
    Act,
    ActionBuffers,
    Decide,
    LearnAct,
    Perceive,
    RobotState,
    steer,
    steer_reference,
)
from evolution.learning import LifetimeLearning
from evolution.runner.checkpoints import (
    genomes_identity,
    load_run,
    policy_identity,
    run_fingerprint,
    runner_state,
    save_run,
)
from evolution.runner.config import RunConfig
from evolution.runner.events import RECHARGE_END_SWITCHED, EventKind, EventLog
from evolution.runner.loop import run_generations
from evolution.runner.perception import Perception
from evolution.scheduler import TimeSharingScheduler
from evolution.schemes import MedeaEvolution, scheme
from evolution.stats import GenerationStats

if TYPE_CHECKING:
    import pandas as pd

def default_policies() -> BehaviourPolicies:
    """The shipped trained behaviours.

    Raises:
        FileNotFoundError: the trained values are not installed; the message names the
            hand-written alternative.
    """
    try:
        return BehaviourPolicies.load_default()
    except FileNotFoundError as error:
        raise FileNotFoundError(
            f"{error}. To run evolution without trained behaviours pass "
            "policies=BehaviourPolicies.reactive() (the hand-written baseline)."
        ) from error


class EvolutionRunner:
    """Runs EE or CE on the physics world (see the module docstring).

    Args:
        config: the run's configuration.
        seed: the run's seed (an integer ≥ 0).
        policies: the basic behaviours; default :func:`default_policies` (the shipped trained
            values; a clear error if they are not installed).
        initial_genomes: optional initial population, robot-major (``population_size``
            genomes); default U[-1, 1] random genomes drawn from the seed. For seeding a run
            with evolved individuals (the paper's hardware experiment) and for tests.

    Attributes:
        config, seed, policies: as given.
        survival: the survival world (``survival.world`` is the physical world).
        vision: the vision provider.
        controller: the vectorised evolved controller.
        scheduler: the EE or CE scheduler (agents, spare lists, statistics).
        events: the event log.
        steps: control steps taken.
        generation_steps: control step at which each generation closed (index = generation).
    """

    def __init__(
        self,
        config: RunConfig,
        seed: int,
        policies: BehaviourPolicies | None = None,
        initial_genomes: Sequence[Genome] | None = None,
        backend: Backend = DEFAULT_BACKEND,
    ) -> None:
        if not isinstance(config, RunConfig):
            raise ValueError(f"config must be a RunConfig, got {type(config)!r}")
        self.config = config
        self.seed = check_integer("seed", seed, 0)
        self.backend = check_backend(backend)
        self.policies = policies if policies is not None else default_policies()
        if not callable(getattr(self.policies, "commands", None)):
            raise ValueError("policies must be a behaviours.BehaviourPolicies")
        self.policies_id = policy_identity(self.policies)
        if initial_genomes is not None:
            initial_genomes = list(initial_genomes)
        self.initial_genomes_id = genomes_identity(initial_genomes)
        self.fingerprint = run_fingerprint(
            config, self.seed, self.policies_id, self.initial_genomes_id
        )

        # Later children (the hardware profile's, the learner's) leave the first streams as
        # they were.
        world_ss, scheduler_ss, vision_ss, profile_ss, learning_ss = np.random.SeedSequence(
            self.seed
        ).spawn(5)
        world_rng = np.random.default_rng(world_ss)
        self.survival = SurvivalWorld(config.world, config.survival, world_rng, backend=backend)
        self.world = self.survival.world
        self.vision = make_provider(
            config.vision, self.world, config.camera, np.random.default_rng(vision_ss),
            backend=backend,
        )  # fmt: skip
        evo = config.evolution
        #: the evolution scheme (``method``: :mod:`evolution.schemes`)
        self.scheme = scheme(config.method)
        robot_arena = self.world.robot_arena
        self.scheduler: TimeSharingScheduler = self.scheme.build(
            evo, np.random.default_rng(scheduler_ss), initial_genomes, backend, robot_arena
        )
        n = evo.n_robots
        self.actuator_sample: ActuatorSample | None = None
        self.range_noise: RangeSensorNoise | None = None
        if config.profile is not None:  # sim-to-real: per-robot drive, noisy IR sensors
            actuator_ss, range_ss = profile_ss.spawn(2)
            self.actuator_sample = apply_actuators(
                self.world, config.profile.actuators, np.random.default_rng(actuator_ss)
            )
            if config.profile.range_noise.enabled:
                self.range_noise = RangeSensorNoise(
                    config.profile.range_noise, self.world.range_max,
                    np.random.default_rng(range_ss),
                )  # fmt: skip
        self.perception = Perception(
            self.world, self.vision, range_noise=self.range_noise, backend=backend
        )
        #: Learning mode's in-life learner (None: the fixed behaviours of the paper).
        self.learning: LifetimeLearning | None = None
        if evo.learning.enabled:
            tables = self.policies.tables
            if tables is None:
                raise ValueError(
                    "learning.enabled: learning mode needs tile-coded behaviours (the shipped "
                    "or trained ones), not the hand-written reactive ones"
                )
            self.learning = LifetimeLearning(
                evo, tables, self.survival, np.random.default_rng(learning_ss), backend
            )
            self.learning.load_population(
                self.scheduler.population(), self.scheduler.slot_generation
            )
        self.action = ActionBuffers(
            commands=np.zeros(n, dtype=np.int64),
            wheels=np.zeros((n, 2)),
            led=np.zeros(n, dtype=np.bool_),
            mate=np.zeros(n, dtype=np.bool_),
        )
        rules = config.survival
        #: finds tipped and stuck robots every step; rescues them if ``survival.rescue``
        self.watchdog = Watchdog(
            self.world, self.action.wheels, self.survival.docked,
            self.survival.reflex_steps_left, self.scheduler.active, rules=rules, backend=backend,
        )  # fmt: skip
        self.events = EventLog()
        self.steps = 0
        self.generation_steps: list[int] = []
        self._robots = np.arange(n)
        self._docked_slot = np.zeros(n, dtype=np.intp)
        self._docked_generation = np.zeros(n, dtype=np.int64)
        self._bind_step()
        self._load_switched(self.scheduler.switched)

    def _bind_step(self) -> None:
        """Build the controller on the scheduler's genomes and bind sense → decide → act.

        Called at construction and whenever the scheduler is replaced (a checkpoint restore):
        the controller reads the scheduler's live ``active_weights``.
        """
        evo, survival, perception = self.config.evolution, self.survival, self.perception
        since_recharge, since_mating = self.scheduler.since_view
        robots = RobotState(
            survival.energy, survival.recharge_steps, self.world.led_on, self.action.wheels,
            since_recharge, since_mating,
        )  # fmt: skip
        self.controller = NeuralController(
            self.scheduler.active_weights, robots, perception.inputs, evo.max_energy,
            evo.max_recharge_steps, backend=self.backend, controller=resolve(evo),
            state=self.scheduler.controller_state, lifetime_steps=evo.lifetime_steps,
            top_speed=self.world.robot.top_speed,
        )  # fmt: skip
        speeds = command_speeds(self.world.robot)
        # The controller's fused calls: the paper's own kernels for the paper's controller and
        # inputs, else built in this process around its rule (evolution.controllers).
        kernels = self.controller.kernels
        tables = self.policies.tables
        learning = self.learning
        if learning is not None and perception.fused:
            assert isinstance(self.vision, GeometricVision) and tables is not None
            perceive = Perceive(
                perception.sensors, perception.nearest, perception.rules, perception.inputs
            )
            decided = Decide(self.controller.rules, robots, self.controller.buffers)
            learn_act = LearnAct(
                tables, learning.values, learning.episodes, learning.step_buffers,
                survival.docked, speeds, self.action,
            )  # fmt: skip
            learn_kernel = pick(self.backend, kernels.learn, kernels.learn_reference)
            fused_learning = bind(learn_kernel, self.vision.scene, perceive, decided, learn_act)

            def sense_decide_learn_fused() -> None:
                raise_for_status(fused_learning())

            self.sense_decide_act = sense_decide_learn_fused
        elif perception.fused and tables is not None:
            # Geometric vision without noise, no range noise, tile-coded behaviours: one call.
            assert isinstance(self.vision, GeometricVision)
            perceive = Perceive(
                perception.sensors, perception.nearest, perception.rules, perception.inputs
            )
            decided = Decide(self.controller.rules, robots, self.controller.buffers)
            act = Act(tables, survival.docked, speeds, self.action)
            kernel = pick(self.backend, kernels.act, kernels.act_reference)
            fused = bind(kernel, self.vision.scene, perceive, decided, act)

            def sense_decide_act_fused() -> None:
                raise_for_status(fused())

            self.sense_decide_act = sense_decide_act_fused
        else:
            self.sense_decide_act = self.sense_decide_act_stepwise
        self._steer = bind(
            pick(self.backend, steer, steer_reference),
            self.controller.buffers, survival.docked, speeds, self.action,
        )  # fmt: skip

    # --- the hot loop ----------------------------------------------------------------------
    def step(self) -> bool:
        """One control step for every robot; True if a generation closed in it.

        sense → decide → act (:meth:`sense_decide_act`), then physics and the world's events
        (``SurvivalWorld.step``), then the schedule (``scheduler.on_step``): time sharing,
        matings, deaths and offspring. ``docs/design.md`` §3 draws the data flow.
        """
        scheduler, learning = self.scheduler, self.learning
        if learning is not None:  # learning mode: who acts, the exploration draws
            learning.prepare(scheduler.active_slot, scheduler.active)
        # sense → decide → act: one compiled call on the default path
        self.sense_decide_act()
        # physics → events: commands, the physics substeps, energy, docking, mating
        action = self.action
        events = self.survival.step(
            action.wheels, action.led, action.mate, self.controller.continue_recharge
        )
        self.steps += 1
        if learning is not None:  # learning mode: rewards, terminal transitions
            learning.observe(events, scheduler.age_view)
        if events.any:
            self._log_world_events(events)
        watched = self.watchdog.observe()  # tipped and stuck robots (None: no change)
        if watched is not None:
            self._log_watchdog(watched)
        if self.scheme.broadcasts:  # genomes sent to the robots in range (mEDEA)
            self._broadcast()
        # schedule: ageing, time sharing, matings, deaths, offspring
        switched = scheduler.on_step(
            self.survival.energy, events.died, events.captured, events.mate_partner,
            self.survival.docked,
        )  # fmt: skip
        if self.scheme.broadcasts:
            self._log_scheme_events()
        if not np.count_nonzero(switched):
            return False
        self._load_switched(switched)
        if scheduler.birth_log:
            if learning is not None:  # newborns' parameters and values
                learning.on_births(
                    scheduler.birth_log, scheduler.newborn_genomes(), scheduler.selection_parents
                )
            self._log_births()
        return self._close_generations()

    def sense_decide_act_stepwise(self) -> None:
        """Sense → decide → act stage by stage, for setups the fused call does not cover:
        rendered or noisy vision and range noise (sensing in Python, see
        :class:`Perception`), and behaviours that are not tile-coded (run in Python)."""
        inputs = self.perception.update()
        self.controller.decide()
        if self.learning is not None:
            self.learning.commands(
                self.controller.behaviour, inputs.behaviour, self.action.commands
            )
        else:
            self.policies.commands(
                self.controller.behaviour, inputs.behaviour, out=self.action.commands
            )
        self._steer()

    def remember_docked_agents(self) -> None:
        """Note the slot and generation of every robot's active agent as the one recharging.

        Docking notes it for the docked robot (:meth:`_log_world_events`); a restored run calls
        this once, since a docked robot's active agent is the one that docked (switching it
        out ends the recharge).
        """
        np.copyto(self._docked_slot, self.scheduler.active_slot)
        self._docked_generation[:] = self.scheduler.slot_generation[self._robots, self._docked_slot]

    def _load_switched(self, switched: np.ndarray) -> None:
        """Put each switched robot's new agent into the world (or park an idle CE robot)."""
        survival, scheduler = self.survival, self.scheduler
        for robot in np.flatnonzero(switched).tolist():
            if survival.docked[robot]:
                survival.end_recharge(robot, reflex=True)
                self.events.append(
                    self.steps, robot, EventKind.RECHARGE_END, int(self._docked_slot[robot]),
                    int(self._docked_generation[robot]), RECHARGE_END_SWITCHED,
                )  # fmt: skip
            survival.set_energy(robot, float(scheduler.active_energy[robot]))

    def _log_world_events(self, events: Any) -> None:
        """Append the step's dockings, recharge ends, matings and deaths (rare)."""
        scheduler, log, step = self.scheduler, self.events, self.steps
        slot = scheduler.active_slot
        generation = scheduler.slot_generation
        for robot in np.flatnonzero(events.docked).tolist():
            s = int(slot[robot])
            log.append(step, robot, EventKind.DOCK, s, int(generation[robot, s]),
                       int(events.dock_pack[robot]))  # fmt: skip
            # The agent that recharges, should it be switched out before it undocks.
            self._docked_slot[robot] = s
            self._docked_generation[robot] = generation[robot, s]
        for robot in np.flatnonzero(events.recharge_ended).tolist():
            s = int(slot[robot])
            log.append(step, robot, EventKind.RECHARGE_END, s, int(generation[robot, s]),
                       int(events.recharge_end_reason[robot]))  # fmt: skip
        for robot in np.flatnonzero(events.mate_partner >= 0).tolist():
            s = int(slot[robot])
            log.append(step, robot, EventKind.MATE, s, int(generation[robot, s]),
                       int(events.mate_partner[robot]))  # fmt: skip
        if np.count_nonzero(events.died):
            age = scheduler.active_age  # before on_step: the age lived before this step
            for robot in np.flatnonzero(events.died).tolist():
                s = int(slot[robot])
                log.append(step, robot, EventKind.DEATH, s, int(generation[robot, s]),
                           int(age[robot]) + 1)  # fmt: skip

    def _log_watchdog(self, watched: Any) -> None:
        """Append the step's tips, jams and rescues (rare)."""
        scheduler, log, step = self.scheduler, self.events, self.steps
        slot, generation = scheduler.active_slot, scheduler.slot_generation

        def add(robot: int, kind: EventKind, value: int) -> None:
            s = int(slot[robot])
            log.append(step, robot, kind, s, int(generation[robot, s]), value)

        for robot in watched.tip_started:
            add(robot, EventKind.TIPPED, 0)
        for robot, steps in watched.tip_ended:
            add(robot, EventKind.TIPPED_END, steps)
        for robot in watched.stuck_started:
            add(robot, EventKind.STUCK, 0)
        for robot, steps in watched.stuck_ended:
            add(robot, EventKind.STUCK_END, steps)
        for robot, trouble in watched.rescued:
            add(robot, EventKind.RESCUE, int(trouble))

    def _broadcast(self) -> None:
        """Hand the scheduler which robots' IR ports are within broadcast range of which."""
        assert isinstance(self.scheduler, MedeaEvolution)
        ports = self.world.data.site_xpos[self.world.ir_port_site, :2]
        gap = ports[:, None, :] - ports[None, :, :]
        reach = self.config.evolution.medea.broadcast_range
        self.scheduler.receive(np.einsum("ijk,ijk->ij", gap, gap) <= reach * reach)

    def _log_scheme_events(self) -> None:
        """Append the scheme's own events (mEDEA: receptions, robots falling silent)."""
        scheduler = self.scheduler
        assert isinstance(scheduler, MedeaEvolution)
        generation = scheduler.slot_generation
        for step, robot, sender in scheduler.receive_log:
            self.events.append(step, robot, EventKind.RECEIVE, 0, int(generation[robot, 0]),
                               sender)  # fmt: skip
        for step, robot in scheduler.listen_log:
            self.events.append(step, robot, EventKind.LISTEN, 0, int(generation[robot, 0]), 0)
        scheduler.receive_log.clear()
        scheduler.listen_log.clear()

    def _log_births(self) -> None:
        log = self.events
        for step, robot, slot, generation, origin in self.scheduler.birth_log:
            log.append(step, robot, EventKind.BIRTH, slot, generation, origin)
        self.scheduler.birth_log.clear()

    def _close_generations(self) -> bool:
        done = self.scheduler.completed_generations()
        closed = done > len(self.generation_steps)
        while len(self.generation_steps) < done:
            self.generation_steps.append(self.steps)
        return closed

    # --- running ---------------------------------------------------------------------------
    @property
    def completed_generations(self) -> int:
        """Generations whose statistics are final (EE: every slot passed; CE: replaced)."""
        return len(self.generation_steps)

    def run(
        self,
        generations: int,
        *,
        checkpoint_dir: str | os.PathLike[str] | None = None,
        checkpoint_every: int = 1,
        keep_checkpoints: int = 3,
        max_steps: int | None = None,
        progress: bool = False,
        on_generation: Callable[[EvolutionRunner], object] | None = None,
    ) -> pd.DataFrame:
        """Step until ``generations`` generations have completed; return the statistics.

        The run loop (checkpoint cadence, pruning, progress) is
        :func:`evolution.runner.loop.run_generations`; see it for the arguments.
        """
        return run_generations(
            self, generations, checkpoint_dir=checkpoint_dir, checkpoint_every=checkpoint_every,
            keep_checkpoints=keep_checkpoints, max_steps=max_steps, progress=progress,
            on_generation=on_generation,
        )  # fmt: skip

    def close(self) -> None:
        """Release the vision provider's resources (the rendered camera's OpenGL context)."""
        close = getattr(self.vision, "close", None)
        if callable(close):
            close()

    def __enter__(self) -> EvolutionRunner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- results ---------------------------------------------------------------------------
    def statistics(self) -> pd.DataFrame:
        """Per completed generation, the paper's statistics (:class:`GenerationStats` columns)
        plus ``closed_at_step`` (world control step at which the generation completed),
        ``method`` and ``seed``."""
        import pandas as pd

        rows = self.scheduler.stats.to_records()
        columns = [f.name for f in dataclasses.fields(GenerationStats)]
        frame = pd.DataFrame(rows, columns=columns)
        frame["closed_at_step"] = pd.Series(self.generation_steps[: len(frame)], dtype="int64")
        frame["method"] = self.config.method
        frame["seed"] = self.seed
        return frame

    def summary(self) -> dict[str, Any]:
        """Headline numbers of the run so far (plain types, for logs and JSON)."""
        counts = self.events.counts()
        return {
            "method": self.config.method,
            "seed": self.seed,
            "policies": self.policies_id,
            "control_steps": self.steps,
            "simulated_seconds": self.steps * self.config.survival.control_dt,
            "completed_generations": self.completed_generations,
            "dockings": counts["dock"],
            "matings": counts["mate"] // 2,
            "deaths": counts["death"],
            "births": counts["birth"],
            "offspring": self.events.offspring(),
            "tips": counts["tipped"],
            "jams": counts["stuck"],
            "rescues": counts["rescue"],
            "troubled_robots": self.troubled_robots(),
        }

    def troubled_robots(self) -> list[int]:
        """The robots the watchdog found tipped or stuck so far, in order."""
        rows = self.events.array
        kinds = rows[:, 2]
        troubled = np.isin(kinds, (EventKind.TIPPED, EventKind.STUCK))
        return sorted(set(rows[troubled, 1].tolist()))

    # --- checkpoints (evolution.runner.checkpoints) ---------------------------------------
    def state(self) -> dict[str, Any]:
        """The complete state of the run as plain data (what a checkpoint stores)."""
        return runner_state(self)

    def save_checkpoint(self, path: str | os.PathLike[str]) -> Path:
        """Write the complete state to ``path`` atomically (temporary file, fsync, rename)."""
        return save_run(self, path)

    @classmethod
    def from_checkpoint(
        cls,
        path: str | os.PathLike[str],
        policies: BehaviourPolicies | None = None,
        *,
        expect: tuple[RunConfig, int] | None = None,
        expect_initial_genomes: Sequence[Genome] | None = None,
        backend: Backend = DEFAULT_BACKEND,
    ) -> EvolutionRunner:
        """Rebuild a runner from a checkpoint; it continues bit-identically.

        Args:
            path: a checkpoint written by :meth:`save_checkpoint` (or by :meth:`run`).
            policies: the behaviour policies the run used (default :func:`default_policies`).
            expect: optional ``(config, seed)`` the checkpoint must belong to.
            expect_initial_genomes: with ``expect``, the initial population the run was
                started with (None: a random one).
            backend: the rebuilt runner's backend (results do not depend on it).

        Raises:
            CheckpointError: missing, truncated, corrupt, malformed or incompatible file, a
                different config, seed or behaviour policies, or another format or MuJoCo
                version. The file is never modified, and loading it never runs code.
        """
        return load_run(
            cls, path, policies if policies is not None else default_policies(),
            expect=expect, expect_initial_genomes=expect_initial_genomes, backend=backend,
        )  # fmt: skip


__all__ = [
    "EvolutionRunner",
    "default_policies",
]
