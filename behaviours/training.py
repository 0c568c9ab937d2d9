"""Train a basic behaviour with Sarsa(λ) in the physics world; resumable and bit-reproducible.

``train("forage", episodes=1500, seed=0, out_dir="runs/behaviours")`` runs Sarsa(λ) with
replacing traces over the behaviour's tile coder (:mod:`behaviours.definitions`) in its
physics episodes (:mod:`behaviours.episodes`) and writes, in ``out_dir``:

* ``<name>.npz``: the learned action values (versioned, SHA-256, loadable with
  :func:`behaviours.definitions.load_values` / ``BehaviourPolicies.from_directory``);
* ``<name>_curve.csv`` and ``<name>_curve.png``: the learning curve, one row per episode
  (return of robot 0, steps, success, steps in contact with an obstacle) and its moving
  averages;
* ``<name>_checkpoint.npz``: the resumable state (weights, every generator's state, the curve),
  written atomically (:mod:`cyber_rodent.atomic`) every ``checkpoint_every`` episodes and at
  the end, so an interrupted run resumes with ``resume=True`` and finishes with exactly the
  values an uninterrupted run would have.

Mate is trained by self-play: two robots run Mate with one shared Q table, each with its own
traces and exploration, so each learns to meet a partner that behaves as it does.

Determinism: every random draw comes from generators derived from ``seed`` (the learners'
exploration streams, and one placement stream per episode, :func:`behaviours.episodes.
episode_rng`); MuJoCo is deterministic on one machine. Same seed, same values, bit for bit.

The shipped values (``behaviours/data``) are the ``<name>.npz`` files of such a run, copied
there; their metadata records the seed and episode count.

Survival rules: ``survival=`` trains under an evolution run's rules (e.g. a 0.2 s control step;
:func:`behaviours.episodes.episode_rules`). The rules that differ from the paper's (energy aside,
which episodes never use) are part of the checkpoint's identity, so a run is never resumed under
other rules, and are recorded as ``survival`` in the values' metadata; under the paper's rules
neither carries the key, so checkpoints and values are those of earlier versions.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from behaviours.action_values import ActionValues
from behaviours.definitions import SPECS, spec, values_metadata
from behaviours.episodes import BehaviourEpisode, EpisodeConfig, episode_rng, episode_rules
from behaviours.inputs import BEHAVIOUR_NAMES
from behaviours.sarsa import SarsaConfig, SarsaLambda
from behaviours.tile_coding import TileCoder
from cyber_rodent.atomic import atomic_output
from cyber_rodent.commands import COMMAND_NAMES, N_COMMANDS
from cyber_rodent.profiles import HardwareProfile
from cyber_rodent.survival import SurvivalConfig
from cyber_rodent.tasks.spec import task_spec
from cyber_rodent.validation import integer, validate_fields

#: Episodes a full training run of each behaviour uses by default (what the shipped values
#: were trained with; :attr:`behaviours.definitions.BehaviourSpec.episodes`).
DEFAULT_EPISODES = {s.name: s.episodes for s in SPECS}
CHECKPOINT_VERSION = 2
#: Columns of the learning curve.
CURVE_COLUMNS = ("episode", "return", "steps", "success", "contacts")
_MAX_EPISODES = 10_000_000
_MAX_SEED = 2**63 - 1


@dataclass(frozen=True)
class TrainingConfig:
    """How a behaviour is trained.

    Attributes:
        sarsa: learning parameters. ``gamma`` 0.98 weighs a reward 50 steps (5 s) ahead at
            36 %, which suits goals reached within the 100-step episodes; ε 0.1 explores enough
            to find the pack or partner from every start.
        episode: the episodes (length, rewards); ``episode.gamma`` must equal ``sarsa.gamma``.
        checkpoint_every: episodes between checkpoints (≥ 1).
        curve_window: episodes in the moving average of the plotted curve (≥ 1).
    """

    sarsa: SarsaConfig = field(
        default_factory=lambda: SarsaConfig(alpha=0.1, gamma=0.98, lam=0.9, epsilon=0.1)
    )
    episode: EpisodeConfig = field(default_factory=EpisodeConfig)
    checkpoint_every: int = integer(100, 1)
    curve_window: int = integer(50, 1)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.sarsa, SarsaConfig):
            raise ValueError(f"sarsa: must be a SarsaConfig, got {type(self.sarsa).__name__}")
        if not isinstance(self.episode, EpisodeConfig):
            raise ValueError(
                f"episode: must be an EpisodeConfig, got {type(self.episode).__name__}"
            )
        if self.episode.gamma != self.sarsa.gamma:
            raise ValueError(
                f"episode.gamma: the shaping discount must equal sarsa.gamma "
                f"({self.sarsa.gamma}), got {self.episode.gamma}"
            )

    def to_dict(self) -> dict[str, Any]:
        """Plain-dict form (JSON), stored in checkpoints to refuse resuming another config."""
        return {"sarsa": asdict(self.sarsa), "episode": asdict(self.episode)}


@dataclass
class TrainingResult:
    """What :func:`train` produced.

    Attributes:
        values: the learned action values.
        curve: (episodes, 5) array of ``CURVE_COLUMNS``.
        values_path, curve_csv, curve_png, checkpoint_path: files written.
        episodes_run: episodes run by this call (0 if a resumed run was already complete).
        wall_time: seconds spent in this call.
    """

    values: ActionValues
    curve: np.ndarray
    values_path: Path
    curve_csv: Path
    curve_png: Path
    checkpoint_path: Path
    episodes_run: int
    wall_time: float


def check_episodes(episodes: object) -> int:
    """Validate an episode count.

    Raises:
        ValueError: not an integer in [1, 10,000,000] (the message names ``episodes``).
    """
    if isinstance(episodes, bool) or not isinstance(episodes, int | np.integer):
        raise ValueError(f"episodes: must be an integer in [1, {_MAX_EPISODES}], got {episodes!r}")
    if not 1 <= episodes <= _MAX_EPISODES:
        raise ValueError(f"episodes: must be in [1, {_MAX_EPISODES}], got {episodes}")
    return int(episodes)


def has_goal(behaviour: str) -> bool:
    """The behaviour's task has a goal (Forage's docking, Mate's IR exchange): its training is
    measured by the share of episodes that reach it; without one (Search), by the steps in
    contact with an obstacle."""
    return task_spec(behaviour).success is not None


def _check_seed(seed: object) -> int:
    if (
        isinstance(seed, bool)
        or not isinstance(seed, int | np.integer)
        or not 0 <= seed <= _MAX_SEED
    ):
        raise ValueError(f"seed: must be an integer in [0, 2**63 - 1], got {seed!r}")
    return int(seed)


def survival_changes(survival: SurvivalConfig | None) -> dict[str, Any]:
    """The episode rules of ``survival`` that differ from the paper's, by field (JSON values).

    Energy is left out: the episodes replace it (:func:`behaviours.episodes.episode_rules`).
    Example: ``SurvivalConfig(control_dt=0.2, initial_energy=50.0)`` gives
    ``{"control_dt": 0.2}``; the paper's rules give ``{}``.
    """
    rules, paper = asdict(episode_rules(survival)), asdict(episode_rules(None))
    changes = {name: value for name, value in rules.items() if value != paper[name]}
    result: dict[str, Any] = json.loads(json.dumps(changes))  # as a checkpoint reads it
    return result


def _learner_rngs(seed: int, n: int) -> list[np.random.Generator]:
    return [np.random.default_rng(np.random.SeedSequence([seed, 1, i])) for i in range(n)]


# --- checkpoints ---------------------------------------------------------------------------------
class CheckpointError(ValueError):
    """A training checkpoint is unreadable, damaged or belongs to another run."""


def _digest(header: str, weights: np.ndarray, curve: np.ndarray) -> str:
    h = hashlib.sha256(header.encode())
    h.update(np.ascontiguousarray(weights, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(curve, dtype="<f8").tobytes())
    return h.hexdigest()


def _write_checkpoint(
    path: Path, state: dict[str, Any], weights: np.ndarray, curve: np.ndarray
) -> None:
    header = json.dumps(state, sort_keys=True)
    with atomic_output(path) as temp, open(temp, "wb") as fh:
        np.savez(
            fh,
            weights=weights.astype("<f8"),
            curve=curve.astype("<f8"),
            header=np.array(header),
            sha256=np.array(_digest(header, weights, curve)),
        )


def _read_checkpoint(path: Path) -> tuple[dict[str, Any], np.ndarray, np.ndarray]:
    try:
        with open(path, "rb") as fh, np.load(fh, allow_pickle=False) as data:
            weights = np.array(data["weights"])
            curve = np.array(data["curve"])
            header = str(data["header"][()])
            stored = str(data["sha256"][()])
    except (OSError, ValueError, KeyError, EOFError) as err:
        raise CheckpointError(f"{path}: unreadable training checkpoint ({err})") from err
    except Exception as err:  # zipfile errors of a truncated archive
        raise CheckpointError(f"{path}: unreadable training checkpoint ({err})") from err
    if _digest(header, weights, curve) != stored:
        raise CheckpointError(f"{path}: checksum mismatch, the checkpoint is damaged")
    return json.loads(header), weights, curve


# --- curves ---------------------------------------------------------------------------------------
def _write_curve(curve: np.ndarray, csv_path: Path, png_path: Path, name: str, window: int) -> None:
    header = ",".join(CURVE_COLUMNS)
    with atomic_output(csv_path) as temp:
        np.savetxt(
            temp,
            curve,
            delimiter=",",
            header=header,
            comments="",
            fmt=["%d", "%.6g", "%d", "%d", "%d"],
        )

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels: tuple[tuple[int, str], ...]
    if has_goal(name):
        panels = ((3, "success rate"), (1, "return (robot 0)"), (2, "steps per episode"))
    else:  # no goal: the measures are return and contacts
        panels = ((1, "return (robot 0)"), (4, "steps in contact per episode"))
    fig, axes = plt.subplots(1, len(panels), figsize=(4 * len(panels), 3.2))
    w = max(1, min(window, len(curve)))
    kernel = np.ones(w) / w
    for ax, (col, label) in zip(axes, panels, strict=True):
        y = curve[:, col]
        ax.plot(curve[:, 0], y, color="0.8", lw=0.5)
        if len(y) >= w:
            ax.plot(curve[w - 1 :, 0], np.convolve(y, kernel, mode="valid"), color="C0")
        ax.set_xlabel("episode")
        ax.set_title(f"{label} (moving avg {w})", fontsize=9)
    fig.suptitle(f"{name}: Sarsa(λ) learning curve")
    fig.tight_layout()
    try:
        with atomic_output(png_path) as temp:
            fig.savefig(temp, dpi=90)
    finally:
        plt.close(fig)


# --- training -------------------------------------------------------------------------------------
def train(
    behaviour: str,
    episodes: int | None = None,
    seed: int = 0,
    out_dir: str | os.PathLike[str] = "runs/behaviours",
    resume: bool = False,
    progress: bool = True,
    config: TrainingConfig | None = None,
    profile: HardwareProfile | None = None,
    randomise: bool = False,
    survival: SurvivalConfig | None = None,
    robot: str = "cyber_rodent",
) -> TrainingResult:
    """Train one behaviour and write its values, curve and checkpoint to ``out_dir``.

    Args:
        behaviour: ``"mate"``, ``"forage"`` or ``"search"``.
        episodes: total training episodes (default ``DEFAULT_EPISODES[behaviour]``). With
            ``resume``, the run continues until this many episodes are done in total.
        seed: the run's seed; the same seed gives bit-identical values.
        out_dir: output directory (created if needed).
        resume: continue from ``<out_dir>/<name>_checkpoint.npz``.
        progress: show a tqdm progress bar (with ETA) on stderr.
        config: learning and episode settings.
        profile: optional hardware-like profile of the episodes (sim-to-real).
        randomise: domain randomisation: each episode draws its noise and actuator
            magnitudes from ``profile``'s ranges (default profile: :class:`HardwareProfile()`),
            see :mod:`behaviours.episodes`.
        survival: the survival rules of the episodes (default: the paper's); energy aside,
            every rule applies (:func:`behaviours.episodes.episode_rules`).
        robot: the body the behaviours are trained on (``WorldConfig.robot``; default the
            Cyber Rodent). Another body's behaviours need training anew on it
            (``docs/extending.md`` §9).

    Returns:
        The values and the paths written.

    Raises:
        ValueError: unknown behaviour, bad episode count or seed, ``survival`` not a
            ``SurvivalConfig``, or (``CheckpointError``) a checkpoint that is damaged or from
            another behaviour, seed, config, profile or survival rules.
        FileNotFoundError: ``resume`` without a checkpoint in ``out_dir``.
    """
    s = spec(behaviour)
    episodes = check_episodes(DEFAULT_EPISODES[behaviour] if episodes is None else episodes)
    seed = _check_seed(seed)
    config = config or TrainingConfig()
    if not isinstance(config, TrainingConfig):
        raise ValueError(f"config: must be a TrainingConfig, got {type(config).__name__}")
    rules = survival_changes(survival)  # also refuses a survival that is no SurvivalConfig
    if randomise is True and profile is None:
        profile = HardwareProfile()
    # Built before the output directory: rules the world refuses (a control step that is no
    # whole number of physics timesteps) leave nothing behind.
    env = BehaviourEpisode(
        behaviour,
        config.episode,
        profile=profile,
        randomise=randomise,
        survival=survival,
        robot=robot,
    )
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        "values": out / f"{behaviour}.npz",
        "csv": out / f"{behaviour}_curve.csv",
        "png": out / f"{behaviour}_curve.png",
        "checkpoint": out / f"{behaviour}_checkpoint.npz",
    }
    k = env.n_learners
    coder = TileCoder(s.coder)
    weights = np.zeros((N_COMMANDS, coder.table_size))
    rngs = _learner_rngs(seed, k)
    curve = np.zeros((0, len(CURVE_COLUMNS)))
    identity = {
        "version": CHECKPOINT_VERSION,
        "behaviour": behaviour,
        "seed": seed,
        "coder": s.coder.to_dict(),
        "config": config.to_dict(),
    }
    if profile is not None:  # absent otherwise: plain checkpoints keep their identity
        described = {"hardware": asdict(profile), "randomise": randomise}
        identity["profile"] = json.loads(json.dumps(described))  # as a checkpoint reads it
    if rules:  # absent under the paper's rules: earlier checkpoints keep their identity
        identity["survival"] = rules
    if robot != "cyber_rodent":  # likewise absent for the paper's robot
        identity["robot"] = robot
    start = 0
    if resume:
        if not paths["checkpoint"].is_file():
            raise FileNotFoundError(
                f"no checkpoint to resume: {paths['checkpoint']} does not exist"
            )
        state, saved_weights, curve = _read_checkpoint(paths["checkpoint"])
        for key in {**identity, "profile": None, "survival": None, "robot": None}:  # or absent
            want = identity.get(key)
            if state.get(key) != want:
                raise CheckpointError(
                    f"{paths['checkpoint']}: {key} differs from this run's "
                    f"({state.get(key)!r} vs {want!r}); use another --out or drop --resume"
                )
        if saved_weights.shape != weights.shape or curve.shape[1:] != (len(CURVE_COLUMNS),):
            raise CheckpointError(f"{paths['checkpoint']}: weights of the wrong shape")
        weights[:] = saved_weights
        for rng, rng_state in zip(rngs, state["rng_states"], strict=True):
            rng.bit_generator.state = rng_state
        start = int(state["episodes_done"])
    learners = [SarsaLambda(coder, N_COMMANDS, config.sarsa, rngs[i], weights) for i in range(k)]

    def save_checkpoint(done: int) -> None:
        state = {
            **identity,
            "episodes_done": done,
            "rng_states": [r.bit_generator.state for r in rngs],
        }
        _write_checkpoint(paths["checkpoint"], state, weights, curve[:done])

    t0 = time.perf_counter()
    rows = np.zeros((max(episodes - start, 0), len(CURVE_COLUMNS)))
    curve = np.concatenate([curve[:start], rows])
    bar = None
    if progress:
        from cyber_rodent.progress import progress_bar

        bar = progress_bar(
            total=episodes,
            initial=min(start, episodes),
            desc=f"train {behaviour}",
            unit="ep",
            dynamic_ncols=True,
        )
    try:
        actions = np.zeros(k, dtype=np.int64)
        for episode in range(start, episodes):
            states = env.reset(episode_rng(seed, episode))
            for i, learner in enumerate(learners):
                actions[i] = learner.begin_episode(states[i])
            ret = 0.0
            success = False
            contacts = 0
            for _ in range(config.episode.max_steps):
                result = env.step(actions)
                ret += float(result.rewards[0])
                contacts += int(result.collided[0])
                if result.terminal:
                    for i, learner in enumerate(learners):
                        learner.step(float(result.rewards[i]), None, terminal=True)
                    success = True
                    break
                for i, learner in enumerate(learners):
                    actions[i] = learner.step(float(result.rewards[i]), result.states[i])
            curve[episode] = (episode, ret, env.steps, success, contacts)
            done = episode + 1
            if bar is not None:
                bar.update(1)
                if done % 10 == 0:
                    recent = curve[max(0, done - 100) : done]
                    if has_goal(behaviour):
                        bar.set_postfix(success=f"{recent[:, 3].mean():.2f}")
                    else:
                        bar.set_postfix(contacts=f"{recent[:, 4].mean():.1f}")
            if done % config.checkpoint_every == 0 and done < episodes:
                save_checkpoint(done)
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    total = max(episodes, start)
    curve = curve[:total]
    save_checkpoint(total)
    values = ActionValues(
        s.coder,
        weights,
        COMMAND_NAMES,
        values_metadata(
            behaviour,
            seed=seed,
            episodes=total,
            trainer=config.to_dict(),
            **({"profile": identity["profile"]} if profile is not None else {}),
            **({"survival": rules} if rules else {}),
            **({"robot": robot} if robot != "cyber_rodent" else {}),
            **_final_training_measures(behaviour, curve),
        ),
    )
    values.save(paths["values"], compress=True)
    _write_curve(curve, paths["csv"], paths["png"], behaviour, config.curve_window)
    return TrainingResult(
        values,
        curve,
        paths["values"],
        paths["csv"],
        paths["png"],
        paths["checkpoint"],
        max(episodes - start, 0),
        wall,
    )


def _final_training_measures(behaviour: str, curve: np.ndarray) -> dict[str, float]:
    """Mean of the last 200 training episodes (ε-greedy), recorded in the values' metadata."""
    tail = curve[-200:]
    if has_goal(behaviour):
        return {"final_training_success_rate": round(float(tail[:, 3].mean()), 4)}
    return {"final_training_contacts_per_episode": round(float(tail[:, 4].mean()), 4)}


def train_all(
    episodes: int | None = None,
    seed: int = 0,
    out_dir: str | os.PathLike[str] = "runs/behaviours",
    resume: bool = False,
    progress: bool = True,
    survival: SurvivalConfig | None = None,
) -> dict[str, TrainingResult]:
    """Train every behaviour in turn (``train`` with the same arguments)."""
    return {
        name: train(
            name, episodes, seed, out_dir, resume=resume, progress=progress, survival=survival
        )
        for name in BEHAVIOUR_NAMES
    }
