"""Stable-Baselines3's DQN and PPO, with the library's defaults, learn Forage from the
Gymnasium environment alone, next to the shipped Sarsa(λ).

Usage::

    .venv/bin/python -m benchmarks.sb3_forage                  # the committed curves
    .venv/bin/python -m benchmarks.sb3_forage --algo ppo --steps 20000 --eval-episodes 50

A client no one here wrote, using only the public interfaces, as a new user would:
``DQN("MlpPolicy", env)`` and ``PPO("MlpPolicy", env)`` with every hyperparameter at the
library's default (only the seed and the CPU are given), on ``env =
gymnasium.make("CyberRodent/Forage-v0", action="discrete", reward="shaped")``
(docs/rl_interfaces.md), with no wrapper: the observation is normalised to [0, 1] by the
environment. The reward is the one the shipped Sarsa(λ) Forage policy was trained with. One
torch thread on the CPU; the algorithms run one after the other.

Every ``--eval-every`` environment steps the current policy acts deterministically on the
evaluation episodes of ``behaviours.evaluation.evaluate``: episode ``k`` starts from the
placement of ``episode_rng(eval_seed + EVALUATION_SEED_OFFSET, k)`` (a pack in view), and
succeeds by docking within the episode's 100 control steps. The shipped Sarsa(λ) policy is
measured in the same run on the same episodes (``evaluate``, as ``benchmarks/behaviours.py``
does), and the script checks that both start every episode from the same placement. Nothing
is tuned on these episodes: they only measure.

Writes the learning curves (algorithm, environment steps, success rate, median steps to dock,
wall seconds, and the Sarsa(λ) policy's numbers on every row) to ``--out`` (CSV) and a plot to
``--figure`` (PNG), with the Sarsa(λ) policy as a horizontal line, and prints for each
algorithm the first evaluation at which it docked in at least 90 % of the episodes.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

# Run as a script (``python benchmarks/sb3_forage.py``), this file's directory comes first on
# sys.path and ``benchmarks/behaviours.py`` would shadow the ``behaviours`` package: drop it.
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import cyber_rodent  # noqa: E402, F401  (registers the CyberRodent/* ids)
from behaviours.definitions import load_values  # noqa: E402
from behaviours.episodes import BehaviourEpisode, coverage_cells, episode_rng  # noqa: E402
from behaviours.evaluation import (  # noqa: E402
    EVALUATION_SEED_OFFSET,
    EvaluationResult,
    evaluate,
)
from behaviours.greedy_policy import GreedyPolicy  # noqa: E402
from cyber_rodent.atomic import atomic_output, write_text  # noqa: E402

ENV_ID = "CyberRodent/Forage-v0"
ENV_KWARGS: dict[str, Any] = {"action": "discrete", "reward": "shaped"}
ALGORITHMS = ("dqn", "ppo")
#: The success rate the curves are read at (the first evaluation reaching it).
TARGET_SUCCESS = 0.9
COLUMNS = (
    "algo",
    "env_steps",
    "success_rate",
    "median_steps_to_dock",
    "train_wall_s",
    "wall_s",
    "sarsa_success_rate",
    "sarsa_median_steps_to_dock",
)
CSV_OUT = Path("results/sb3_forage.csv")
FIGURE_OUT = Path("docs/images/sb3_forage.png")


def make_env() -> gym.Env[np.ndarray, Any]:
    """The training and evaluation environment: Forage as ``gymnasium.make`` builds it."""
    return gym.make(ENV_ID, **ENV_KWARGS)


def reset_to_evaluation_episode(
    env: gym.Env[np.ndarray, Any], episode: int, eval_seed: int
) -> np.ndarray:
    """Start evaluation episode ``episode``: the placement ``behaviours.evaluation`` draws."""
    env.unwrapped.np_random = episode_rng(eval_seed + EVALUATION_SEED_OFFSET, episode)
    obs, _ = env.reset()  # no seed: the reset draws from the generator just set
    return obs


def check_same_starts(env: gym.Env[np.ndarray, Any], episodes: int, eval_seed: int) -> None:
    """Raise unless every evaluation episode starts as in ``behaviours.evaluation.evaluate``."""
    reference = BehaviourEpisode("forage")
    for e in range(episodes):
        reference.reset(episode_rng(eval_seed + EVALUATION_SEED_OFFSET, e))
        reset_to_evaluation_episode(env, e, eval_seed)
        world = env.unwrapped.world  # type: ignore[attr-defined]
        if not np.array_equal(world.poses(), reference.world.poses()):
            raise RuntimeError(f"evaluation episode {e}: the Gymnasium start differs")


def evaluate_model(
    model: Any, env: gym.Env[np.ndarray, Any], episodes: int, eval_seed: int
) -> EvaluationResult:
    """The model's deterministic policy on the evaluation episodes (``evaluate``'s measures)."""
    max_steps = env.unwrapped.episode.max_steps  # type: ignore[attr-defined]
    world = env.unwrapped.world  # type: ignore[attr-defined]
    success = np.zeros(episodes, dtype=bool)
    steps = np.zeros(episodes, dtype=np.int64)
    contacts = np.zeros(episodes, dtype=np.int64)
    cells = np.zeros(episodes, dtype=np.int64)
    positions = np.zeros((max_steps + 1, 2))
    for e in range(episodes):
        obs = reset_to_evaluation_episode(env, e, eval_seed)
        positions[0] = world.poses()[0, :2]
        n = 0
        terminated = truncated = False
        while not (terminated or truncated):
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(int(action))
            n += 1
            contacts[e] += info["collided"]
            positions[n] = world.poses()[0, :2]
        success[e] = terminated
        steps[e] = n
        cells[e] = coverage_cells(positions[: n + 1])
    return EvaluationResult("forage", "sb3", success, steps, contacts, cells)


@dataclass
class CurvePoint:
    """One evaluation of the learner."""

    algo: str
    env_steps: int
    success_rate: float
    median_steps_to_dock: float
    train_wall_s: float
    wall_s: float


def make_model(algo: str, seed: int) -> Any:
    """A fresh DQN or PPO learner with the library's default hyperparameters."""
    from stable_baselines3 import DQN, PPO

    learner = {"dqn": DQN, "ppo": PPO}[algo]
    return learner("MlpPolicy", make_env(), seed=seed, device="cpu")


def learning_curve(
    algo: str, steps: int, eval_every: int, eval_episodes: int, seed: int, eval_seed: int
) -> list[CurvePoint]:
    """Train for ``steps`` environment steps, evaluating at 0 and every ``eval_every``."""
    from stable_baselines3.common.callbacks import BaseCallback

    model = make_model(algo, seed)
    eval_env = make_env()
    check_same_starts(eval_env, eval_episodes, eval_seed)
    points: list[CurvePoint] = []
    start = time.perf_counter()
    eval_time = 0.0

    def measure(env_steps: int) -> None:
        nonlocal eval_time
        t0 = time.perf_counter()
        result = evaluate_model(model, eval_env, eval_episodes, eval_seed)
        eval_time += time.perf_counter() - t0
        wall = time.perf_counter() - start
        points.append(
            CurvePoint(
                algo,
                env_steps,
                result.success_rate,
                result.median_steps_to_goal,
                wall - eval_time,
                wall,
            )
        )
        print(
            f"  {algo.upper()} {env_steps:8d} steps: docked "
            f"{100 * result.success_rate:5.1f} %, median "
            f"{result.median_steps_to_goal:5.1f} steps to dock ({wall:.0f} s)",
            flush=True,
        )

    class Evaluations(BaseCallback):
        """Evaluate whenever another ``eval_every`` environment steps have been taken."""

        def _on_step(self) -> bool:
            if self.num_timesteps >= len(points) * eval_every:
                measure(self.num_timesteps)
            return True

    measure(0)
    model.learn(total_timesteps=steps, callback=Evaluations())
    if points[-1].env_steps < steps:  # the last evaluation fell short of the budget
        measure(model.num_timesteps)
    eval_env.close()
    return points


def write_curve(
    points: Sequence[CurvePoint], sarsa: EvaluationResult, path: Path
) -> None:
    """The curve as CSV, the Sarsa(λ) policy's numbers repeated on every row."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(COLUMNS)
    for p in points:
        writer.writerow(
            [
                p.algo,
                p.env_steps,
                f"{p.success_rate:.4g}",
                f"{p.median_steps_to_dock:.4g}",
                f"{p.train_wall_s:.1f}",
                f"{p.wall_s:.1f}",
                f"{sarsa.success_rate:.4g}",
                f"{sarsa.median_steps_to_goal:.4g}",
            ]
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, buffer.getvalue())


def steps_to_target(points: Sequence[CurvePoint], target: float = TARGET_SUCCESS) -> int | None:
    """The environment steps of the first evaluation docking in at least ``target`` of the
    episodes (None if none did)."""
    return next((p.env_steps for p in points if p.success_rate >= target), None)


#: Each algorithm's colour in the figure.
COLOURS = {"dqn": "#1f5fa8", "ppo": "#2a9d3f"}


@dataclass
class Reference:
    """The shipped Sarsa(λ) policy's numbers on the evaluation episodes."""

    success_rate: float
    median_steps_to_goal: float
    episodes: int


def read_curves(path: Path, episodes: int) -> tuple[dict[str, list[CurvePoint]], Reference]:
    """The curves and the Sarsa(λ) numbers of a CSV written by :func:`write_curve`."""
    curves: dict[str, list[CurvePoint]] = {}
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        curves.setdefault(row["algo"], []).append(
            CurvePoint(
                row["algo"],
                int(row["env_steps"]),
                float(row["success_rate"]),
                float(row["median_steps_to_dock"]),
                float(row["train_wall_s"]),
                float(row["wall_s"]),
            )
        )
    first = rows[0]
    reference = Reference(
        float(first["sarsa_success_rate"]), float(first["sarsa_median_steps_to_dock"]), episodes
    )
    return curves, reference


def plot_curves(
    curves: dict[str, list[CurvePoint]], sarsa: EvaluationResult | Reference, path: Path
) -> None:
    """Success rate and median steps to dock against environment steps, one line per
    algorithm, Sarsa(λ) as dashed lines."""
    from evolution.lab.figures import styled_pyplot

    plt = styled_pyplot()
    episodes = sarsa.episodes
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.0, 6.0), sharex=True)
    for algo, points in curves.items():
        x = np.array([p.env_steps for p in points]) / 1000
        label = f"{algo.upper()} (Stable-Baselines3 defaults)"
        colour = COLOURS.get(algo)
        top.plot(x, [100 * p.success_rate for p in points], "o-", ms=3.5, color=colour,
                 label=label)  # fmt: skip
        bottom.plot(x, [p.median_steps_to_dock for p in points], "o-", ms=3.5, color=colour,
                    label=label)  # fmt: skip
    top.axhline(
        100 * sarsa.success_rate,
        color="#d1261f",
        ls="--",
        label=f"shipped Sarsa(λ): {100 * sarsa.success_rate:.1f} %",
    )
    top.axhline(100 * TARGET_SUCCESS, color="0.45", ls=":", lw=1.2,
                label=f"{100 * TARGET_SUCCESS:.0f} %")  # fmt: skip
    top.set_ylim(-2, 102)
    top.set_ylabel("docked within 100 steps, %")
    top.set_title(f"Forage-v0, shaped reward: {episodes} evaluation episodes per point")
    top.legend(loc="lower right")
    top.grid(alpha=0.3)
    bottom.axhline(
        sarsa.median_steps_to_goal,
        color="#d1261f",
        ls="--",
        label=f"shipped Sarsa(λ): {sarsa.median_steps_to_goal:g}",
    )
    bottom.set_ylim(bottom=0)
    bottom.set_ylabel("median steps to dock\n(docking episodes)")
    bottom.set_xlabel("environment steps (thousands)")
    bottom.legend(loc="upper right")
    bottom.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as temp:
        fig.savefig(temp, bbox_inches="tight")
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> dict[str, list[CurvePoint]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--algo", choices=(*ALGORITHMS, "both"), default="both",
        help="the learner(s), one after the other",
    )  # fmt: skip
    parser.add_argument("--steps", type=int, default=100_000, help="environment steps to train")
    parser.add_argument("--eval-every", type=int, default=5_000, help="steps between evals")
    parser.add_argument("--eval-episodes", type=int, default=200, help="evaluation episodes")
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    parser.add_argument(
        "--eval-seed", type=int, default=0,
        help="evaluation seed (0: the episodes of benchmarks/behaviours.py)",
    )  # fmt: skip
    parser.add_argument("--out", type=Path, default=CSV_OUT, help="learning curves, CSV")
    parser.add_argument("--figure", type=Path, default=FIGURE_OUT, help="learning curves, PNG")
    parser.add_argument(
        "--replot", action="store_true",
        help="only redraw --figure from the curves in --out (--eval-episodes: their episodes)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    for name in ("steps", "eval_every", "eval_episodes"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    algorithms = ALGORITHMS if args.algo == "both" else (args.algo,)
    if args.replot:
        curves, reference = read_curves(args.out, args.eval_episodes)
        plot_curves(curves, reference, args.figure)
        print("wrote", args.figure)
        return curves

    import torch

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    sarsa = evaluate(
        "forage",
        GreedyPolicy(load_values("forage", None)),
        args.eval_episodes,
        seed=args.eval_seed,
        label="sarsa",
    )
    print(
        f"shipped Sarsa(λ) Forage: docked {100 * sarsa.success_rate:.1f} % of "
        f"{args.eval_episodes} episodes, median {sarsa.median_steps_to_goal:g} steps "
        f"({time.perf_counter() - t0:.0f} s)",
        flush=True,
    )
    curves: dict[str, list[CurvePoint]] = {}
    for algo in algorithms:
        print(f"training {algo.upper()} for {args.steps} environment steps ...", flush=True)
        curves[algo] = learning_curve(
            algo, args.steps, args.eval_every, args.eval_episodes, args.seed, args.eval_seed
        )
    write_curve([p for points in curves.values() for p in points], sarsa, args.out)
    plot_curves(curves, sarsa, args.figure)
    for algo, points in curves.items():
        last = points[-1]
        median = "—" if math.isnan(last.median_steps_to_dock) else f"{last.median_steps_to_dock:g}"
        reached = steps_to_target(points)
        first = "never" if reached is None else f"first at {reached} steps"
        print(
            f"{algo.upper()} after {last.env_steps} steps: docked {100 * last.success_rate:.1f} %"
            f" (median {median} steps); >= {100 * TARGET_SUCCESS:.0f} % {first}; "
            f"Sarsa(λ) {100 * sarsa.success_rate:.1f} %; {last.wall_s:.0f} s"
        )
    print("wrote", args.out, args.figure)
    return curves


if __name__ == "__main__":
    main()
