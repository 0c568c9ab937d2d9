"""The Cyber Rodent as dm-control tasks: ``Survival``, ``Forage``, ``Mate``, ``Search``.

>>> from cyber_rodent import tasks
>>> env = tasks.load("survival", seed=0)            # 4 robots, 5 packs, geometric vision
>>> env = tasks.load("forage", seed=0, vision="rendered")

Every task is defined once, as a :class:`~cyber_rodent.tasks.spec.TaskSpec` in the registry
of :mod:`cyber_rodent.tasks.spec` (its rewards' terms in :mod:`cyber_rodent.tasks.rewards`); the
dm-control tasks, the Gymnasium environments, the PettingZoo colony and the behaviours' episodes
all read it, and all run it through one episode loop, :class:`~cyber_rodent.tasks.episode.
TaskEpisode` (reset with the start draws, step, termination, reward terms, observation), of
which each interface is a thin adapter. Every task is a ``dm_env.Environment``
(``dm_control.rl.control.Environment``) over one :class:`~cyber_rodent.survival.SurvivalWorld`.
Shapes, observations and actions are described in :mod:`cyber_rodent.tasks.base`. The tasks'
names come from the registry alone: :func:`task_names`.
"""

from cyber_rodent.tasks.base import OBSERVATION_NAMES, CyberRodentTask, task_class
from cyber_rodent.tasks.environment import (
    TASK_NAMES,
    TASKS,
    CyberRodentEnvironment,
    Forage,
    Mate,
    Search,
    Survival,
    load,
)
from cyber_rodent.tasks.episode import EpisodeStep, TaskEpisode
from cyber_rodent.tasks.spec import TaskSpec, register, task_names, task_spec, unregister

__all__ = [
    "OBSERVATION_NAMES",
    "TASKS",
    "TASK_NAMES",
    "CyberRodentEnvironment",
    "CyberRodentTask",
    "EpisodeStep",
    "Forage",
    "Mate",
    "Search",
    "Survival",
    "TaskEpisode",
    "TaskSpec",
    "load",
    "register",
    "task_class",
    "task_names",
    "task_spec",
    "unregister",
]
