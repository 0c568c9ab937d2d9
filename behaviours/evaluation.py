"""Measure a behaviour policy in the physics world: docking, mating and obstacle avoidance.

One function, :func:`evaluate`, runs seeded episodes (:mod:`behaviours.episodes`) with a policy
acting on every learner robot and reports, per episode, whether the goal was reached and in how
many steps, how many steps the robot spent touching an obstacle, and how much of the field it
covered. Episode ``k`` of a seed has the same start placement for every policy, so the learned,
the random and the reactive policy are compared on identical starts.

The issue's measures:

* **Forage**: share of episodes (each starting with a pack in view) that dock within 100
  control steps; median steps to dock over the docking episodes.
* **Mate**: share of episodes (two Mate-running robots starting in view of each other) with an
  IR exchange within 100 steps.
* **Search**: obstacle contacts per 1,000 steps (steps at whose end robot 0's body touches a
  wall, pack or robot) and the area covered per episode (distinct 10 cm cells visited by its
  centre, in m²).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from behaviours.episodes import (
    COVERAGE_CELL,
    BehaviourEpisode,
    EpisodeConfig,
    coverage_cells,
    episode_rng,
    random_commands,
)
from behaviours.inputs import behaviour_index
from behaviours.policies import CommandPolicy

#: The issue's quality measures, as rows (behaviour, label, key of ``EvaluationResult.summary``,
#: shown as a percentage): one definition for every benchmark table that reports them.
MEASURES: tuple[tuple[str, str, str, bool], ...] = (
    ("forage", "dock rate within 100 steps", "success_rate", True),
    ("forage", "median steps to dock", "median_steps_to_goal", False),
    ("mate", "IR exchange within 100 steps", "success_rate", True),
    ("mate", "median steps to exchange", "median_steps_to_goal", False),
    ("search", "contacts per 1000 steps", "contacts_per_1000_steps", False),
    ("search", "area covered per episode m²", "area_covered_m2", False),
)

#: Offset between evaluation and training placement streams: evaluation episodes are never
#: training episodes, whatever the seeds.
EVALUATION_SEED_OFFSET = 1_000_003


@dataclass
class EvaluationResult:
    """Per-episode outcomes of one policy.

    Attributes:
        behaviour: the behaviour's name.
        policy: label of the policy.
        success: (episodes,) bool, goal reached (dock / IR exchange) within ``max_steps``.
        steps: (episodes,) int, steps run (to the goal, or ``max_steps``).
        contacts: (episodes,) int, steps ending with robot 0 touching an obstacle.
        cells: (episodes,) int, distinct ``COVERAGE_CELL`` squares visited by robot 0.
    """

    behaviour: str
    policy: str
    success: np.ndarray
    steps: np.ndarray
    contacts: np.ndarray
    cells: np.ndarray

    @property
    def episodes(self) -> int:
        return len(self.success)

    @property
    def success_rate(self) -> float:
        """Share of episodes that reached the goal."""
        return float(self.success.mean())

    @property
    def median_steps_to_goal(self) -> float:
        """Median steps of the successful episodes (NaN if none)."""
        hit = self.steps[self.success]
        return float(np.median(hit)) if hit.size else float("nan")

    @property
    def contacts_per_1000_steps(self) -> float:
        """Obstacle contacts per 1,000 control steps."""
        return 1000.0 * float(self.contacts.sum()) / max(1, int(self.steps.sum()))

    @property
    def area_covered(self) -> float:
        """Mean area covered per episode, m²."""
        return float(self.cells.mean()) * COVERAGE_CELL**2

    def summary(self) -> dict[str, object]:
        """Plain-dict summary (JSON-safe)."""
        return {
            "behaviour": self.behaviour,
            "policy": self.policy,
            "episodes": self.episodes,
            "success_rate": self.success_rate,
            "median_steps_to_goal": self.median_steps_to_goal,
            "contacts_per_1000_steps": self.contacts_per_1000_steps,
            "area_covered_m2": self.area_covered,
            "mean_steps": float(self.steps.mean()),
        }


def evaluate(
    behaviour: str,
    policy: CommandPolicy | str,
    episodes: int,
    seed: int = 0,
    config: EpisodeConfig | None = None,
    env: BehaviourEpisode | None = None,
    label: str | None = None,
) -> EvaluationResult:
    """Run ``episodes`` seeded episodes of ``behaviour`` with ``policy``.

    Args:
        behaviour: ``"mate"``, ``"forage"`` or ``"search"``.
        policy: an object with ``act(states) -> commands`` (e.g. a ``GreedyPolicy`` or a
            reactive policy), or ``"random"`` for uniformly random commands.
        episodes: number of episodes (≥ 1).
        seed: placement seed (the random policy's draws are seeded from it too).
        config: episode settings (default ``EpisodeConfig()``: 100 steps).
        env: reuse an existing episode world of this behaviour (saves building one).
        label: name of the policy in the result.

    Raises:
        ValueError: unknown behaviour or policy name, or ``episodes`` < 1.
    """
    behaviour_index(behaviour)
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes: must be an integer >= 1, got {episodes!r}")
    if isinstance(policy, str):
        if policy != "random":
            raise ValueError(f"policy: must be a policy object or 'random', got {policy!r}")
        random_rng = np.random.default_rng(np.random.SeedSequence([seed, 2]))
        act = None
        label = label or "random"
    else:
        act = policy.act
        label = label or type(policy).__name__
    if env is None:
        env = BehaviourEpisode(behaviour, config)
    elif env.name != behaviour:
        raise ValueError(f"env: an episode world of {env.name!r}, not {behaviour!r}")
    max_steps = env.config.max_steps
    success = np.zeros(episodes, dtype=bool)
    steps = np.zeros(episodes, dtype=np.int64)
    contacts = np.zeros(episodes, dtype=np.int64)
    cells = np.zeros(episodes, dtype=np.int64)
    positions = np.zeros((max_steps + 1, 2))
    for e in range(episodes):
        states = env.reset(episode_rng(seed + EVALUATION_SEED_OFFSET, e))
        positions[0] = env.position()
        n_contacts = 0
        for t in range(max_steps):
            commands = random_commands(random_rng, env.n_learners) if act is None else act(states)
            result = env.step(commands)
            states = result.states
            n_contacts += int(result.collided[0])
            positions[t + 1] = env.position()
            if result.terminal:
                success[e] = True
                break
        steps[e] = env.steps
        contacts[e] = n_contacts
        cells[e] = coverage_cells(positions[: env.steps + 1])
    return EvaluationResult(behaviour, label, success, steps, contacts, cells)
