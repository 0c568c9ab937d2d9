"""What one robot observes in every task interface, defined once.

The observation is a flat vector of named entries, 21 for the Cyber Rodent
(:data:`OBSERVATIONS`, in vector order): its 8 IR range readings, the bearing, distance and
visibility of the nearest green LED, red face and blue battery pack, the robot's energy, its LED,
whether it is docked, and the control steps recharged in the current docking. Another robot
(``WorldConfig.robot``) has its own range sensors first and any sensors of other kinds last
(:func:`observation_table` of its sensor table, ``cyber_rodent.robot``). This table is the
one place that says, for each entry, its name, its physical unit, its bounds and how it is
normalised; the environments
(:mod:`cyber_rodent.gym_env`, :mod:`cyber_rodent.colony_env`) and the dm-control tasks
(:mod:`cyber_rodent.tasks.base`) build their observation spaces and their observations from it
(through :meth:`cyber_rodent.tasks.episode.TaskEpisode.observations`), for every task alike.

Two kinds of observation (:data:`OBSERVATION_KINDS`, the environments' ``observation=``):

* ``"normalised"`` (the default): every entry mapped linearly by its bounds into [0, 1], as the
  paper maps every sensory input to "the normalized linear interval [0, 1]" (§3.4) and as the
  behaviours' and the controller's inputs are (``docs/design.md`` §9.19), except the bearings,
  which are signed, in [−1, 1]: 0 straight ahead, the sign the side. A learner must tell left
  from right at straight ahead, and a network whose units start centred on zero inputs does
  so from the start when ahead is 0 rather than 0.5: with every hyperparameter at
  Stable-Baselines3's default, DQN docked in 54–72 % of Forage episodes after 100,000 steps
  with bearings in [0, 1], and in 98–100 % with bearings in [−1, 1] (training seeds 0, 1, 2;
  50 episodes that are not the benchmark's evaluation episodes). An entry's raw value ``zero``
  reads 0 and ``one`` reads 1 (:class:`ObservationScale`), linearly in between and clipped to
  the entry's normalised bounds; the observation space's ``low`` (−1 for the bearings, else 0)
  and ``high`` (1) say so.
* ``"raw"``: physical units (metres, radians, energy, control steps); the space's ``low`` and
  ``high`` are the bounds of the table.

=====================  =============  ===============  ============================================
entries                unit           raw bounds       normalised
=====================  =============  ===============  ============================================
8 ``range_*``          m              [0, range_max]   proximity ``1 − range / range_max``: 0 =
                                      (1.0 front,      nothing in range, 1 = touching (the CR's IR
                                      0.3 others)      sensors measure proximity)
``*_bearing``          rad            [−π, π]          ``bearing / π`` in [−1, 1]: 0 straight
                                                       ahead, > 0 on the left, ±1 behind; 0 when
                                                       unseen
``*_distance``         m              [0, max_range]   ``distance / max_range``; 1 when unseen
``*_visible``          flag           {0, 1}           as is
``energy``             energy         [0, max_energy]  ``energy / max_energy``: 0.5 at birth in
                                                       Survival (100 of 200); the behaviour tasks'
                                                       endless energy (1e6 of 1e6) reads full, 1
                                                       (less 1e-6 per step)
``led_on``, ``docked`` flag           {0, 1}           as is
``recharge_steps``     control steps  [0, max_rs]      ``recharge_steps / max_recharge_steps`` (40)
=====================  =============  ===============  ============================================

``max_range`` is the camera's range (the field's diagonal, 3.25 m, by default); an unseen
target reads bearing 0, distance ``max_range``, visible 0 in raw units, so 0, 1, 0 normalised.
The dm-control tasks observe this very table in float64, its entries grouped by name
(:data:`OBSERVATION_GROUPS`: ``range``, ``nearest_led`` …), and build their specs from the same
bounds (:meth:`ObservationLimits.intervals`). The normalised distance is the behaviours'
distance input (``behaviours.inputs``), the normalised bearing ``2 x − 1`` of their
bearing input ``x``, and the proximities are the readings their Search input is taken from.

The environments read what the robots see through :func:`nearest_frame`: each robot's nearest
LED, face and pack, the only part of the vision the observation, the start conditions and the
rewards use. With the geometric vision and no vision noise it is
:meth:`~cyber_rodent.vision.geometric.GeometricVision.nearest_targets`, the lazy pass that
casts rays only until the nearest target of each class is certain (bit for bit the nearest
targets of the full pass, ``tests/test_vision_nearest.py``); otherwise the provider's
``observe()``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from cyber_rodent.robot import CYBER_RODENT_SENSORS, SENSOR_KINDS, SensorRow
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.validation import check_choice
from cyber_rodent.vision import (
    BATTERY,
    FACE,
    LED,
    GeometricVision,
    VisionFrame,
    VisionProvider,
)

#: The kinds of observation: normalised (the default: bearings in [−1, 1], the rest in [0, 1]),
#: or in physical units.
OBSERVATION_KINDS = ("normalised", "raw")

#: How an entry is bounded and normalised (see the module docstring). SENSOR: a sensor of a kind
#: other than ``range`` (``cyber_rodent.robot.SENSOR_KINDS``), bounded by its row's limit.
RANGE, BEARING, DISTANCE, FLAG, ENERGY, RECHARGE_STEPS, SENSOR = (
    "range", "bearing", "distance", "flag", "energy", "recharge_steps", "sensor"
)  # fmt: skip


@dataclass(frozen=True)
class ObservationEntry:
    """One entry of the observation vector.

    Attributes:
        name: its name (``observation_names``).
        unit: the unit of its raw value (``observation_units``).
        quantity: what bounds and normalises it: :data:`RANGE`, :data:`BEARING`,
            :data:`DISTANCE`, :data:`FLAG`, :data:`ENERGY`, :data:`RECHARGE_STEPS` or
            :data:`SENSOR`.
        limit: a :data:`SENSOR` entry's bound (its row's ``limit``): raw [0, limit], or
            [-limit, limit] if ``signed``; normalised linearly onto [0, 1] (or [-1, 1]).
        signed: a :data:`SENSOR` entry may be negative.
    """

    name: str
    unit: str
    quantity: str
    limit: float = 0.0
    signed: bool = False


_TARGETS = (("led", LED), ("face", FACE), ("battery", BATTERY))
#: The robot's own entries, after the sensors and the targets.
_OWN: tuple[ObservationEntry, ...] = (
    ObservationEntry("energy", "energy", ENERGY),
    ObservationEntry("led_on", "flag", FLAG),
    ObservationEntry("docked", "flag", FLAG),
    ObservationEntry("recharge_steps", "control steps", RECHARGE_STEPS),
)


@dataclass(frozen=True)
class ObservationTable:
    """One kind of robot's observation vector: its range sensors, the three nearest targets,
    its own four entries, then its sensors of other kinds (``RobotModel.other_sensors``).

    Attributes:
        entries: every entry, in vector order.
        n_range: how many range sensors come first.
    """

    entries: tuple[ObservationEntry, ...]
    n_range: int

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(entry.name for entry in self.entries)

    @property
    def units(self) -> tuple[str, ...]:
        return tuple(entry.unit for entry in self.entries)

    @property
    def size(self) -> int:
        return len(self.entries)

    @property
    def first_own(self) -> int:
        """The column of the first of the robot's own entries (energy)."""
        return self.n_range + 3 * len(_TARGETS)

    @property
    def first_sensor(self) -> int:
        """The column of the first sensor of a kind other than ``range``."""
        return self.first_own + len(_OWN)

    @property
    def groups(self) -> tuple[tuple[str, slice | int], ...]:
        """The entries grouped as the dm-control tasks name them (:mod:`cyber_rodent.tasks.
        base`): the ranges, each target's bearing, distance and visibility, then every other
        entry on its own. A group is its name and its columns: a slice, or one column."""
        n = self.n_range
        return (
            ("range", slice(0, n)),
            *(
                (f"nearest_{target}", slice(n + 3 * k, n + 3 * k + 3))
                for k, (target, _) in enumerate(_TARGETS)
            ),
            *((self.entries[i].name, i) for i in range(self.first_own, self.size)),
        )


@cache
def observation_table(sensors: tuple[SensorRow, ...] = CYBER_RODENT_SENSORS) -> ObservationTable:
    """The observation table of a robot with the sensor table ``sensors``
    (``RobotModel.sensors``; the default: the Cyber Rodent's)."""
    ranges = [row for row in sensors if row.kind == "range"]
    others = [row for row in sensors if row.kind != "range"]
    entries = (
        *(ObservationEntry(row.name, "m", RANGE) for row in ranges),
        *(
            entry
            for target, _ in _TARGETS
            for entry in (
                ObservationEntry(f"{target}_bearing", "rad", BEARING),
                ObservationEntry(f"{target}_distance", "m", DISTANCE),
                ObservationEntry(f"{target}_visible", "flag", FLAG),
            )
        ),
        *_OWN,
        *(
            ObservationEntry(
                row.name,
                SENSOR_KINDS[row.kind].unit,
                SENSOR,
                float(row.limit),
                SENSOR_KINDS[row.kind].signed,
            )
            for row in others
        ),
    )
    return ObservationTable(tuple(entries), len(ranges))


#: The Cyber Rodent's table (the paper's robot); a world's is ``observation_table(world.robot.
#: sensors)``.
PAPER_TABLE = observation_table()
#: The Cyber Rodent's observation vector's entries, in order.
OBSERVATIONS: tuple[ObservationEntry, ...] = PAPER_TABLE.entries
OBSERVATION_NAMES: tuple[str, ...] = PAPER_TABLE.names
OBSERVATION_UNITS: tuple[str, ...] = PAPER_TABLE.units
N_OBSERVATIONS = PAPER_TABLE.size
#: The same entries grouped as the dm-control tasks name them (:attr:`ObservationTable.groups`).
OBSERVATION_GROUPS: tuple[tuple[str, slice | int], ...] = PAPER_TABLE.groups


class ObservationBounds(NamedTuple):
    """Per-entry bounds of the raw observation (float32, :data:`OBSERVATION_NAMES` order)."""

    low: np.ndarray
    high: np.ndarray


@dataclass(frozen=True)
class ObservationScale:
    """The normalisation of every entry: raw ``zero`` reads 0, raw ``one`` reads 1, linearly,
    clipped to [``low``, ``high``].

    Attributes:
        zero: (21,) float64, the raw value of each entry that normalises to 0.
        one: (21,) float64, the raw value that normalises to 1 (below ``zero`` for the ranges,
            which read as proximities).
        low: (21,) float32, each entry's normalised lower bound (−1 for the bearings, else 0).
        high: (21,) float32, its upper bound (1).
    """

    zero: np.ndarray
    one: np.ndarray
    low: np.ndarray
    high: np.ndarray

    def normalise(self, raw: np.ndarray) -> np.ndarray:
        """Raw observations (…, 21) as float32 within [``low``, ``high``]:
        ``(raw − zero) / (one − zero)``, clipped."""
        scaled = (np.asarray(raw, dtype=np.float64) - self.zero) / (self.one - self.zero)
        np.clip(scaled, self.low, self.high, out=scaled)
        scaled += 0.0  # a reversed entry's −0.0 reads 0.0
        normalised: np.ndarray = scaled.astype(np.float32)
        return normalised

    def raw(self, normalised: np.ndarray) -> np.ndarray:
        """Normalised observations (…, 21) back in physical units (float64; a raw value beyond
        the bounds was clipped, and float32 rounding stays)."""
        values = np.asarray(normalised, dtype=np.float64)
        raw: np.ndarray = self.zero + values * (self.one - self.zero)
        return raw


@dataclass(frozen=True)
class ObservationLimits:
    """What the bounds of one robot's observation depend on.

    Attributes:
        range_max: (n_range,) each range sensor's range, m (``World.range_max[0]``).
        max_range: the camera's range, m (an unseen target's distance).
        max_energy: the rules' maximum energy.
        max_recharge_steps: the rules' longest recharge, control steps.
        table: the robot's observation table (default: the Cyber Rodent's).
    """

    range_max: np.ndarray
    max_range: float
    max_energy: float
    max_recharge_steps: float
    table: ObservationTable = PAPER_TABLE

    @classmethod
    def of(
        cls,
        range_max: np.ndarray,
        max_range: float,
        survival: SurvivalConfig,
        table: ObservationTable = PAPER_TABLE,
    ) -> ObservationLimits:
        """The limits of a world's sensors, a camera's range and the rules ``survival``."""
        return cls(
            np.asarray(range_max, dtype=np.float64).copy(),
            float(max_range),
            float(survival.max_energy),
            float(survival.max_recharge_steps),
            table,
        )

    def intervals(self) -> ObservationBounds:
        """The raw observation's bounds, entry by entry, float64 (the dm-control specs')."""
        size = self.table.size
        low = np.zeros(size)
        high = np.ones(size)
        for i, entry in enumerate(self.table.entries):
            low[i], high[i] = self._interval(i, entry)
        return ObservationBounds(low, high)

    def bounds(self) -> ObservationBounds:
        """The raw observation's bounds, entry by entry (float32, the spaces')."""
        low, high = self.intervals()
        return ObservationBounds(low.astype(np.float32), high.astype(np.float32))

    def scale(self) -> ObservationScale:
        """The normalisation: each entry's bounds onto [0, 1], the ranges reversed
        (proximity), the bearings onto [−1, 1] (0 ahead)."""
        size = self.table.size
        zero = np.zeros(size)
        one = np.ones(size)
        low = np.zeros(size, dtype=np.float32)
        high = np.ones(size, dtype=np.float32)
        for i, entry in enumerate(self.table.entries):
            raw_low, raw_high = self._interval(i, entry)
            if entry.quantity == RANGE:
                zero[i], one[i] = raw_high, raw_low
            elif entry.quantity == BEARING or (entry.quantity == SENSOR and entry.signed):
                zero[i], one[i] = 0.0, raw_high
                low[i] = -1.0
            else:
                zero[i], one[i] = raw_low, raw_high
        return ObservationScale(zero, one, low, high)

    def space(self, kind: str) -> spaces.Box:
        """The observation space of ``kind`` (:data:`OBSERVATION_KINDS`)."""
        kind = check_observation(kind)
        bounds = self.bounds() if kind == "raw" else self.scale()
        return spaces.Box(bounds.low, bounds.high, dtype=np.float32)

    def _interval(self, index: int, entry: ObservationEntry) -> tuple[float, float]:
        quantity = entry.quantity
        if quantity == RANGE:
            return 0.0, float(self.range_max[index])
        if quantity == BEARING:
            return -math.pi, math.pi
        if quantity == DISTANCE:
            return 0.0, self.max_range
        if quantity == ENERGY:
            return 0.0, self.max_energy
        if quantity == RECHARGE_STEPS:
            return 0.0, self.max_recharge_steps
        if quantity == SENSOR:
            return (-entry.limit if entry.signed else 0.0), entry.limit
        return 0.0, 1.0  # a flag


def check_observation(value: object) -> str:
    """``value`` if it is an observation kind (:data:`OBSERVATION_KINDS`); else ValueError
    naming the argument and the allowed kinds."""
    kind: str = check_choice("observation", value, OBSERVATION_KINDS)
    return kind


def observation_bounds(
    range_max: np.ndarray, max_range: float, survival: SurvivalConfig
) -> ObservationBounds:
    """The raw bounds of one robot's observation.

    Args:
        range_max: (8,) each range sensor's range, m (``World.range_max[0]``).
        max_range: the camera's range, m (an unseen target's distance).
        survival: the rules (``max_energy``, ``max_recharge_steps``).
    """
    return ObservationLimits.of(range_max, max_range, survival).bounds()


def robot_observations(
    survival: SurvivalWorld,
    frame: VisionFrame,
    max_range: float,
    dtype: type[np.floating[Any]] = np.float32,
) -> np.ndarray:
    """(n_robots, table size): every robot's raw observation, a fresh array, in the order of
    its robot's table (:func:`observation_table`; the Cyber Rodent's: :data:`N_OBSERVATIONS`).

    Every value is computed in float64 and stored as ``dtype``: float32 for the Gymnasium and
    PettingZoo environments, float64 for the dm-control tasks (:data:`OBSERVATION_GROUPS`). An
    unseen target has bearing 0, distance ``max_range`` and visible 0.
    """
    world = survival.world
    table = observation_table(world.robot.sensors)
    n_range = table.n_range
    obs = np.empty((world.config.n_robots, table.size), dtype=dtype)
    obs[:, :n_range] = world.range_readings()
    for k, (_, cls) in enumerate(_TARGETS):
        col = n_range + 3 * k
        visible = frame.visible[:, cls]
        obs[:, col] = np.where(visible, frame.bearing[:, cls], 0.0)
        obs[:, col + 1] = np.where(
            visible, np.minimum(frame.distance[:, cls], max_range), max_range
        )
        obs[:, col + 2] = visible
    col = table.first_own
    obs[:, col] = survival.energy
    obs[:, col + 1] = world.led_on
    obs[:, col + 2] = survival.docked
    obs[:, col + 3] = survival.recharge_steps
    if table.size > table.first_sensor:
        obs[:, table.first_sensor :] = world.sensor_values()
    return obs


def nearest_frame(vision: VisionProvider) -> VisionFrame:
    """Every robot's nearest LED, face and pack in the world's current state, a fresh frame.

    The geometric vision without noise answers with its lazy nearest-target pass
    (:meth:`~cyber_rodent.vision.geometric.GeometricVision.nearest_targets`: the same nearest
    targets as ``observe()``, bit for bit, at a fraction of the rays) and the frame has no blob
    list; any other provider, or noisy vision (whose draws cover every target), answers with
    ``observe()``.
    """
    if isinstance(vision, GeometricVision) and not vision.config.noise.enabled:
        nearest = vision.nearest_targets()
        return VisionFrame(
            bearing=nearest.bearing.copy(),
            distance=nearest.distance.copy(),
            visible=nearest.visible.copy(),
            blobs=[[] for _ in range(vision.n_robots)],
        )
    return vision.observe()


__all__ = [
    "BEARING",
    "DISTANCE",
    "ENERGY",
    "FLAG",
    "N_OBSERVATIONS",
    "OBSERVATIONS",
    "OBSERVATION_GROUPS",
    "OBSERVATION_KINDS",
    "OBSERVATION_NAMES",
    "OBSERVATION_UNITS",
    "RANGE",
    "RECHARGE_STEPS",
    "ObservationBounds",
    "ObservationEntry",
    "ObservationLimits",
    "ObservationScale",
    "ObservationTable",
    "PAPER_TABLE",
    "SENSOR",
    "check_observation",
    "nearest_frame",
    "observation_bounds",
    "observation_table",
    "robot_observations",
]
