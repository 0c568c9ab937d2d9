"""A hardware-like world profile for sim-to-real studies (paper §4.3, Fig. 7; docs/design.md §5).

The paper moved the 5 fittest individuals of a simulated run onto 3 real CRs and observed that
"sensors were much noisier, behaviours were slower, and one robot was weaker than the others".
:class:`HardwareProfile` models those differences as four independent parts, each with
documented defaults and each switchable on its own (``enabled=False`` or
:meth:`HardwareProfile.without`):

* :class:`RangeNoise`: IR range sensors with additive Gaussian noise and dropouts (a dropped
  reading sees nothing, i.e. reads the sensor's full range, as a missed IR echo does);
* :class:`VisionUncertainty`: bearing and distance noise and missed detections of the omni
  camera, expressed as the existing :class:`~cyber_rodent.vision.VisionNoise` of the camera
  config (applied by :func:`apply_vision`);
* :class:`ActuatorVariation`: per-robot wheel gains (a wheel reaches ``gain x`` the commanded
  speed), wheel-floor friction, motor lag (the velocity servo's first-order time constant) and
  one designated weaker robot (:func:`apply_actuators` writes them into the compiled model);
* :class:`FieldLayout`: the paper's hardware field, 3 robots and 6 packs (:func:`apply_field`).

Every ``apply_*`` function changes only what its part names; a disabled part changes nothing.
All randomness comes from an explicit ``np.random.Generator``: the same seed gives the same
actuator sample and the same noise sequence.

Defaults are our reading of "much noisier" (the paper gives no numbers): range noise 2 cm std
with 2 % dropouts (cheap IR sensors), vision 5° bearing / 15 % distance noise with 10 % missed
detections, wheel gains within ±10 %, friction within ±20 %, motor lag 50–100 ms (the simulated
motor has 50 ms) and robot 2 at 70 % wheel gain ("one robot was weaker").
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.atomic import write_json
from cyber_rodent.validation import (
    RULE,
    boolean,
    check_choice,
    check_number,
    integer,
    number,
    validate_fields,
)
from cyber_rodent.vision.config import CameraConfig, VisionNoise
from cyber_rodent.world import World, WorldConfig

#: Names of the profile's parts, in the order :meth:`HardwareProfile.without` accepts them.
PROFILE_PARTS = ("range_noise", "vision", "actuators", "field")
#: Names accepted by :func:`profile_by_name` (``--profile``).
PROFILE_NAMES = ("sim", "hardware")


@dataclass(frozen=True)
class RangeNoise:
    """Noise of the 8 IR range sensors.

    Attributes:
        enabled: apply this part.
        std: m, std of additive Gaussian noise on each reading (result clipped to
            [0, sensor range]); default 0.02.
        dropout: probability that a reading is lost in a step and reads the full range
            (nothing seen); default 0.02.
    """

    enabled: bool = boolean(True)
    std: float = number(0.02, 0.0, 1.0)
    dropout: float = number(0.02, 0.0, 1.0)

    def __post_init__(self) -> None:
        validate_fields(self, "range_noise.")

    @property
    def active(self) -> bool:
        """Enabled and with a non-zero magnitude."""
        return self.enabled and (self.std > 0 or self.dropout > 0)


@dataclass(frozen=True)
class VisionUncertainty:
    """Uncertainty of the omni camera's detections (per detected target, before the nearest is
    chosen, as :class:`~cyber_rodent.vision.VisionNoise` documents).

    Attributes:
        enabled: apply this part.
        bearing_std_deg: degrees, std of Gaussian bearing noise; default 5.
        distance_rel_std: relative std of multiplicative distance noise; default 0.15.
        dropout: probability that a visible target is missed in a frame; default 0.1.
    """

    enabled: bool = boolean(True)
    bearing_std_deg: float = number(5.0, 0.0, 90.0)
    distance_rel_std: float = number(0.15, 0.0, 1.0)
    dropout: float = number(0.1, 0.0, 1.0)

    def __post_init__(self) -> None:
        validate_fields(self, "vision.")

    def noise(self) -> VisionNoise:
        """The camera noise model this part stands for (no noise when disabled)."""
        if not self.enabled:
            return VisionNoise()
        return VisionNoise(self.bearing_std_deg, self.distance_rel_std, self.dropout)


@dataclass(frozen=True)
class ActuatorVariation:
    """Per-robot differences of the drive, sampled once per world.

    Attributes:
        enabled: apply this part.
        wheel_gain_spread: each wheel's gain factor is drawn from U[1 - s, 1 + s]; the wheel
            then settles at ``gain x`` the commanded speed (a motor/gear tolerance); default 0.1.
        friction_spread: each robot's wheel-floor sliding friction is scaled by a factor from
            U[1 - s, 1 + s] (tyre wear, dust); default 0.2.
        motor_lag_s: (low, high) s, each robot's motor time constant is drawn from U[low, high]
            (the simulated motor: 0.05 s); default (0.05, 0.1): slower behaviours.
        weak_robot: index of the robot that is weaker than the others (paper §4.3), -1 for
            none; default 2 (the third of the hardware's three robots).
        weak_gain: extra gain factor of both wheels of the weak robot; default 0.7.
    """

    enabled: bool = boolean(True)
    wheel_gain_spread: float = number(0.1, 0.0, 0.9)
    friction_spread: float = number(0.2, 0.0, 0.9)
    motor_lag_s: tuple[float, float] = (0.05, 0.1)
    weak_robot: int = integer(2, -1)
    weak_gain: float = number(0.7, 0.1, 1.0)

    def __post_init__(self) -> None:
        validate_fields(self, "actuators.")
        lag = self.motor_lag_s
        if not isinstance(lag, tuple | list) or len(lag) != 2:
            raise ValueError(f"actuators.motor_lag_s must be a (low, high) pair, got {lag!r}")
        low = check_number("actuators.motor_lag_s[0]", lag[0], 0.001, 1.0)
        high = check_number("actuators.motor_lag_s[1]", lag[1], low, 1.0)
        object.__setattr__(self, "motor_lag_s", (low, high))

    def sample(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(n, 2) wheel gains, (n,) friction factors and (n,) motor lags of ``n`` robots,
        drawn from the ranges (the weak robot's factor included)."""
        s, f = self.wheel_gain_spread, self.friction_spread
        gain = rng.uniform(1.0 - s, 1.0 + s, size=(n, 2))
        friction = rng.uniform(1.0 - f, 1.0 + f, size=n)
        lag = rng.uniform(*self.motor_lag_s, size=n)
        if self.weak_robot >= 0:
            gain[self.weak_robot] *= self.weak_gain
        return gain, friction, lag


@dataclass(frozen=True)
class FieldLayout:
    """The hardware field (paper §4.3): 3 robots and 6 battery packs.

    Attributes:
        enabled: apply this part.
        n_robots: robots in the field; default 3.
        n_packs: battery packs in the field; default 6.
    """

    enabled: bool = boolean(True)
    n_robots: int = integer(3, 1)
    n_packs: int = integer(6, 0)

    def __post_init__(self) -> None:
        validate_fields(self, "field.")


@dataclass(frozen=True)
class HardwareProfile:
    """The four hardware-like differences together; each switchable on its own.

    Attributes:
        range_noise: IR sensor noise and dropouts.
        vision: camera detection noise.
        actuators: per-robot wheel gain, friction, motor lag, weak robot.
        field: the 3-robot, 6-pack field.
    """

    range_noise: RangeNoise = dataclasses.field(default_factory=RangeNoise)
    vision: VisionUncertainty = dataclasses.field(default_factory=VisionUncertainty)
    actuators: ActuatorVariation = dataclasses.field(default_factory=ActuatorVariation)
    field: FieldLayout = dataclasses.field(default_factory=FieldLayout)

    def __post_init__(self) -> None:
        for name, cls in zip(
            PROFILE_PARTS,
            (RangeNoise, VisionUncertainty, ActuatorVariation, FieldLayout),
            strict=True,
        ):
            if not isinstance(getattr(self, name), cls):
                raise ValueError(f"{name} must be a {cls.__name__}, got {getattr(self, name)!r}")

    def without(self, *parts: str) -> HardwareProfile:
        """A copy with the named parts switched off (names from :data:`PROFILE_PARTS`)."""
        unknown = [p for p in parts if p not in PROFILE_PARTS]
        if unknown:
            raise ValueError(
                f"parts must be among {', '.join(PROFILE_PARTS)}, got {', '.join(unknown)}"
            )
        return dataclasses.replace(
            self, **{p: dataclasses.replace(getattr(self, p), enabled=False) for p in parts}
        )

    def only(self, *parts: str) -> HardwareProfile:
        """A copy with only the named parts switched on (for one-at-a-time studies)."""
        return self.without(*[p for p in PROFILE_PARTS if p not in parts])

    @property
    def enabled_parts(self) -> tuple[str, ...]:
        return tuple(p for p in PROFILE_PARTS if getattr(self, p).enabled)

    def randomised(self, rng: np.random.Generator) -> HardwareProfile:
        """A profile for one episode of domain randomisation (see :func:`randomised`)."""
        return _randomised_ranges(self, rng)


def profile_by_name(name: str) -> HardwareProfile | None:
    """``"sim"``: None (the plain simulation); ``"hardware"``: :class:`HardwareProfile()`."""
    check_choice("profile", name, PROFILE_NAMES)
    return None if name == "sim" else HardwareProfile()


# --- applying the parts ------------------------------------------------------------------------
def apply_field(world: WorldConfig, layout: FieldLayout) -> WorldConfig:
    """``world`` with the layout's robot and pack counts (unchanged if the part is off)."""
    if not layout.enabled:
        return world
    return dataclasses.replace(world, n_robots=layout.n_robots, n_packs=layout.n_packs)


def apply_vision(camera: CameraConfig, vision: VisionUncertainty) -> CameraConfig:
    """``camera`` with the part's noise model (unchanged if the part is off)."""
    if not vision.enabled:
        return camera
    return dataclasses.replace(camera, noise=vision.noise())


@dataclass(frozen=True)
class ActuatorSample:
    """What :func:`apply_actuators` drew and wrote, per robot.

    Attributes:
        wheel_gain: (n, 2) left/right gain factors (weak robot's factor included).
        friction_scale: (n,) wheel-floor friction factors.
        motor_lag_s: (n,) motor time constants, s.
    """

    wheel_gain: np.ndarray
    friction_scale: np.ndarray
    motor_lag_s: np.ndarray


def _wheel_ids(world: World) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) actuator ids and (n, 2) wheel contact geom ids, robot-major, left then right."""
    m = world.model
    n = world.config.n_robots
    motors = np.arange(world._ctrl_slice.start, world._ctrl_slice.stop).reshape(n, 2)
    geoms = np.array(
        [
            [
                mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, C.robot_prefix(i) + side)
                for side in (world.robot.parts.left_wheel_geom, world.robot.parts.right_wheel_geom)
            ]
            for i in range(n)
        ],
        dtype=np.int64,
    )
    if (geoms < 0).any():
        raise RuntimeError("model has no wheel contact geoms")
    return motors, geoms


def apply_actuators(
    world: World, variation: ActuatorVariation, rng: np.random.Generator
) -> ActuatorSample | None:
    """Draw per-robot actuator differences and write them into ``world``'s compiled model.

    Only the wheel motors' gain (``actuator_gainprm[:, 0]``; the velocity feedback
    ``biasprm`` is kept, so the servo settles at ``gain x`` the command), their time constant
    (``actuator_dynprm[:, 0]``) and the wheel contact geoms' sliding friction change. The
    factors apply to the model's values as built, so call this once per world.

    Args:
        world: the world to modify.
        variation: the part's ranges.
        rng: the generator the sample is drawn from.

    Returns:
        The sample, or None (nothing changed, no random numbers drawn) if the part is off.

    Raises:
        ValueError: ``weak_robot`` is not a robot of this world.
    """
    if not variation.enabled:
        return None
    n = world.config.n_robots
    if variation.weak_robot >= n:
        raise ValueError(
            f"actuators.weak_robot must be in [-1, {n - 1}] for a {n}-robot world, "
            f"got {variation.weak_robot}"
        )
    gain, friction, lag = variation.sample(n, rng)
    motors, geoms = _wheel_ids(world)
    m = world.model
    m.actuator_gainprm[motors, 0] = m.actuator_gainprm[motors, 0] * gain
    m.actuator_dynprm[motors, 0] = lag[:, None]
    m.geom_friction[geoms, 0] = m.geom_friction[geoms, 0] * friction[:, None]
    return ActuatorSample(gain, friction, lag)


class RangeSensorNoise:
    """Applies :class:`RangeNoise` to (n, 8) range readings in place, allocation-free.

    Args:
        noise: the part's magnitudes.
        range_max: (n, 8) each sensor's range (a reading is clipped to [0, range_max], and a
            dropped reading reads range_max).
        rng: the noise generator (owned by the caller; its state is what a checkpoint saves).
    """

    def __init__(self, noise: RangeNoise, range_max: np.ndarray, rng: np.random.Generator):
        self.noise = noise
        self.rng = rng
        self.range_max = np.ascontiguousarray(range_max, dtype=float)
        self._gauss = np.zeros_like(self.range_max)
        self._uniform = np.zeros_like(self.range_max)
        self._dropped = np.zeros(self.range_max.shape, dtype=bool)

    def apply(self, ranges: np.ndarray) -> np.ndarray:
        """Add noise and dropouts to ``ranges`` (metres) in place; returns it."""
        noise = self.noise
        if not noise.active:
            return ranges
        if noise.std > 0:
            self.rng.standard_normal(out=self._gauss)
            self._gauss *= noise.std
            ranges += self._gauss
            np.clip(ranges, 0.0, self.range_max, out=ranges)
        if noise.dropout > 0:
            self.rng.random(out=self._uniform)
            np.less(self._uniform, noise.dropout, out=self._dropped)
            np.copyto(ranges, self.range_max, where=self._dropped)
        return ranges


def randomised(profile: HardwareProfile, rng: np.random.Generator) -> HardwareProfile:
    """A profile sampled from ``profile``'s ranges, for domain randomisation
    (:meth:`HardwareProfile.randomised`; a fitted profile draws within its uncertainty)."""
    return profile.randomised(rng)


def _randomised_ranges(profile: HardwareProfile, rng: np.random.Generator) -> HardwareProfile:
    """A profile sampled from ``profile``'s ranges, for domain randomisation.

    Each magnitude (range noise std and dropout, vision noise, wheel-gain and friction spreads,
    the weak robot's gain deficit) is scaled by an independent U[0, 1] factor, so an episode
    sees anything from the plain simulation to the full hardware profile; the motor lag is
    drawn within ``motor_lag_s`` by :func:`apply_actuators` as usual. Disabled parts stay off.
    """
    u = rng.random(8)
    r, v, a = profile.range_noise, profile.vision, profile.actuators
    return dataclasses.replace(
        profile,
        range_noise=dataclasses.replace(r, std=r.std * u[0], dropout=r.dropout * u[1]),
        vision=dataclasses.replace(
            v,
            bearing_std_deg=v.bearing_std_deg * u[2],
            distance_rel_std=v.distance_rel_std * u[3],
            dropout=v.dropout * u[4],
        ),
        actuators=dataclasses.replace(
            a,
            wheel_gain_spread=a.wheel_gain_spread * u[5],
            friction_spread=a.friction_spread * u[6],
            weak_gain=1.0 - (1.0 - a.weak_gain) * u[7],
        ),
    )


# --- a profile fitted to a robot's logs (cyber_rodent.sysid) ------------------------------------
#: ``format`` of a profile file (``cyber-rodent sysid --out``; ``--profile FILE``).
PROFILE_FILE_FORMAT = "cyber-rodent-profile"
#: Version of the profile file's layout; a reader refuses others.
PROFILE_FILE_VERSION = 1
#: Bounds of a fitted per-robot value: a wheel gain factor, a friction factor, a motor lag (s).
FITTED_GAIN = (0.1, 3.0)
FITTED_FRICTION = (0.05, 5.0)
FITTED_LAG = (0.001, 1.0)


def _per_robot(
    name: str, values: object, low: float, high: float, width: int = 0
) -> tuple[Any, ...]:
    """``values`` as a tuple of numbers (``width`` 0) or of ``width``-tuples, each in range."""
    if not isinstance(values, tuple | list) or not values:
        raise ValueError(f"{name} must be a non-empty list (one entry per robot), got {values!r}")
    out: list[Any] = []
    for i, v in enumerate(values):
        if width:
            if not isinstance(v, tuple | list) or len(v) != width:
                raise ValueError(f"{name}[{i}] must be {width} numbers, got {v!r}")
            out.append(
                tuple(check_number(f"{name}[{i}][{j}]", x, low, high) for j, x in enumerate(v))
            )
        else:
            out.append(check_number(f"{name}[{i}]", v, low, high))
    return tuple(out)


@dataclass(frozen=True)
class FittedActuators(ActuatorVariation):
    """Each logged robot's drive as fitted (:mod:`cyber_rodent.sysid`), with its uncertainty.

    An :class:`ActuatorVariation` whose :meth:`sample` returns the fitted robots' values
    instead of drawing from ranges (the range fields are unused). Which fitted robot each
    simulated robot is gets drawn per world: a random permutation of the fitted robots
    (repeated when the world has more robots), so a one-robot episode runs on each of them in
    turn. ``weak_robot`` is -1: a weak robot shows in its fitted gains.

    Attributes:
        wheel_gain: per robot (left, right) gain factor of the wheel servo (the wheel settles at
            ``gain x`` the command); range [0.1, 3]; source: the fit (default 1, the model).
        wheel_gain_sd: per robot (left, right) standard error of the gain (bootstrap over log
            segments); >= 0; default 0.
        friction_scale: per robot factor on the wheel-floor sliding friction; range [0.05, 5];
            default 1.
        friction_scale_sd: its standard error; >= 0; default 0.
        motor_lag: per robot motor time constant, s; range [0.001, 1]; default 0.05 (the model).
        motor_lag_sd: its standard error, s; >= 0; default 0.
    """

    weak_robot: int = integer(-1, -1, -1)
    wheel_gain: tuple[tuple[float, float], ...] = ((1.0, 1.0),)
    wheel_gain_sd: tuple[tuple[float, float], ...] = ((0.0, 0.0),)
    friction_scale: tuple[float, ...] = (1.0,)
    friction_scale_sd: tuple[float, ...] = (0.0,)
    motor_lag: tuple[float, ...] = (0.05,)
    motor_lag_sd: tuple[float, ...] = (0.0,)

    def __post_init__(self) -> None:
        super().__post_init__()
        fields = {
            "wheel_gain": _per_robot("actuators.wheel_gain", self.wheel_gain, *FITTED_GAIN, 2),
            "wheel_gain_sd": _per_robot("actuators.wheel_gain_sd", self.wheel_gain_sd, 0, 10, 2),
            "friction_scale": _per_robot(
                "actuators.friction_scale", self.friction_scale, *FITTED_FRICTION
            ),
            "friction_scale_sd": _per_robot(
                "actuators.friction_scale_sd", self.friction_scale_sd, 0, 10
            ),
            "motor_lag": _per_robot("actuators.motor_lag", self.motor_lag, *FITTED_LAG),
            "motor_lag_sd": _per_robot("actuators.motor_lag_sd", self.motor_lag_sd, 0, 10),
        }
        n = len(fields["wheel_gain"])
        for name, value in fields.items():
            if len(value) != n:
                raise ValueError(
                    f"actuators.{name} must have one entry per fitted robot ({n}), got {len(value)}"
                )
            object.__setattr__(self, name, value)

    @property
    def n_fitted(self) -> int:
        """Robots the fit describes."""
        return len(self.wheel_gain)

    def sample(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The fitted values of ``n`` robots, each a fitted robot drawn without replacement
        (a fresh permutation for every ``n_fitted`` robots)."""
        k = self.n_fitted
        which = np.concatenate([rng.permutation(k) for _ in range(-(-n // k))])[:n]
        gain = np.asarray(self.wheel_gain, dtype=float)[which]
        friction = np.asarray(self.friction_scale, dtype=float)[which]
        lag = np.asarray(self.motor_lag, dtype=float)[which]
        return gain, friction, lag

    def drawn(self, rng: np.random.Generator) -> FittedActuators:
        """A copy whose values are drawn from N(value, sd), clipped to their ranges."""

        def draw(
            values: tuple[Any, ...], sds: tuple[Any, ...], bounds: tuple[float, float]
        ) -> np.ndarray:
            v, sd = np.asarray(values, dtype=float), np.asarray(sds, dtype=float)
            return np.clip(v + sd * rng.standard_normal(v.shape), *bounds)

        gain = draw(self.wheel_gain, self.wheel_gain_sd, FITTED_GAIN)
        friction = draw(self.friction_scale, self.friction_scale_sd, FITTED_FRICTION)
        lag = draw(self.motor_lag, self.motor_lag_sd, FITTED_LAG)
        return dataclasses.replace(
            self,
            wheel_gain=tuple((float(g[0]), float(g[1])) for g in gain),
            friction_scale=tuple(map(float, friction)),
            motor_lag=tuple(map(float, lag)),
        )


#: The scalar parameters of a fitted profile that carry an uncertainty: name -> (part, field).
FITTED_SCALARS: dict[str, tuple[str, str]] = {
    "range_noise.std": ("range_noise", "std"),
    "range_noise.dropout": ("range_noise", "dropout"),
    "vision.bearing_std_deg": ("vision", "bearing_std_deg"),
    "vision.distance_rel_std": ("vision", "distance_rel_std"),
    "vision.dropout": ("vision", "dropout"),
}


@dataclass(frozen=True)
class FittedProfile(HardwareProfile):
    """A :class:`HardwareProfile` fitted to a robot's logs (``cyber-rodent sysid``).

    Its actuators are :class:`FittedActuators` (explicit per-robot values); its noise parts hold
    the fitted magnitudes. Domain randomisation (:meth:`randomised`) draws every fitted value
    from a normal distribution around it with its standard error (clipped to the field's
    range), instead of scaling the magnitudes from zero as the hand-set profile does.

    Attributes:
        uncertainty: standard errors of the scalar noise parameters, as (name, sd) pairs with
            names from :data:`FITTED_SCALARS`; each sd >= 0 (bootstrap over log segments).
    """

    actuators: ActuatorVariation = dataclasses.field(default_factory=FittedActuators)
    uncertainty: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.actuators, FittedActuators):
            raise ValueError(f"actuators must be FittedActuators, got {self.actuators!r}")
        pairs = []
        for item in self.uncertainty:
            if not isinstance(item, tuple | list) or len(item) != 2:
                raise ValueError(f"uncertainty entries must be (name, sd) pairs, got {item!r}")
            name = check_choice("uncertainty name", item[0], tuple(FITTED_SCALARS))
            pairs.append((name, check_number(f"uncertainty[{name}]", item[1], 0.0, 100.0)))
        object.__setattr__(self, "uncertainty", tuple(pairs))

    def sd(self, name: str) -> float:
        """The standard error of scalar ``name`` (0 if the fit gave none)."""
        return dict(self.uncertainty).get(name, 0.0)

    def randomised(self, rng: np.random.Generator) -> HardwareProfile:
        """A profile drawn around the fit: each value from N(value, sd), clipped to its
        field's range; the drive's per-robot values likewise (:meth:`FittedActuators.drawn`)."""
        z = rng.standard_normal(len(FITTED_SCALARS))
        changes: dict[str, dict[str, float]] = {}
        for k, (name, (part, field)) in enumerate(FITTED_SCALARS.items()):
            config = getattr(self, part)
            rule = next(f for f in dataclasses.fields(config) if f.name == field).metadata[RULE]
            value = float(np.clip(getattr(config, field) + self.sd(name) * z[k], 0.0, rule.high))
            changes.setdefault(part, {})[field] = value
        parts = {p: dataclasses.replace(getattr(self, p), **c) for p, c in changes.items()}
        assert isinstance(self.actuators, FittedActuators)
        return dataclasses.replace(self, **parts, actuators=self.actuators.drawn(rng))


def _part_from(cls: type, name: str, record: object) -> object:
    if not isinstance(record, dict):
        raise ValueError(f"profile file: {name} must be an object, got {record!r}")
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(record) - known)
    if unknown:
        raise ValueError(f"profile file: {name}.{unknown[0]} is not a field of {cls.__name__}")
    values = {k: tuple(map(tuple, v)) if k == "wheel_gain" or k == "wheel_gain_sd"
              else tuple(v) if isinstance(v, list) else v for k, v in record.items()}  # fmt: skip
    return cls(**values)


def profile_record(profile: HardwareProfile) -> dict[str, object]:
    """The JSON object a profile file holds for ``profile`` (``kind``: hardware or fitted)."""
    kind = "fitted" if isinstance(profile, FittedProfile) else "hardware"
    return {"kind": kind, **json.loads(json.dumps(dataclasses.asdict(profile)))}


def profile_from_record(record: object) -> HardwareProfile:
    """The profile a profile file's ``profile`` object describes (:func:`profile_record`).

    Raises:
        ValueError: one line naming the first field that is missing, unknown or out of range.
    """
    if not isinstance(record, dict):
        raise ValueError(f"profile file: profile must be an object, got {record!r}")
    record = dict(record)
    kind = check_choice(
        "profile file: profile.kind", record.pop("kind", None), ("hardware", "fitted")
    )
    fitted = kind == "fitted"
    classes = dict(
        zip(
            PROFILE_PARTS,
            (RangeNoise, VisionUncertainty, FittedActuators if fitted else ActuatorVariation,
             FieldLayout),
            strict=True,
        )
    )  # fmt: skip
    known = set(PROFILE_PARTS) | ({"uncertainty"} if fitted else set())
    unknown = sorted(set(record) - known)
    if unknown:
        raise ValueError(f"profile file: profile.{unknown[0]} is not a part of a {kind} profile")
    parts = {p: _part_from(c, p, record[p]) for p, c in classes.items() if p in record}
    if fitted:
        pairs = tuple(tuple(x) if isinstance(x, list) else x for x in record.get("uncertainty", []))
        return FittedProfile(**parts, uncertainty=pairs)  # type: ignore[arg-type]
    return HardwareProfile(**parts)  # type: ignore[arg-type]


def save_profile(
    path: str | os.PathLike[str], profile: HardwareProfile, provenance: Mapping[str, object]
) -> Path:
    """Write ``profile`` (and what produced it) as a profile file, atomically."""
    record = {
        "format": PROFILE_FILE_FORMAT,
        "version": PROFILE_FILE_VERSION,
        "profile": profile_record(profile),
        "provenance": provenance,
    }
    return write_json(path, record)


def load_profile(path: str | os.PathLike[str]) -> HardwareProfile:
    """The profile in a profile file (:func:`save_profile`).

    Raises:
        ValueError: one line: not a readable JSON file, another format or version, or a bad
            field (named).
    """
    p = Path(path)
    try:
        record = json.loads(p.read_text())
    except (OSError, ValueError) as err:
        raise ValueError(f"profile file {p}: cannot read it as JSON ({err})") from None
    if not isinstance(record, dict) or record.get("format") != PROFILE_FILE_FORMAT:
        raise ValueError(f"profile file {p}: format must be {PROFILE_FILE_FORMAT!r}")
    if record.get("version") != PROFILE_FILE_VERSION:
        raise ValueError(
            f"profile file {p}: version must be {PROFILE_FILE_VERSION}, got "
            f"{record.get('version')!r}"
        )
    try:
        return profile_from_record(record.get("profile"))
    except (TypeError, ValueError) as err:
        raise ValueError(f"{p}: {err}") from None


def profile_from_arg(text: str) -> HardwareProfile | None:
    """What ``--profile TEXT`` names: ``sim`` (None), ``hardware``, or a profile file's path.

    Raises:
        ValueError: one line: neither a name nor an existing file, or a bad file.
    """
    if text in PROFILE_NAMES:
        return profile_by_name(text)
    if not Path(text).is_file():
        raise ValueError(
            f"--profile must be one of {', '.join(PROFILE_NAMES)} or a profile file "
            f"(cyber-rodent sysid --out), got {text!r}"
        )
    return load_profile(text)


__all__ = [
    "FITTED_SCALARS",
    "PROFILE_FILE_FORMAT",
    "PROFILE_FILE_VERSION",
    "PROFILE_NAMES",
    "PROFILE_PARTS",
    "ActuatorSample",
    "ActuatorVariation",
    "FieldLayout",
    "FittedActuators",
    "FittedProfile",
    "HardwareProfile",
    "RangeNoise",
    "RangeSensorNoise",
    "VisionUncertainty",
    "apply_actuators",
    "apply_field",
    "apply_vision",
    "load_profile",
    "profile_by_name",
    "profile_from_arg",
    "profile_from_record",
    "profile_record",
    "randomised",
    "save_profile",
]
