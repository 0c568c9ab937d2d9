"""Run checkpoints: the runner's complete state as plain data, and the files that hold it.

A run checkpoint is an :mod:`evolution.checkpoint` file (docs/design.md §10) of kind
``evolution-run-<method>`` whose header carries the run's fingerprint
(:func:`run_fingerprint`: config, seed, behaviour policies, initial population) and whose
state is::

    config              dataclasses.asdict(RunConfig)
    seed, policies_id, initial_genomes_id
    steps               control steps taken
    generation_steps    the step at which each generation closed
    scheduler           TimeSharingScheduler.state(): agents, spare lists, life records,
                        statistics, counters, generator states
    events              EventLog.state(): the event table
    world               evolution.runner.world_state.capture_world(): MuJoCo, the survival
                        world, the vision provider's generator
    range_noise         the range-sensor noise generator's state (hardware profile), or None
    learning            LifetimeLearning.state() in learning mode (learned values, traces,
                        open episodes, the exploration stream, the within-life record), or None
    inputs              the names of the controller's inputs (absent in older checkpoints:
                        the paper's)

Loading rebuilds a runner from the config, seed and policies, then writes the state into it
in place (the compiled step's bound buffers stay valid), so it continues bit-identically. The
config, seed and policies in the state must reproduce the header's fingerprint, and the
policies given must be the ones the run used. The files of a run directory are
``gen_NNNNN.ckpt``, written when NNNNN generations have completed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import numpy as np

from behaviours import BehaviourPolicies
from cyber_rodent.atomic import remove_stale_temporaries
from cyber_rodent.backend import DEFAULT_BACKEND, Backend
from cyber_rodent.validation import check_integer
from evolution.checkpoint import (
    CheckpointError,
    config_fingerprint,
    load_checkpoint,
    read_header,
    restore_array,
    save_checkpoint,
)
from evolution.genome import Genome
from evolution.input_kernels import PAPER_INPUTS
from evolution.runner.config import LATER_FIELDS, RunConfig, run_config_from_record
from evolution.runner.fingerprint_fields import FINGERPRINT_FIELDS
from evolution.runner.settings import settings
from evolution.runner.world_state import capture_world, restore_world

if TYPE_CHECKING:
    from cyber_rodent.profiles import RangeSensorNoise
    from cyber_rodent.survival import SurvivalWorld
    from cyber_rodent.survival.watchdog import Watchdog
    from cyber_rodent.vision import VisionProvider
    from evolution.controller import NeuralController
    from evolution.kernels import ActionBuffers
    from evolution.learning import LifetimeLearning
    from evolution.runner.events import EventLog
    from evolution.scheduler import TimeSharingScheduler


class ResumableRun(Protocol):
    """What a run checkpoint holds of a runner and how one is rebuilt from it (see the module
    docstring): the members of :class:`evolution.runner.step.EvolutionRunner` it reads and
    writes, named here so that the runner, which saves and loads through this module, and this
    module do not import each other."""

    config: RunConfig
    seed: int
    policies_id: str
    initial_genomes_id: str | None
    fingerprint: str
    steps: int
    generation_steps: list[int]
    scheduler: TimeSharingScheduler
    events: EventLog
    survival: SurvivalWorld
    vision: VisionProvider
    range_noise: RangeSensorNoise | None
    learning: LifetimeLearning | None
    controller: NeuralController
    action: ActionBuffers
    watchdog: Watchdog

    def __init__(
        self, config: RunConfig, seed: int, policies: BehaviourPolicies | None = None, *,
        backend: Backend = DEFAULT_BACKEND,
    ) -> None: ...  # fmt: skip

    def remember_docked_agents(self) -> None:
        """Note each robot's active agent as the one recharging (once, on a restored run)."""

    def close(self) -> None:
        """Release what the runner holds."""


Runner = TypeVar("Runner", bound=ResumableRun)

#: Kind prefix of run checkpoints (the method follows).
KIND_PREFIX = "evolution-run-"
_NAME = "gen_{:05d}.ckpt"
_NAME_RE = re.compile(r"^gen_(\d{5,})\.ckpt$")


# --- identities -----------------------------------------------------------------------------
def checkpoint_kind(method: str) -> str:
    """The ``kind`` recorded in a run checkpoint's header."""
    return f"{KIND_PREFIX}{method}"


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
        elif dataclasses.is_dataclass(policy) and not isinstance(policy, type):
            digest.update(repr(dataclasses.asdict(policy)).encode())
        else:
            config = getattr(policy, "config", None)
            digest.update(repr(config).encode())
    return f"{getattr(policies, 'kind', 'custom')}:{digest.hexdigest()[:16]}"


def genomes_identity(genomes: Sequence[Genome] | None) -> str | None:
    """SHA-256 of an initial population's weights (None for the random one)."""
    if genomes is None:
        return None
    digest = hashlib.sha256()
    for genome in genomes:
        digest.update(genome.weights.tobytes())
    return digest.hexdigest()



def _later_paths() -> frozenset[str]:
    return frozenset(".".join(map(str, (*path, name))) for *path, name, _ in LATER_FIELDS)


def _drop_new_defaults(run: dict[str, Any], defaults: dict[str, Any], prefix: str = "") -> None:
    """Remove from ``run`` (an ``asdict`` config, in place) every field that is neither in
    :data:`FINGERPRINT_FIELDS` nor under a ``LATER_FIELDS`` entry and holds its default (a
    section left empty goes too): a field added to the config changes no fingerprint while it
    holds its default."""
    later = _later_paths()
    for name in list(run):
        path = prefix + name
        if path in later or name not in defaults:
            continue
        value, default = run[name], defaults[name]
        if isinstance(value, dict) and isinstance(default, dict):
            _drop_new_defaults(value, default, path + ".")
            if not value and path not in FINGERPRINT_FIELDS:
                del run[name]
        elif path not in FINGERPRINT_FIELDS and value == default:
            del run[name]


def _default_record() -> dict[str, Any]:
    return dataclasses.asdict(RunConfig())


def run_fingerprint(
    config: RunConfig, seed: int, policies_id: str, genomes_id: str | None = None
) -> str:
    """What a checkpoint must match to be resumed by a run: config (its controller and inputs
    included), seed, policies and the initial population if one was given."""
    run = dataclasses.asdict(config)
    if run.get("profile", 0) is None:
        del run["profile"]  # runs without a profile keep the fingerprints they always had
    for *path, name, default in LATER_FIELDS:
        section = run
        for part in path:
            section = section.get(part, {})
        if name in section and section[name] == default:
            del section[name]  # likewise runs that leave a later field at its default
    _drop_new_defaults(run, _default_record())
    fields: dict[str, Any] = {
        "run": run,
        "seed": seed,
        "policies": policies_id,
    }
    if genomes_id is not None:
        fields["initial_genomes"] = genomes_id
    return config_fingerprint(fields)


#: The paper's inputs' names (a checkpoint without ``inputs`` was written with them).
PAPER_INPUT_NAMES = [row.name for row in PAPER_INPUTS]


def _inputs_difference(state: dict[str, Any], runner: ResumableRun) -> str:
    """"" if ``state``'s run read the inputs ``runner`` reads, else the difference in words."""
    saved = state.get("inputs", PAPER_INPUT_NAMES)
    here = [row.name for row in runner.controller.layout.inputs]
    if saved == here:
        return ""
    return f"controller inputs {saved} there, {here} here"


def _record_differences(saved: object, parsed: RunConfig) -> str:
    """The config fields in which a checkpoint's stored config (``saved``, as written) and the
    config this code reads from it (``parsed``) differ, in words: the fields this code added
    since, with their defaults, or changed."""
    here = dataclasses.asdict(parsed)
    out: list[str] = []

    def walk(there: Any, now: Any, prefix: str) -> None:
        if isinstance(there, dict) and isinstance(now, dict):
            for name in sorted(set(there) | set(now)):
                path = prefix + name
                if name not in there:
                    out.append(f"{path} (not in the checkpoint; {now[name]!r} here)")
                elif name not in now:
                    out.append(f"{path} (in the checkpoint, unknown here)")
                else:
                    walk(there[name], now[name], path + ".")
        elif (list(there) if isinstance(there, tuple | list) else there) != (
            list(now) if isinstance(now, tuple | list) else now
        ):
            out.append(f"{prefix.rstrip('.')} ({there!r} there, {now!r} here)")

    walk(saved, here, "")
    return ", ".join(out)


# --- state ----------------------------------------------------------------------------------
def runner_state(runner: ResumableRun) -> dict[str, Any]:
    """The complete state of ``runner`` as plain data (see the module docstring)."""
    noise = runner.range_noise
    return {
        "config": dataclasses.asdict(runner.config),
        "seed": runner.seed,
        "policies_id": runner.policies_id,
        "initial_genomes_id": runner.initial_genomes_id,
        "steps": runner.steps,
        "generation_steps": list(runner.generation_steps),
        "scheduler": runner.scheduler.state(),
        "events": runner.events.state(),
        "world": capture_world(runner.survival, runner.vision),
        "range_noise": None if noise is None else noise.rng.bit_generator.state,
        "learning": None if runner.learning is None else runner.learning.state(),
        "inputs": [row.name for row in runner.controller.layout.inputs],
        "wheels": runner.action.wheels.copy(),
        "watchdog": runner.watchdog.state_dict(),
    }


def restore_runner(runner: ResumableRun, state: dict[str, Any]) -> None:
    """Write a :func:`runner_state` into a runner freshly built with the same config, seed
    and policies, in place.

    Raises:
        ValueError, KeyError, TypeError, IndexError: the state does not fit the runner.
    """
    restore_world(state["world"], runner.survival, runner.vision)
    runner.scheduler.load_state(state["scheduler"])
    runner.remember_docked_agents()
    runner.events.load_state(state["events"])
    runner.steps = int(state["steps"])
    runner.generation_steps = [int(step) for step in state["generation_steps"]]
    noise, saved = runner.range_noise, state["range_noise"]
    if (noise is None) != (saved is None):
        raise ValueError("the range-sensor noise generator does not match this run's profile")
    if noise is not None:
        noise.rng.bit_generator.state = saved
    # The previous step's wheel commands (an input may read them); absent in states written
    # before any input could, whose runs never read them.
    wheels = state.get("wheels")
    if wheels is not None:
        restore_array(runner.action.wheels, wheels, "wheels")
        # The watchdog's counters (absent in states written before it: it starts afresh, which
    # changes nothing a run does unless it rescues, and no run rescued before it existed).
    watchdog = state.get("watchdog")
    if watchdog is not None:
        runner.watchdog.load_state(watchdog)
    learning, learned = runner.learning, state.get("learning")
    if (learning is None) != (learned is None):
        raise ValueError(
            "learning.enabled: the checkpoint was written in "
            f"{'learning' if learned is not None else 'fixed-behaviour'} mode"
        )
    if learning is not None and learned is not None:
        learning.load_state(learned)


# --- files ----------------------------------------------------------------------------------
def save_run(runner: ResumableRun, path: str | os.PathLike[str]) -> Path:
    """Write ``runner``'s complete state to ``path`` atomically; return the path."""
    path = Path(path)
    save_checkpoint(
        path, runner_state(runner), kind=checkpoint_kind(runner.config.method),
        fingerprint=runner.fingerprint,
    )  # fmt: skip
    return path


def load_run(
    cls: type[Runner],
    path: str | os.PathLike[str],
    policies: BehaviourPolicies,
    *,
    expect: tuple[RunConfig, int] | None = None,
    expect_initial_genomes: Sequence[Genome] | None = None,
    backend: Backend = DEFAULT_BACKEND,
) -> Runner:
    """Rebuild a runner of class ``cls`` from a run checkpoint; it continues bit-identically.

    Args:
        cls: the runner class.
        path: a checkpoint written by :func:`save_run`.
        policies: the behaviour policies the run used.
        expect: optional ``(config, seed)`` the checkpoint must belong to.
        expect_initial_genomes: with ``expect``, the initial population the run was started
            with (None: a random one).
        backend: the rebuilt runner's backend (results do not depend on it).

    Raises:
        CheckpointError: missing, truncated, corrupt, malformed or incompatible file (another
            format, MuJoCo version or layout), a different config, seed or behaviour
            policies. The file is never modified.
    """
    path = Path(path)
    header = read_header(path)
    kind = str(header.get("kind", ""))
    if not kind.startswith(KIND_PREFIX):
        raise CheckpointError(f"{path}: not an evolution run checkpoint (kind {kind!r})")
    policies_id = policy_identity(policies)
    fingerprint = None
    if expect is not None:
        config, seed = expect
        kind_expected = checkpoint_kind(config.method)
        if kind != kind_expected:
            raise CheckpointError(
                f"{path}: checkpoint is of a {kind!r} run, this run is {kind_expected!r}"
            )
        initial = list(expect_initial_genomes) if expect_initial_genomes is not None else None
        fingerprint = run_fingerprint(
            config, check_integer("seed", seed, 0), policies_id, genomes_identity(initial)
        )
    try:
        state = load_checkpoint(path, kind=kind, fingerprint=fingerprint)
    except CheckpointError as error:
        if expect is None or "fingerprint" not in str(error):
            raise
        differences = _setting_differences(path, kind, expect[0])
        if not differences:
            raise
        raise CheckpointError(
            f"{path}: checkpoint was written with a different configuration: the run was "
            f"started with other settings ({differences}); resume it with those"
        ) from None

    try:
        config = run_config_from_record(state["config"])
        seed = check_integer("seed", state["seed"], 0)
        saved_policies, genomes_id = state["policies_id"], state["initial_genomes_id"]
    except (ValueError, KeyError, TypeError) as error:
        raise CheckpointError(f"{path}: cannot read the run's config ({error!r})") from error
    if saved_policies != policies_id:
        raise CheckpointError(
            f"{path}: the run used behaviour policies {saved_policies}, got {policies_id}; "
            "resume with the same policies"
        )
    payload_fingerprint = run_fingerprint(config, seed, policies_id, genomes_id)
    if payload_fingerprint != header.get("fingerprint"):
        differences = _record_differences(state["config"], config)
        cause = (
            f"this code reads its config differently: {differences}; a config field added "
            "since must default to the behaviour before it"
            if differences
            else "the file was altered"
        )
        raise CheckpointError(
            f"{path}: header and payload disagree (config fingerprint): {cause}"
        )
    runner = cls(config, seed, policies, backend=backend)
    runner.initial_genomes_id = genomes_id
    runner.fingerprint = payload_fingerprint
    inputs = _inputs_difference(state, runner)
    if inputs:
        runner.close()
        raise CheckpointError(
            f"{path}: checkpoint was written with other controller inputs ({inputs}); resume "
            "it with those (evolution.inputs)"
        )
    try:
        restore_runner(runner, state)
    except (ValueError, KeyError, TypeError, IndexError) as error:
        runner.close()
        raise CheckpointError(f"{path}: cannot restore this checkpoint ({error!r})") from error
    return runner


def _setting_differences(path: Path, kind: str, config: RunConfig) -> str:
    """The settings in which a checkpoint's run differs from ``config``, in words ("" if it
    cannot be read or none differ: then the seed or the policies do)."""
    try:
        state = load_checkpoint(path, kind=kind)
        saved = run_config_from_record(state["config"])
    except (CheckpointError, ValueError, KeyError, TypeError):
        return ""
    there, here = settings(saved), settings(config)
    differences = [
        f"{key} = {there[key].default!r} there, {here[key].default!r} here"
        for key in here
        if key in there and there[key].default != here[key].default
    ]
    return ", ".join(differences)


def checkpoint_path(directory: str | os.PathLike[str], generation: int) -> Path:
    """The file of the checkpoint written when ``generation`` generations had completed."""
    return Path(directory) / _NAME.format(generation)


def list_checkpoints(directory: str | os.PathLike[str]) -> list[Path]:
    """Run checkpoints in ``directory``, oldest generation first."""
    directory = Path(directory)
    if not directory.is_dir():
        return []
    found = []
    for path in directory.iterdir():
        match = _NAME_RE.match(path.name)
        if match:
            found.append((int(match.group(1)), path))
    return [path for _, path in sorted(found)]


def latest_checkpoint(directory: str | os.PathLike[str]) -> Path | None:
    """The newest run checkpoint in ``directory`` (None if there is none)."""
    found = list_checkpoints(directory)
    return found[-1] if found else None


def prune_checkpoints(directory: str | os.PathLike[str], keep: int) -> None:
    """Delete all but the ``keep`` newest checkpoints (0: keep all) and stray temporaries."""
    remove_stale_temporaries(directory)
    if keep <= 0:
        return
    for path in list_checkpoints(directory)[:-keep]:
        path.unlink(missing_ok=True)


__all__ = [
    "KIND_PREFIX",
    "ResumableRun",
    "checkpoint_kind",
    "checkpoint_path",
    "genomes_identity",
    "latest_checkpoint",
    "list_checkpoints",
    "load_run",
    "policy_identity",
    "prune_checkpoints",
    "restore_runner",
    "run_fingerprint",
    "runner_state",
    "save_run",
]
