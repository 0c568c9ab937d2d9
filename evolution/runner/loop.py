"""The evolution runner: embodied evolution (EE) or the centralised GA (CE) in the physics world.

One :class:`EvolutionRunner` owns a :class:`~cyber_rodent.survival.SurvivalWorld` (robots,
packs, energy, docking, IR mating), its vision provider, the behaviour policies, the evolved
controller and a time-sharing scheduler (:class:`~evolution.scheduler.EmbodiedEvolution` or
:class:`~evolution.scheduler.CentralisedEvolution`). Both methods use the same world, population,
lifetime and time sharing; they differ only in the scheduler.

One control step, for all robots at once (docs/design.md §3)::

    range sensors + vision ──► controller inputs ──► behaviour + LED  (or, docked: continue?)
    ──► behaviour policy ──► wheel command ──► SurvivalWorld.step (k physics substeps)
    ──► events ──► scheduler.on_step ──► agent switches: load energy, end recharge

Decisions the paper leaves open, as implemented here:

* **Docked robots.** While a robot recharges, only the recharge part of its agent's controller
  acts (paper §3.5); its LED is dark (the selection part, which drives the LED, is idle) and the
  world ignores its Mate signal and wheels.
* **Previous LED input.** The controller's last input is the robot's LED as it was lit during
  the previous step ("whether the CR had the LED turned on", §3.5): after an agent switch the
  new agent sees the LED its predecessor left on, as a physical robot would.
* **Agent switches.** When the scheduler switches a robot to another agent (time share, mating,
  death, end of life), the runner loads that agent's own energy into the robot. If the robot
  was docked, its recharge ends with the post-recharge rotation reflex: the recharge belonged
  to the previous agent, and without the reflex the newcomer, teeth still on the electrode,
  would be credited a capture it did not make.
* **Idle CE robots.** A CE robot whose agents have all finished is parked until the whole
  population has finished: energy 0, so it stands still with its LED dark and cannot dock or
  mate (it still occupies space and can be seen, as a switched-off robot would).

Random streams: the run's seed makes a ``SeedSequence`` that spawns one generator for the world
(placement and reflexes), one for the scheduler (initial population; EE spawns one per robot
from it) and one for the vision noise. A run is a pure function of its :class:`RunConfig`, its
seed and its behaviour policies.

Checkpoints hold the complete state (physics, world, scheduler with agents, spare lists and
statistics, generator states, event log) and are written atomically by
:mod:`evolution.checkpoint`; a run resumed from any checkpoint continues bit-identically
(see :mod:`evolution.runner.world_state` for what "complete" takes).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import re
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from behaviours import MATE, BehaviourPolicies, greedy_kernel
from cyber_rodent.commands import COMMAND_SPEEDS
from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.vision import BATTERY, FACE, LED, make_provider
from evolution import controller_kernel
from evolution.checkpoint import (
    CheckpointError,
    config_fingerprint,
    load_checkpoint,
    read_header,
    remove_stale_temporaries,
    save_checkpoint,
)
from evolution.controller import NeuralController
from evolution.genome import RECHARGE, SELECTION, Genome
from evolution.runner import step_kernel
from evolution.runner.config import RunConfig
from evolution.runner.events import RECHARGE_END_SWITCHED, EventKind, EventLog
from evolution.runner.perception import Perception
from evolution.runner.world_state import capture_world, restore_world
from evolution.scheduler import CentralisedEvolution, EmbodiedEvolution, TimeSharingScheduler
from evolution.stats import GenerationStats

if TYPE_CHECKING:
    import pandas as pd

#: Version of the runner's checkpoint payload layout.
RUNNER_STATE_VERSION = 1
#: Control steps between progress-bar refreshes while a generation is under way.
_PROGRESS_EVERY = 500
_CHECKPOINT_NAME = "gen_{:05d}.ckpt"
_CHECKPOINT_RE = re.compile(r"^gen_(\d{5,})\.ckpt$")


def checkpoint_kind(method: str) -> str:
    """The ``kind`` recorded in a run checkpoint's header."""
    return f"evolution-run-{method}"


def policy_identity(policies: BehaviourPolicies) -> str:
    """A stable description of behaviour policies, for the run's fingerprint.

    Learned policies are identified by a SHA-256 of their action values, hand-written ones by
    their type and configuration, so resuming with different policies is refused.
    """
    digest = hashlib.sha256()
    digest.update(str(getattr(policies, "kind", type(policies).__name__)).encode())
    for policy in getattr(policies, "policies", ()):
        digest.update(type(policy).__qualname__.encode())
        values = getattr(policy, "values", None)
        weights = getattr(values, "weights", None)
        if isinstance(weights, np.ndarray):
            digest.update(np.ascontiguousarray(weights).tobytes())
        elif dataclasses.is_dataclass(policy):
            digest.update(repr(dataclasses.asdict(policy)).encode())
        else:
            config = getattr(policy, "config", None)
            digest.update(repr(config).encode())
    return f"{getattr(policies, 'kind', 'custom')}:{digest.hexdigest()[:16]}"


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


def genomes_identity(genomes: Sequence[Genome] | None) -> str | None:
    """SHA-256 of an initial population's weights (None for the random one)."""
    if genomes is None:
        return None
    digest = hashlib.sha256()
    for genome in genomes:
        digest.update(genome.weights.tobytes())
    return digest.hexdigest()


def run_fingerprint(
    config: RunConfig, seed: int, policies_id: str, genomes_id: str | None = None
) -> str:
    """What a checkpoint must match to be resumed by a run: config, seed, policies and the
    initial population if one was given."""
    run = dataclasses.asdict(config)
    if run.get("profile", 0) is None:
        del run["profile"]  # runs without a profile keep the fingerprints they always had
    fields: dict[str, Any] = {
        "run": run,
        "seed": seed,
        "policies": policies_id,
    }
    if genomes_id is not None:
        fields["initial_genomes"] = genomes_id
    return config_fingerprint(fields)


def _check_seed(seed: object) -> int:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be an integer in [0, ∞), got {seed!r}")
    return int(seed)


def _check_count(name: str, value: object, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
        raise ValueError(f"{name} must be an integer in [{low}, ∞), got {value!r}")
    return int(value)


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
    ) -> None:
        if not isinstance(config, RunConfig):
            raise ValueError(f"config must be a RunConfig, got {type(config)!r}")
        self.config = config
        self.seed = _check_seed(seed)
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

        # A fourth child (the hardware profile's) leaves the first three streams unchanged.
        world_ss, scheduler_ss, vision_ss, profile_ss = np.random.SeedSequence(self.seed).spawn(4)
        world_rng = np.random.default_rng(world_ss)
        self.survival = SurvivalWorld(config.world, config.survival, world_rng)
        self.world = self.survival.world
        self.vision = make_provider(
            config.vision, self.world, config.camera, np.random.default_rng(vision_ss)
        )
        evo = config.evolution
        scheduler_cls = EmbodiedEvolution if config.method == "ee" else CentralisedEvolution
        self.scheduler: TimeSharingScheduler = scheduler_cls(
            evo, np.random.default_rng(scheduler_ss), initial_genomes
        )
        n = evo.n_robots
        self.controller = NeuralController(n, evo.max_energy, evo.max_recharge_steps)
        self.perception = Perception(self.world, self.vision)
        self.actuator_sample = self.range_noise = None
        if config.profile is not None:  # sim-to-real: per-robot drive, noisy IR sensors
            from cyber_rodent.profiles import RangeSensorNoise, apply_actuators

            actuator_ss, range_ss = profile_ss.spawn(2)
            self.actuator_sample = apply_actuators(
                self.world, config.profile.actuators, np.random.default_rng(actuator_ss)
            )
            if config.profile.range_noise.enabled:
                self.range_noise = RangeSensorNoise(
                    config.profile.range_noise, self.world.range_max,
                    np.random.default_rng(range_ss),
                )  # fmt: skip
                self.perception.range_noise = self.range_noise
        self.events = EventLog()
        self.steps = 0
        self.generation_steps: list[int] = []
        self._weights = self.scheduler.active_weights
        self._commands = np.zeros(n, dtype=np.int64)
        self._wheels = np.zeros((n, 2))
        self._mate = np.zeros(n, dtype=bool)
        self._led = np.zeros(n, dtype=bool)
        self._holding = np.zeros(n, dtype=bool)
        self._fused_args: tuple | None = None  # built at the first step (see _fused_arguments)
        self._robots = np.arange(n)
        self._docked_slot = np.zeros(n, dtype=np.intp)
        self._docked_generation = np.zeros(n, dtype=np.int64)
        self._load_switched(self.scheduler.switched)

    # --- the hot loop ----------------------------------------------------------------------
    def step(self) -> bool:
        """One control step for every robot; True if a generation closed in it."""
        survival = self.survival
        fused = self._fused_args
        if fused is None:
            fused = self._fused_args = self._fused_arguments()
        if not fused or step_kernel.sense_decide_act(*fused) != greedy_kernel.OK:
            self._sense_decide_act()  # the reference path (it raises what the kernel refused)
        events = survival.step(self._wheels, self._led, self._mate, self.controller.proceed)
        self.steps += 1
        scheduler = self.scheduler
        if events.any:
            self._log_world_events(events)
        if survival.docked.any():  # who is recharging, should the agent be switched out
            np.copyto(self._docked_slot, scheduler.active_slot)
            self._docked_generation[:] = scheduler.slot_generation[self._robots, self._docked_slot]
        switched = scheduler.on_step(
            survival.energy, events.died, events.docked, events.mate_partner
        )
        if not switched.any():
            return False
        self._load_switched(switched)
        if self.scheduler.birth_log:
            self._log_births()
        return self._close_generations()

    def _sense_decide_act(self) -> None:
        """Perception, controllers, behaviours and wheel speeds, kernel by kernel: the
        reference of ``step_kernel.sense_decide_act`` and the path for every other setup."""
        survival = self.survival
        perception = self.perception
        inputs = perception.update()
        nd = perception.norm_distance
        behaviour, led, proceed = self.controller.decide(
            self._weights, survival.energy, perception.proximity, nd[:, FACE], nd[:, LED],
            nd[:, BATTERY], self.world.led_on, inputs.mate_available, inputs.forage_available,
            survival.recharge_steps,
        )  # fmt: skip
        # A robot that keeps recharging runs no behaviour: its LED is dark.
        holding = self._holding
        np.logical_and(survival.docked, proceed, out=holding)
        np.logical_not(holding, out=holding)
        np.logical_and(led, holding, out=self._led)
        self.policies.commands(behaviour, inputs, out=self._commands)
        np.take(COMMAND_SPEEDS, self._commands, axis=0, out=self._wheels)
        np.equal(behaviour, MATE, out=self._mate)

    def _fused_arguments(self) -> tuple:
        """The arguments of ``step_kernel.sense_decide_act`` on this runner's buffers, or ()
        where the setup needs the step-by-step path (rendered or noisy vision, sensor noise,
        reactive behaviours, no numba)."""
        vision = self.vision
        perception = self.perception.kernel_arguments()  # () unless geometric, noise-free
        policies = self.policies.kernel_arguments()
        if not (
            step_kernel.AVAILABLE
            and controller_kernel.AVAILABLE
            and perception
            and policies
            and vision.backend == "compiled"
        ):
            return ()
        survival, controller = self.survival, self.controller
        return (
            *vision.kernel_arguments(),
            *perception,
            self._weights, RECHARGE.start, SELECTION.start, survival.energy,
            survival.recharge_steps, controller.max_energy, controller.max_recharge_steps,
            *controller.kernel_arguments(),
            *policies, self._commands,
            survival.docked, COMMAND_SPEEDS, MATE, self._wheels, self._led, self._mate,
        )  # fmt: skip

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
        for robot in np.flatnonzero(events.recharge_ended).tolist():
            s = int(slot[robot])
            log.append(step, robot, EventKind.RECHARGE_END, s, int(generation[robot, s]),
                       int(events.recharge_end_reason[robot]))  # fmt: skip
        for robot in np.flatnonzero(events.mate_partner >= 0).tolist():
            s = int(slot[robot])
            log.append(step, robot, EventKind.MATE, s, int(generation[robot, s]),
                       int(events.mate_partner[robot]))  # fmt: skip
        if events.died.any():
            age = scheduler.active_age  # before on_step: the age lived before this step
            for robot in np.flatnonzero(events.died).tolist():
                s = int(slot[robot])
                log.append(step, robot, EventKind.DEATH, s, int(generation[robot, s]),
                           int(age[robot]) + 1)  # fmt: skip

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
        on_generation: Any = None,
    ) -> pd.DataFrame:
        """Step until ``generations`` generations have completed; return the statistics.

        Args:
            generations: completed generations to reach (a resumed runner counts the ones it
                already has).
            checkpoint_dir: where to write checkpoints (``gen_NNNNN.ckpt``); None: none.
            checkpoint_every: write a checkpoint each time this many more generations have
                completed.
            keep_checkpoints: newest checkpoint files to keep (older ones are deleted after a
                newer one is safely written); 0 keeps all.
            max_steps: stop after this many control steps in total even if the generations
                are not complete (an EE slot whose agents keep dying never completes a
                generation); None: no limit.
            progress: show a tqdm progress bar over generations.
            on_generation: optional callable ``f(runner)`` after each completed generation
                (after its checkpoint).

        Returns:
            :meth:`statistics` of the completed generations.
        """
        generations = _check_count("generations", generations, 0)
        checkpoint_every = _check_count("checkpoint_every", checkpoint_every, 1)
        keep_checkpoints = _check_count("keep_checkpoints", keep_checkpoints, 0)
        if max_steps is not None:
            max_steps = _check_count("max_steps", max_steps, 0)
        directory = Path(checkpoint_dir) if checkpoint_dir is not None else None
        if directory is not None:
            directory.mkdir(parents=True, exist_ok=True)
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(
                total=generations, initial=min(self.completed_generations, generations),
                unit="gen", desc=f"{self.config.method.upper()} seed {self.seed}",
            )  # fmt: skip
        step = self.step
        last_saved = self.completed_generations
        started, start_steps = time.perf_counter(), self.steps
        try:
            while self.completed_generations < generations:
                if max_steps is not None and self.steps >= max_steps:
                    break
                if not step():
                    if bar is not None and self.steps % _PROGRESS_EVERY == 0:
                        self._show_progress(bar, generations, started, start_steps)
                    continue
                done = self.completed_generations
                if directory is not None and done - last_saved >= checkpoint_every:
                    self.save_checkpoint(directory / _CHECKPOINT_NAME.format(done))
                    last_saved = done
                    _prune(directory, keep_checkpoints)
                if bar is not None:
                    self._show_progress(bar, generations, started, start_steps)
                if on_generation is not None:
                    on_generation(self)
        finally:
            if bar is not None:
                bar.close()
        return self.statistics()

    def generation_progress(self) -> float:
        """Completed generations plus the share of the next one done (for progress bars).

        EE: the share of the slots (up to the closing quorum) already past the next
        generation; CE: the share of the population that has finished its lifetime.
        """
        done = self.completed_generations
        scheduler = self.scheduler
        if isinstance(scheduler, EmbodiedEvolution):
            ahead = int((scheduler.slot_generation > done).sum())
            share = ahead / scheduler.close_quorum
        else:
            share = float(scheduler.finished.mean())
        return done + min(share, 0.999)

    def _show_progress(self, bar: Any, generations: int, started: float, start_steps: int) -> None:
        rate = (self.steps - start_steps) / max(time.perf_counter() - started, 1e-9)
        postfix = {"steps": self.steps, "steps/s": f"{rate:.0f}"}
        rows = self.scheduler.stats.rows
        if rows and rows[-1].completed:
            postfix["batteries"] = f"{rows[-1].batteries_mean:.1f}"
            postfix["matings"] = f"{rows[-1].matings_mean:.2f}"
        bar.set_postfix(postfix, refresh=False)
        bar.n = round(min(self.generation_progress(), generations), 3)
        bar.refresh()

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
        }

    # --- checkpoints -----------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """The complete, picklable state of the run (what a checkpoint stores)."""
        return {
            "runner_state_version": RUNNER_STATE_VERSION,
            "config": self.config,
            "seed": self.seed,
            "policies_id": self.policies_id,
            "initial_genomes_id": self.initial_genomes_id,
            "steps": self.steps,
            "generation_steps": list(self.generation_steps),
            "scheduler": self.scheduler,
            "events": self.events,
            "world": capture_world(self.survival, self.vision),
            "range_noise_rng": (
                self.range_noise.rng.bit_generator.state if self.range_noise is not None else None
            ),
        }

    def save_checkpoint(self, path: str | os.PathLike[str]) -> Path:
        """Write the complete state to ``path`` atomically (temporary file, fsync, rename)."""
        path = Path(path)
        save_checkpoint(
            path, self.state(), kind=checkpoint_kind(self.config.method),
            fingerprint=self.fingerprint,
        )  # fmt: skip
        return path

    @classmethod
    def from_checkpoint(
        cls,
        path: str | os.PathLike[str],
        policies: BehaviourPolicies | None = None,
        *,
        expect: tuple[RunConfig, int] | None = None,
        expect_initial_genomes: Sequence[Genome] | None = None,
    ) -> EvolutionRunner:
        """Rebuild a runner from a checkpoint; it continues bit-identically.

        Args:
            path: a checkpoint written by :meth:`save_checkpoint` (or by :meth:`run`).
            policies: the behaviour policies the run used (default :func:`default_policies`).
            expect: optional ``(config, seed)`` the checkpoint must belong to.
            expect_initial_genomes: with ``expect``, the initial population the run was
                started with (None: a random one).

        Raises:
            CheckpointError: missing, truncated, corrupt or incompatible file, a different
                config, seed or behaviour policies, or another code version. The file is never
                modified.
        """
        path = Path(path)
        header = read_header(path) if path.is_file() else None
        if header is None:
            raise CheckpointError(f"{path}: checkpoint file not found")
        kind = str(header.get("kind", ""))
        if not kind.startswith("evolution-run-"):
            raise CheckpointError(f"{path}: not an evolution run checkpoint (kind {kind!r})")
        policies = policies if policies is not None else default_policies()
        policies_id = policy_identity(policies)
        fingerprint = None
        if expect is not None:
            config, seed = expect
            kind_expected = checkpoint_kind(config.method)
            if kind != kind_expected:
                raise CheckpointError(
                    f"{path}: checkpoint is of a {kind!r} run, this run is {kind_expected!r}"
                )
            fingerprint = run_fingerprint(
                config,
                _check_seed(seed),
                policies_id,
                genomes_identity(
                    list(expect_initial_genomes) if expect_initial_genomes is not None else None
                ),
            )
        state = load_checkpoint(path, kind=kind, fingerprint=fingerprint)
        version = state.get("runner_state_version") if isinstance(state, dict) else None
        if version != RUNNER_STATE_VERSION:
            raise CheckpointError(
                f"{path}: runner state version {version!r} is not supported (this code reads "
                f"{RUNNER_STATE_VERSION})"
            )
        if state["policies_id"] != policies_id:
            raise CheckpointError(
                f"{path}: the run used behaviour policies {state['policies_id']}, got "
                f"{policies_id}; resume with the same policies"
            )
        genomes_id = state["initial_genomes_id"]
        payload_fingerprint = run_fingerprint(
            state["config"], state["seed"], policies_id, genomes_id
        )
        if payload_fingerprint != header["fingerprint"]:
            raise CheckpointError(f"{path}: header and payload disagree (config fingerprint)")
        runner = cls(state["config"], state["seed"], policies)
        runner.initial_genomes_id = genomes_id
        runner.fingerprint = payload_fingerprint
        try:
            runner._restore(state)
        except (ValueError, KeyError, AttributeError) as error:
            raise CheckpointError(f"{path}: cannot restore this checkpoint ({error})") from error
        return runner

    def _restore(self, state: dict[str, Any]) -> None:
        scheduler = state["scheduler"]
        if type(scheduler) is not type(self.scheduler):
            raise ValueError(f"scheduler is a {type(scheduler).__name__}")
        restore_world(state["world"], self.survival, self.vision)
        self.scheduler = scheduler
        self._weights = scheduler.active_weights
        self._fused_args = None
        self.events = state["events"]
        self.steps = int(state["steps"])
        self.generation_steps = list(state["generation_steps"])
        if self.range_noise is not None:
            self.range_noise.rng.bit_generator.state = state["range_noise_rng"]


def list_checkpoints(directory: str | os.PathLike[str]) -> list[Path]:
    """Run checkpoints in ``directory``, oldest generation first."""
    directory = Path(directory)
    if not directory.is_dir():
        return []
    found = []
    for path in directory.iterdir():
        match = _CHECKPOINT_RE.match(path.name)
        if match:
            found.append((int(match.group(1)), path))
    return [path for _, path in sorted(found)]


def latest_checkpoint(directory: str | os.PathLike[str]) -> Path | None:
    """The newest run checkpoint in ``directory`` (None if there is none)."""
    found = list_checkpoints(directory)
    return found[-1] if found else None


def _prune(directory: Path, keep: int) -> None:
    """Delete all but the ``keep`` newest checkpoints (0: keep all) and stray temporaries."""
    remove_stale_temporaries(directory)
    if keep <= 0:
        return
    for path in list_checkpoints(directory)[:-keep]:
        path.unlink(missing_ok=True)


__all__ = [
    "EvolutionRunner",
    "checkpoint_kind",
    "default_policies",
    "latest_checkpoint",
    "list_checkpoints",
    "policy_identity",
    "run_fingerprint",
]
