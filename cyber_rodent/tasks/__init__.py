"""The Cyber Rodent as dm-control tasks: ``Survival``, ``Forage``, ``Mate``, ``Search``.

>>> from cyber_rodent import tasks
>>> env = tasks.load("survival", seed=0)            # 4 robots, 5 packs, geometric vision
>>> env = tasks.load("forage", seed=0, vision="rendered")

Every task is a ``dm_env.Environment`` (``dm_control.rl.control.Environment``) over one
:class:`~cyber_rodent.survival.SurvivalWorld`. Shapes, observations and actions are described
in :mod:`cyber_rodent.tasks.base`; rewards in each task's docstring.
"""

from cyber_rodent.tasks.base import OBSERVATION_NAMES, CyberRodentTask
from cyber_rodent.tasks.environment import TASK_NAMES, TASKS, CyberRodentEnvironment, load
from cyber_rodent.tasks.forage import Forage
from cyber_rodent.tasks.mate import Mate
from cyber_rodent.tasks.search import Search
from cyber_rodent.tasks.survival import Survival

__all__ = [
    "OBSERVATION_NAMES",
    "TASKS",
    "TASK_NAMES",
    "CyberRodentEnvironment",
    "CyberRodentTask",
    "Forage",
    "Mate",
    "Search",
    "Survival",
    "load",
]
