"""Behaviour episodes in the physics world: where the behaviours are trained and measured.

The paper trains the basic behaviours "in the same environmental setting used for the
evolutionary experiments" (§3.4). An episode here runs on the evolution runner's own lean path:
a :class:`~cyber_rodent.survival.SurvivalWorld` (MuJoCo physics, docking by teeth/electrode
contact, IR mating) and the geometric vision provider, stepped one control step
(``SurvivalConfig.control_dt``, 0.2 s by default) at a time with the discrete wheel commands. The
episode loop is the one every task interface runs (:class:`~cyber_rodent.tasks.episode.
TaskEpisode`: the dm-control tasks, the Gymnasium and PettingZoo environments): reset with the
start draws, step, termination, the release of a docking, the reward's terms. A
:class:`BehaviourEpisode` adds the behaviours' inputs and the hardware-like profiles; it drives
the world directly, without dm-control, because training needs hundreds of thousands of steps
and the episode loop is then the only overhead.

Episode settings: the task of the behaviour's name, as its spec declares it
(:mod:`cyber_rodent.tasks.spec`, which the dm-control tasks and the Gymnasium environments read
too): its field, learners, start condition, success, the robots' switches, whether a docking is
released at once, the episode length (``EpisodeConfig.max_steps``, the spec's by default) and
the shaped reward's terms:

* **Forage**: 1 robot, 5 packs; the start placement is re-drawn until the robot sees a pack. It
  ends with success when the robot docks (a capture, as the survival world defines it).
* **Mate**: 2 robots, no packs, both LEDs on, both running Mate (both signal mating); the start
  is re-drawn until each sees the other's LED or face. It ends with success at the first IR
  exchange (by default ports facing within ±15° at ≤ 0.35 m for 2 steps; ``SurvivalConfig``'s
  ``mate_angle_deg``, ``mate_distance`` and ``mate_consecutive_steps``).
* **Search**: 4 robots (3 parked: wheels stopped, LEDs off), 5 packs; any start. It never ends
  early. A robot that docks by accident is released at once (recharging is not Search's job).

An episode ends at the goal or after ``max_steps``; with endless energy no robot dies.

**Hardware-like episodes** (sim-to-real, :mod:`cyber_rodent.profiles`): with a
:class:`~cyber_rodent.profiles.HardwareProfile` every episode adds IR range noise and dropouts,
camera noise and missed detections, and per-robot actuator differences; with the field part on,
Forage and Search use the hardware's 6 packs and Search its 3 robots (Mate keeps 2 robots, no
packs: :meth:`~cyber_rodent.tasks.spec.TaskSpec.hardware_field`). The hardware has one weak
robot among ``field.n_robots``: each episode draws which of them the learner is, so about one
episode in three runs on the weak robot. With
``randomise=True`` each episode also draws the magnitudes from the profile's ranges
(:func:`cyber_rodent.profiles.randomised`): domain randomisation for training. The profile's
draws come from a child of the episode's generator (``rng.spawn``), so the placements are those
of the plain episodes and two policies evaluated with one seed still see the same starts.

Energy plays no part in a behaviour episode, so robots start with enough energy never to die
(``initial_energy = max_energy = 1e6``); every other rule is the survival world's, the paper's by
default or those of an evolution run (``survival=``, :func:`episode_rules`): the behaviours are
then trained under the rules they will act under. The control step sets the physics substeps per
step and Search's reference step ``reference_speed · control_dt``; episode lengths
(``max_steps``) and the discount stay counted in control steps, so a longer control step makes an
episode last longer in simulated time.

Every episode draws its placement from its own generator, derived from ``(seed, episode)``
(:func:`episode_rng`), so episode ``k`` of a run is the same placement whatever happened before:
two policies evaluated with one seed see the same starts (a paired comparison), and a resumed
training run continues exactly where it stopped.

Rewards (per robot, per control step; ``γ`` is the learner's discount): the task's shaped reward,
its terms defined, with :class:`EpisodeConfig` and :func:`episode_rules`, in
:mod:`cyber_rodent.tasks.rewards`, which the Gymnasium environments share:

* **Forage**: ``goal_reward`` (1) at the step the robot docks (terminal), minus ``step_cost``
  (0.02) on every step, plus the potential-based shaping term ``γ Φ(s') − Φ(s)`` with
  ``Φ(s) = −shaping · d(s)``, ``d`` the normalised distance of the nearest pack (1 when none is
  seen), and ``Φ = 0`` at the terminal state. Shaping of this form leaves the optimal policy
  unchanged (Ng, Harada & Russell 1999) but tells the learner from the first episode that
  closing in on a pack is progress and losing sight of it is not; the step cost makes standing
  still (or pushing into a wall) worse than any way to the goal. Example (γ = 0.98, scale 1): a
  step from d = 0.30 to 0.28 without docking earns ``0.98·(−0.28) + 0.30 − 0.02 = 0.0056``;
  docking from d = 0.05 earns ``0 + 0.05 − 0.02 + 1 = 1.03``.
* **Mate**: the same for each of the two robots, with ``d`` the normalised distance of the
  other robot's LED (or face) and the goal the IR exchange (terminal for both).
* **Search**: forward progress minus a collision penalty, as the dm-control ``Search`` task:
  ``clip(p / (reference_speed · dt), −1, 1) − collision_penalty · c``, ``p`` the displacement
  of the robot's centre along its heading at the start of the step, ``c = 1`` when its body
  touches a wall, a pack or a robot at the end of the step. Driving straight at
  ``reference_speed`` in free space earns 1 per step; spinning earns 0; pushing into a wall
  earns at most −penalty. ``collision_penalty`` is 3 here, not the task's default 1: with 1,
  a few more steps of progress before a bump paid off, and the learned policy touched
  obstacles about 3× as often (74 vs 27 contacts per 1,000 steps after 800 episodes).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from behaviours.inputs import behaviour_index, behaviour_inputs, search_inputs
from cyber_rodent.commands import N_COMMANDS, command_speeds
from cyber_rodent.profiles import (
    HardwareProfile,
    RangeSensorNoise,
    apply_actuators,
    apply_vision,
    randomised,
)
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.tasks.episode import EpisodeOptions, TaskEpisode
from cyber_rodent.tasks.rewards import (
    COVERAGE_CELL,
    EpisodeConfig,
    RewardScales,
    coverage_cells,
    episode_rules,
    search_reward,
    shaping_reward,
)
from cyber_rodent.tasks.spec import task_spec
from cyber_rodent.vision import CameraConfig, VisionFrame, make_provider
from cyber_rodent.world import World, WorldConfig


def episode_rng(seed: int, episode: int) -> np.random.Generator:
    """The placement generator of episode ``episode`` of a run with ``seed``."""
    return np.random.default_rng(np.random.SeedSequence([seed, episode, 0x5EED]))


@dataclass
class StepResult:
    """What one episode step returns.

    Attributes:
        states: (k, 2) the learners' next inputs in [0, 1].
        rewards: (k,) reward of the step, per learner.
        terminal: the episode reached its goal (a true terminal state).
        collided: (k,) the learners' bodies touch an obstacle (for Search's statistics).
    """

    states: np.ndarray
    rewards: np.ndarray
    terminal: bool
    collided: np.ndarray


class BehaviourEpisode:
    """Episodes of one behaviour in its physics world (see the module docstring).

    Args:
        behaviour: ``"mate"``, ``"forage"`` or ``"search"``.
        config: episode settings (default: ``EpisodeConfig`` with the task's episode length).
        timestep: physics timestep, s (default ``WorldConfig``'s).
        profile: optional hardware-like profile (see the module docstring).
        randomise: draw the profile's magnitudes anew each episode (needs ``profile``).
        survival: the survival rules (default: the paper's); their energy fields are replaced
            by endless energy (:func:`episode_rules`).
        robot: the robots' kind (``WorldConfig.robot``; default the Cyber Rodent): its sensors,
            its proximity inputs and its scaled commands (``commands.command_speeds``).

    Attributes:
        task: the task's spec (:class:`~cyber_rodent.tasks.spec.TaskSpec`).
        n_learners: robots acting (2 for Mate, else 1).
        steps: control steps of the current episode so far.
    """

    def __init__(
        self,
        behaviour: str,
        config: EpisodeConfig | None = None,
        timestep: float | None = None,
        profile: HardwareProfile | None = None,
        randomise: bool = False,
        survival: SurvivalConfig | None = None,
        robot: str = "cyber_rodent",
    ) -> None:
        self.behaviour = behaviour_index(behaviour)
        self.name = behaviour
        self.task = task = task_spec(behaviour)
        self.config = config or EpisodeConfig(max_steps=task.episode_steps)
        if profile is not None and not isinstance(profile, HardwareProfile):
            raise ValueError(f"profile must be a HardwareProfile or None, got {profile!r}")
        if not isinstance(randomise, bool) or (randomise and profile is None):
            raise ValueError(f"randomise must be True (with a profile) or False, got {randomise!r}")
        self.profile, self.randomise = profile, randomise
        survival_cfg = episode_rules(survival)
        field = task.field
        if profile is not None and profile.field.enabled:
            field = task.hardware_field(profile.field.n_robots, profile.field.n_packs)
        robots, packs = field.robots, field.packs
        world_cfg = WorldConfig(n_robots=robots, n_packs=packs, robot=robot)
        if timestep is not None:
            world_cfg = dataclasses.replace(world_cfg, timestep=timestep)
        fixed = np.random.default_rng(0)  # construction only; every episode re-draws
        self.world = World(world_cfg, fixed)
        self._commands = command_speeds(self.world.robot)
        self._proximity = self.world.robot.proximity
        self.survival = SurvivalWorld(self.world, survival_cfg, fixed)
        camera = CameraConfig()
        if profile is not None:
            camera = apply_vision(camera, profile.vision)
        # A task that looks at nothing (Search: proximity only) runs without vision.
        self.vision = (
            make_provider("geometric", self.world, camera, np.random.default_rng(0))
            if task.sees
            else None
        )
        self._frame: VisionFrame | None = None
        self._range_noise: RangeSensorNoise | None = None
        self.episode_profile: HardwareProfile | None = None
        if profile is not None:
            m = self.world.model
            self._drive_as_built = (
                m.actuator_gainprm.copy(), m.actuator_dynprm.copy(), m.geom_friction.copy()
            )  # fmt: skip
        self.dt = survival_cfg.control_dt
        self._states = np.zeros((0, 2))
        # The task's episode loop: the shaped reward of every learner, contacts measured.
        self.episode = TaskEpisode(
            task,
            self.survival,
            self._look,
            EpisodeOptions(
                reward="shaped",
                scales=RewardScales.from_episode(self.config),
                episode_steps=self.config.max_steps,
                max_start_draws=self.config.max_start_draws,
                collisions=True,
            ),
        )
        self.n_learners = self.episode.k
        self.rewards = self.episode.rewards
        self.positions: list[tuple[float, float]] = []

    @property
    def steps(self) -> int:
        """Control steps of the current episode so far."""
        return self.episode.steps

    # --- episode ---------------------------------------------------------------------------
    def reset(self, rng: np.random.Generator) -> np.ndarray:
        """Start an episode from a placement drawn with ``rng``; return the (k, 2) inputs.

        Raises:
            RuntimeError: no placement satisfied the start condition.
        """
        if self.profile is not None:
            self._apply_profile(self.profile, rng.spawn(1)[0])
        self.episode.reset(rng)
        return self._states

    def step(self, commands: np.ndarray) -> StepResult:
        """Drive the learners with wheel commands (k,) for one control step."""
        k = self.n_learners
        self.episode.wheels[:k] = self._commands[np.asarray(commands, dtype=np.int64)]
        step = self.episode.step()
        assert step.collided is not None  # measured every step
        return StepResult(self._states, step.reward, step.terminated, step.collided[:k].copy())

    def position(self) -> np.ndarray:
        """(x, y) of robot 0's centre, m."""
        return self.world.poses()[0, :2]

    # --- internals -----------------------------------------------------------------------------
    def _apply_profile(self, profile: HardwareProfile, rng: np.random.Generator) -> None:
        """This episode's hardware: noise magnitudes, camera noise, the robots' drives."""
        profile = randomised(profile, rng) if self.randomise else profile
        self.episode_profile = profile
        if self.vision is not None:
            self.vision.config = dataclasses.replace(
                self.vision.config, noise=profile.vision.noise()
            )
            self.vision.rng = rng
        noise = profile.range_noise
        self._range_noise = (
            RangeSensorNoise(noise, self.world.range_max, rng) if noise.active else None
        )
        m = self.world.model
        gain, dyn, friction = self._drive_as_built
        m.actuator_gainprm[:] = gain
        m.actuator_dynprm[:] = dyn
        m.geom_friction[:] = friction
        drive = profile.actuators
        if drive.enabled:
            hardware_robots = profile.field.n_robots if profile.field.enabled else 3
            learner_is_weak = int(rng.integers(hardware_robots)) == drive.weak_robot
            variation = dataclasses.replace(drive, weak_robot=0 if learner_is_weak else -1)
            apply_actuators(self.world, variation, rng)

    def _ranges(self) -> np.ndarray:
        ranges = self.world.range_readings()
        if self._range_noise is not None:
            self._range_noise.apply(ranges)
        return ranges

    def _look(self) -> VisionFrame | None:
        """The learners' inputs now (:attr:`_states`), and what the robots see (None without
        vision): the episode loop's ``look``."""
        self._states = self._observe()
        return self._frame

    def _observe(self) -> np.ndarray:
        k = self.n_learners
        vision = self.vision
        if vision is None:  # Search: proximity only
            ranges = self._ranges()[:k]
            return search_inputs(ranges, self.world.range_max[:k], self._proximity)
        self._frame = vision.observe()
        inputs = behaviour_inputs(
            self._frame, self._ranges(), self.world.range_max, proximity=self._proximity
        )
        return inputs.of(self.behaviour)[:k].copy()


def random_commands(rng: np.random.Generator, k: int) -> np.ndarray:
    """Uniformly random wheel commands (the random baseline)."""
    return rng.integers(N_COMMANDS, size=k)


__all__ = [
    "COVERAGE_CELL",
    "BehaviourEpisode",
    "EpisodeConfig",
    "StepResult",
    "coverage_cells",
    "episode_rng",
    "episode_rules",
    "random_commands",
    "search_reward",
    "shaping_reward",
]
