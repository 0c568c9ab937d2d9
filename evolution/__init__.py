"""Embodied evolution of the Cyber Rodent survival task, and the centralised GA baseline.

The world-independent core: the genome (:class:`Genome`), the controllers (the paper's
39-weight one by default; :mod:`evolution.controllers`, their inputs
:mod:`evolution.input_kernels`) evaluated for every robot by :class:`NeuralController`, virtual
agents (:class:`VirtualAgent`), the reproduction rules (:mod:`evolution.reproduction`), the
time-sharing schedulers (:class:`EmbodiedEvolution`, :class:`CentralisedEvolution`), the
per-generation statistics (:mod:`evolution.stats`) and atomic checkpoints
(:mod:`evolution.checkpoint`). Every number of the paper is a field of :class:`EvolutionConfig`.

The physics side (:mod:`evolution.runner`) is imported on first use, so the core stays
importable without MuJoCo. The experiment tooling (one run in one call, sweeps, figures,
videos, the viewer, transfer and deployment) is :mod:`evolution.lab`, which imports this core
and is never imported by it::

    from evolution.lab import run
    table = run(method="ee", generations=5, seed=0)
"""

from typing import Any

from evolution.agent import MatingRecord, Origin, VirtualAgent, fitness
from evolution.checkpoint import (
    CheckpointError,
    config_fingerprint,
    load_checkpoint,
    save_checkpoint,
)
from evolution.config import GENOME_LENGTH, EvolutionConfig, GeneticConfig, default_config
from evolution.controller import FORAGE, MATE, SEARCH, NeuralController
from evolution.genome import Genome
from evolution.reproduction import draw_replacement, make_offspring, next_generation, tournament
from evolution.scheduler import (
    NO_PARTNER,
    CentralisedEvolution,
    EmbodiedEvolution,
    TimeSharingScheduler,
)
from evolution.stats import GenerationStats, StatisticsRecorder

#: Names served lazily from the physics-side modules (see ``__getattr__``).
_LAZY = {
    "RunConfig": "evolution.runner",
    "EvolutionRunner": "evolution.runner",
}


def __getattr__(name: str) -> Any:
    """Import the runner on first use (it pulls in MuJoCo and the behaviours)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'evolution' has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(module), name)


__all__ = [
    "EvolutionRunner",
    "RunConfig",
    "FORAGE",
    "GENOME_LENGTH",
    "MATE",
    "NO_PARTNER",
    "SEARCH",
    "CentralisedEvolution",
    "CheckpointError",
    "EmbodiedEvolution",
    "EvolutionConfig",
    "GenerationStats",
    "GeneticConfig",
    "Genome",
    "MatingRecord",
    "NeuralController",
    "Origin",
    "StatisticsRecorder",
    "TimeSharingScheduler",
    "VirtualAgent",
    "config_fingerprint",
    "default_config",
    "draw_replacement",
    "fitness",
    "load_checkpoint",
    "make_offspring",
    "next_generation",
    "save_checkpoint",
    "tournament",
]
