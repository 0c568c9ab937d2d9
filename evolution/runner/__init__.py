"""The evolution runner: EE and CE wired to the physics world.

:class:`EvolutionRunner` steps a :class:`~cyber_rodent.survival.SurvivalWorld` with every
robot's active virtual agent in control, feeds the events to the time-sharing scheduler, records
the paper's statistics and an event log, and writes atomic, bit-identically resumable
checkpoints. :func:`evolution.lab.api.run` wraps it in one call.
"""

from evolution.config import METHODS
from evolution.runner.checkpoints import (
    checkpoint_kind,
    latest_checkpoint,
    list_checkpoints,
    policy_identity,
    run_fingerprint,
)
from evolution.runner.config import RunConfig, run_config_from_record
from evolution.runner.events import EventKind, EventLog
from evolution.runner.perception import Perception
from evolution.runner.step import EvolutionRunner, default_policies

__all__ = [
    "METHODS",
    "EventKind",
    "EventLog",
    "EvolutionRunner",
    "Perception",
    "RunConfig",
    "checkpoint_kind",
    "default_policies",
    "latest_checkpoint",
    "list_checkpoints",
    "policy_identity",
    "run_config_from_record",
    "run_fingerprint",
]
