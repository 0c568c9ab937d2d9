"""Embodied evolution of the Cyber Rodent survival task, and the centralised GA baseline.

The world-independent core: the genome (:class:`Genome`), the 39-weight controller
(:class:`NeuralController`), virtual agents (:class:`VirtualAgent`), the reproduction rules
(:mod:`evolution.reproduction`), the time-sharing schedulers (:class:`EmbodiedEvolution`,
:class:`CentralisedEvolution`) and the per-generation statistics (:mod:`evolution.stats`). Every
number of the paper is a field of :class:`EvolutionConfig`.
"""

from evolution.agent import MatingRecord, Origin, VirtualAgent, fitness
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

__all__ = [
    "FORAGE",
    "GENOME_LENGTH",
    "MATE",
    "NO_PARTNER",
    "SEARCH",
    "CentralisedEvolution",
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
    "default_config",
    "draw_replacement",
    "fitness",
    "make_offspring",
    "next_generation",
    "tournament",
]
