"""What the Gymnasium and PettingZoo environments share: options, actions, the simulation they
build, observations, rendering and closing.

:class:`~cyber_rodent.gym_env.CyberRodentEnv` (one learner) and
:class:`~cyber_rodent.colony_env.ColonyEnv` (every learner an agent) are two views of one
:class:`~cyber_rodent.tasks.episode.TaskEpisode`; what they have in common is here, once:

* :class:`EnvConfig`, the options both take (a frozen dataclass, each field validated in one
  line naming it and its allowed values), which each environment's own config extends;
* the action of one robot: :func:`action_space` (the behaviours' command table or wheel speeds,
  then the switches its task leaves open), :func:`action_names`, :func:`decode_action`;
* :class:`FieldEnv`, the part of both classes that builds the world, the survival rules and the
  vision from a config, turns an action into the episode's commands, builds the observation
  from the one table (:mod:`cyber_rodent.observations`), renders the top-down view and closes
  the OpenGL contexts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from cyber_rodent.backend import DEFAULT_BACKEND, Backend, check_backend
from cyber_rodent.commands import COMMAND_SPEEDS, DESIGN_TOP_SPEED, N_COMMANDS, command_speeds
from cyber_rodent.observations import (
    OBSERVATION_KINDS,
    ObservationBounds,
    ObservationLimits,
    ObservationScale,
    observation_table,
)
from cyber_rodent.render import FieldRenderer, check_image_size
from cyber_rodent.robot import robot_names
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.tasks.episode import TaskEpisode
from cyber_rodent.tasks.spec import Field
from cyber_rodent.validation import check_number, choice, number, validate_fields
from cyber_rodent.vision import PROVIDER_NAMES, CameraConfig, VisionProvider, make_provider
from cyber_rodent.world import World, WorldConfig

ACTION_KINDS = ("discrete", "continuous")
#: Default bound of the continuous wheel speeds, m/s.
DEFAULT_MAX_WHEEL_SPEED = 1.0
#: A switch entry of a continuous action, in [-1, 1], is on above this.
SWITCH_ON = 0.0
RENDER_MODES = ("rgb_array",)


# --- options --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EnvConfig:
    """The options of both environments (each extends it with its own).

    Attributes:
        action: ``"discrete"`` (the command table) or ``"continuous"`` (wheel speeds, m/s).
        observation: ``"normalised"`` (in [0, 1], bearings in [−1, 1]) or ``"raw"`` (physical
            units); :mod:`cyber_rodent.observations`.
        vision: ``"geometric"`` (default) or ``"rendered"``.
        camera: the omni camera (None: :class:`CameraConfig`'s defaults).
        survival: the survival rules (None: the paper's).
        max_wheel_speed: bound of the continuous wheel speeds, m/s, in (0, 1.3]; with
            continuous actions, at most the robot's top speed.
        robot: the robots' kind (``WorldConfig.robot``: ``cyber_rodent``, the default, or
            another of ``cyber_rodent.robot.ROBOTS``); its sensor table gives the
            observation, its top speed the discrete commands (``commands.command_speeds``).
        render_mode: None or ``"rgb_array"`` (the top-down view).
        render_width, render_height: size of a rendered image, px.
        backend: ``"numba"`` or ``"numpy"`` kernels (the same trajectories).

    Raises:
        ValueError: one line naming the first invalid field and what it allows.
    """

    action: str = choice("discrete", ACTION_KINDS)
    observation: str = choice("normalised", OBSERVATION_KINDS)
    vision: str = choice("geometric", PROVIDER_NAMES)
    camera: CameraConfig | None = None
    survival: SurvivalConfig | None = None
    max_wheel_speed: float = number(DEFAULT_MAX_WHEEL_SPEED, 0.0, DESIGN_TOP_SPEED, low_open=True)
    render_mode: str | None = None
    render_width: int = 480
    render_height: int = 480
    backend: Backend = DEFAULT_BACKEND
    robot: str = choice("cyber_rodent", robot_names)

    def __post_init__(self) -> None:
        validate_fields(self)
        for name, cls in (("camera", CameraConfig), ("survival", SurvivalConfig)):
            value = getattr(self, name)
            if value is not None and not isinstance(value, cls):
                raise ValueError(f"{name} must be a {cls.__name__}, got {type(value).__name__}")
        if self.render_mode is not None and self.render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {self.render_mode!r}")
        check_image_size(self.render_width, self.render_height)
        check_backend(self.backend)


# --- actions --------------------------------------------------------------------------------------
def action_space(kind: str, switches: tuple[str, ...], max_wheel_speed: float) -> spaces.Space[Any]:
    """The action space of one robot: a wheel command, then on/off ``switches``.

    Discrete: ``Discrete(N_COMMANDS)`` without switches, else ``MultiDiscrete([N_COMMANDS, 2,
    ...])``. Continuous: ``Box`` of the two wheel speeds (m/s, ±``max_wheel_speed``), then one
    entry in [-1, 1] per switch (on above :data:`SWITCH_ON`).
    """
    if kind == "discrete":
        if not switches:
            return spaces.Discrete(N_COMMANDS)
        return spaces.MultiDiscrete([N_COMMANDS, *(2,) * len(switches)])
    low = np.array([-max_wheel_speed] * 2 + [-1.0] * len(switches), dtype=np.float32)
    high = np.array([max_wheel_speed] * 2 + [1.0] * len(switches), dtype=np.float32)
    return spaces.Box(low, high, dtype=np.float32)


def action_names(kind: str, switches: tuple[str, ...]) -> tuple[str, ...]:
    """Names of the entries of an action of :func:`action_space`."""
    wheels = ("command",) if kind == "discrete" else ("left_wheel", "right_wheel")
    return (*wheels, *switches)


def decode_action(
    action: Any,
    space: spaces.Space[Any],
    wheels: np.ndarray,
    switches: np.ndarray,
    commands: np.ndarray = COMMAND_SPEEDS,
) -> None:
    """Write an action of ``space`` (:func:`action_space`) as wheel speeds and switch states.

    Args:
        action: the action.
        space: its space.
        wheels: (2,) out: left and right wheel rim speeds, m/s.
        switches: (n_switches,) bool out.
        commands: (N_COMMANDS, 2) the discrete commands' speeds, m/s (the robot's:
            :func:`~cyber_rodent.commands.command_speeds`).

    Raises:
        ValueError: the action is not in the space (the message says why).
    """
    if isinstance(space, spaces.Box):
        value = np.asarray(action, dtype=np.float32)
        if value.shape != space.shape:
            raise ValueError(f"action must have shape {space.shape}, got {value.shape}")
        if not np.isfinite(value).all():
            raise ValueError("action must be finite (got NaN or inf)")
        if (value < space.low).any() or (value > space.high).any():
            raise ValueError(
                f"action must lie in [{space.low.tolist()}, {space.high.tolist()}], "
                f"got {value.tolist()}"
            )
        wheels[:] = value[:2]
        np.greater(value[2:], SWITCH_ON, out=switches)
        return
    value = np.asarray(action)
    nvec = space.nvec if isinstance(space, spaces.MultiDiscrete) else np.array([N_COMMANDS])
    flat = value.reshape(-1)
    if value.dtype.kind not in "iu" or flat.shape != nvec.shape:
        raise ValueError(
            f"action must be {'an integer' if flat.size == 1 else 'integers'} of {space}, "
            f"got {action!r}"
        )
    if (flat < 0).any() or (flat >= nvec).any():
        raise ValueError(f"action must lie in {space}, got {action!r}")
    wheels[:] = commands[int(flat[0])]
    switches[:] = flat[1:] != 0


def check_max_wheel_speed(value: object) -> float:
    """A continuous action's wheel-speed bound, m/s, in (0, ``DESIGN_TOP_SPEED``] (the robot's
    own top speed is checked when its world is built)."""
    return check_number("max_wheel_speed", value, 0.0, DESIGN_TOP_SPEED, low_open=True)


# --- the environments' common part ----------------------------------------------------------------
class FieldEnv:
    """The part of the Gymnasium and PettingZoo environments that is the same in both.

    A subclass calls :meth:`_build_field` once in its constructor and sets
    :attr:`task_episode`; it then has the simulation objects, the observation's description, a
    robot's action (:meth:`_act`), the observation (:meth:`_observe`), :meth:`render` and
    :meth:`close`.

    Attributes:
        config: the options.
        world, survival, vision: the simulation objects.
        camera: the omni camera; max_range: its range, m (an unseen target's distance).
        task_episode: the task's episode loop (:class:`TaskEpisode`).
        observation_kind, observation_names, observation_units, observation_bounds,
        observation_scale: the observation (:mod:`cyber_rodent.observations`).
        max_wheel_speed, render_mode, dt: as configured.
    """

    metadata: dict[str, Any]
    config: EnvConfig
    world: World
    survival: SurvivalWorld
    vision: VisionProvider
    camera: CameraConfig
    max_range: float
    task_episode: TaskEpisode
    render_mode: str | None
    _renderer: FieldRenderer | None = None
    #: The latest observations in physical units (every robot's; :meth:`_observe`).
    _raw: np.ndarray | None = None

    def _build_field(self, config: EnvConfig, field: Field, rules: SurvivalConfig) -> None:
        """The world of ``field`` under ``rules``, its vision, and the observation's bounds."""
        self.config = config
        self.action_kind = config.action
        self.observation_kind = config.observation
        self.max_wheel_speed = float(config.max_wheel_speed)
        self.render_mode = config.render_mode
        backend = config.backend
        fixed = np.random.default_rng(0)  # construction only; every reset re-draws
        world = WorldConfig(n_robots=field.robots, n_packs=field.packs, robot=config.robot)
        self.world = World(world, fixed)
        top = self.world.robot.top_speed
        if config.action == "continuous" and self.max_wheel_speed > top:
            raise ValueError(
                f"max_wheel_speed must be in (0, {top:g}] m/s for robot {config.robot!r} (its "
                f"top speed), got {self.max_wheel_speed:g}"
            )
        self.commands = command_speeds(self.world.robot)
        self.survival = SurvivalWorld(self.world, rules, fixed, backend=backend)
        self.camera = config.camera or CameraConfig()
        self.vision = make_provider(
            config.vision, self.world, self.camera, np.random.default_rng(0), backend=backend
        )
        self.max_range = float(self.camera.max_range)
        self.metadata = {**self.metadata, "render_fps": 1.0 / rules.control_dt}
        self.dt = rules.control_dt
        table = observation_table(self.world.robot.sensors)
        limits = ObservationLimits.of(self.world.range_max[0], self.max_range, rules, table)
        self.observation_names = table.names
        self.observation_units = table.units
        self.observation_bounds: ObservationBounds = limits.bounds()
        self.observation_scale: ObservationScale = limits.scale()
        self.observation_limits = limits

    def _reseed_vision(self, rng: np.random.Generator) -> None:
        """Noisy vision draws from a child of the episode's generator."""
        if self.camera.noise.enabled:
            self.vision.rng = rng.spawn(1)[0]

    def _act(self, robot: int, action: Any, space: spaces.Space[Any], on: np.ndarray) -> None:
        """Robot ``robot``'s action: its wheels, and the switches its action sets (``on`` is a
        buffer of them)."""
        decode_action(action, space, self.task_episode.wheels[robot], on, self.commands)
        self.task_episode.set_switches(robot, on)

    def _observe(self) -> np.ndarray:
        """Every robot's observation now, of the configured kind; the raw one is kept in
        :attr:`_raw`."""
        self._raw = raw = self.task_episode.observations()
        if self.observation_kind == "normalised":
            return self.observation_scale.normalise(raw)
        return raw

    def render(self) -> np.ndarray | None:
        """The top-down view of the field, (render_height, render_width, 3) uint8."""
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            config = self.config
            self._renderer = FieldRenderer(self.world, config.render_width, config.render_height)
        return self._renderer.top_down()

    def close(self) -> None:
        """Free the OpenGL contexts (idempotent)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self._release()
        close = getattr(self.vision, "close", None)
        if close is not None:  # the rendered provider's GL context
            close()

    def _release(self) -> None:
        """Free what a subclass holds beside the renderer and the vision (in :meth:`close`)."""


__all__ = [
    "ACTION_KINDS",
    "DEFAULT_MAX_WHEEL_SPEED",
    "RENDER_MODES",
    "SWITCH_ON",
    "EnvConfig",
    "FieldEnv",
    "action_names",
    "action_space",
    "check_max_wheel_speed",
    "decode_action",
]
