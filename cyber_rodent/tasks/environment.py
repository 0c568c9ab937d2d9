"""The dm_env environment of the Cyber Rodent tasks, and loading tasks by name."""

from __future__ import annotations

from typing import Any

import numpy as np
from dm_control.rl import control
from dm_env import specs

from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.tasks.base import CyberRodentTask, task_class
from cyber_rodent.tasks.spec import BUILT_IN, FORAGE, MATE, SEARCH, SURVIVAL, task_spec

#: The built-in tasks' names, in registry order (``spec.task_names()`` lists every registered
#: task, those added later too).
TASK_NAMES = BUILT_IN
#: The built-in tasks' classes by name, made from their specs (:func:`task_class`);
#: :func:`load` also finds tasks registered later.
TASKS: dict[str, type[CyberRodentTask]] = {name: task_class(task_spec(name)) for name in BUILT_IN}
Survival = task_class(SURVIVAL)
Forage = task_class(FORAGE)
Mate = task_class(MATE)
Search = task_class(SEARCH)


class CyberRodentEnvironment(control.Environment):  # type: ignore[misc]  # dm_control: no hints
    """``dm_control.rl.control.Environment`` with the Cyber Rodent conventions.

    * One control step is ``SurvivalConfig.control_dt`` (0.2 s) of physics substeps, stepped
      with plain ``mj_step`` (``legacy_step=False``), exactly as the lean path steps them.
    * Episodes last ``task.episode_steps`` control steps, counted as an integer (a time limit
      in seconds would be divided by a float timestep and could be off by one step).
    * The reward is an array, one entry per controlled robot (:meth:`reward_spec`).
    """

    def __init__(self, task: CyberRodentTask):
        super().__init__(
            task.physics,
            task,
            n_sub_steps=task.survival.n_substeps,
            legacy_step=False,
        )
        self._step_limit = task.episode_steps

    def reward_spec(self) -> specs.Array:
        return self._task.reward_spec()

    def close(self) -> None:
        """Release the task's vision now (a rendered task's GL context); idempotent."""
        task: CyberRodentTask = self._task
        close = getattr(task.vision, "close", None)  # not every provider holds resources
        if close is not None:
            close()

    @property
    def survival(self) -> SurvivalWorld:
        """The :class:`~cyber_rodent.survival.SurvivalWorld` under the task."""
        task: CyberRodentTask = self._task
        return task.survival


def load(
    name: str, seed: int | np.random.Generator | None = None, **options: Any
) -> CyberRodentEnvironment:
    """Create the task ``name`` as a ``dm_env`` environment.

    Args:
        name: a registered task (:mod:`cyber_rodent.tasks.spec`): ``"survival"``,
            ``"forage"``, ``"mate"``, ``"search"`` or one added with ``register``
            (case-insensitive).
        seed: an integer seed or a ``np.random.Generator``; the same seed gives the same
            initial states and, for the same actions, the same trajectories. ``None`` draws
            fresh entropy from the OS.
        **options: task options, e.g. ``vision="rendered"``, ``n_robots=...``,
            ``episode_steps=...``, ``survival=SurvivalConfig(...)``, the reward's scales; see
            :class:`~cyber_rodent.tasks.base.CyberRodentTask`.

    Raises:
        ValueError: for an unknown task name or option (the message lists the allowed ones)
            or an invalid option value.
    """
    cls = task_class(task_spec(name))
    allowed = cls.option_names()
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ValueError(
            f"unknown option(s) {unknown} for task {name!r}; allowed options: {', '.join(allowed)}"
        )
    if isinstance(seed, np.random.Generator):
        rng = seed
    elif seed is None or (isinstance(seed, int | np.integer) and not isinstance(seed, bool)):
        if seed is not None and seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        rng = np.random.default_rng(seed)
    else:
        raise ValueError(f"seed must be an integer, a numpy Generator or None, got {seed!r}")
    return CyberRodentEnvironment(cls(rng, **options))
