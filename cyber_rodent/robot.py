"""The robot as an object: its body read from its MJCF file, its sensors from a declared table.

A :class:`RobotModel` is everything the code knows about one kind of robot:

* its **body and drive**, read from the compiled MJCF (:meth:`RobotModel.from_mjcf`): wheel
  radius, half wheel base, top speed (the wheel servos' ``ctrlrange`` x the wheel radius),
  chassis length, mass, motor time constant and the clearance disc placement keeps free;
* its **sensors**, a declared table of :class:`SensorRow` (in the way
  ``evolution.input_kernels.INPUTS`` declares the controller's inputs): each row names an MJCF
  sensor, its kind and what the code cannot read from the file (a range sensor's range, the
  direction it faces), and :meth:`RobotModel.from_mjcf` checks each row against the file;
* the MJCF **parts** the world finds by name (:class:`RobotParts`).

The world is built from a robot model (``WorldConfig.robot`` names one of :data:`ROBOTS`), and
the survival rules (the wheel limit), the commands, the observation table, the hardware profile
and the deploy bundle's spec read it from the world. Two kinds of robot can live in one process:
each world holds its own model.

A **sensor kind** (:class:`SensorKind`, :data:`SENSOR_KINDS`) says which MJCF sensor element
measures it, how one raw reading becomes a value and the value's bounds. ``range`` (an IR
rangefinder that saturates at its range) is built in; another kind is a row of
:data:`SENSOR_KINDS` plus its reader (:func:`register_sensor_kind`, ``docs/extending.md`` §8).
A row whose sensor the MJCF lacks is added to the model at build time by its kind, at the row's
site, so a new sensor needs no edit of the robot's file.

Two robots are built in (:data:`ROBOTS`): ``cyber_rodent`` (the paper's robot,
``assets/mjcf/cyber_rodent.xml``) and ``small_disc`` (an e-puck or Thymio class robot,
``assets/mjcf/small_disc.xml``: ``docs/extending.md`` §9).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.assets import asset_path


# --- sensor kinds ------------------------------------------------------------------------------
def _read_range(raw: np.ndarray, limit: np.ndarray, out: np.ndarray) -> None:
    """A rangefinder reads -1 when its ray hits nothing; an IR sensor saturates at its range."""
    np.copyto(out, raw)
    np.putmask(out, (raw < 0) | (raw > limit), limit)


@dataclass(frozen=True)
class SensorKind:
    """One kind of sensor: how the MJCF measures it and how a raw reading becomes a value.

    Attributes:
        name: the kind's name, the ``kind`` of a :class:`SensorRow`.
        element: the MJCF sensor element that measures it (``rangefinder``, ``gyro``, ``touch``
            …); MuJoCo's sensor type must match.
        component: which component of the element's output is the reading (0 for a scalar
            sensor; 2 for a gyro's yaw rate).
        unit: the value's physical unit.
        read: ``read(raw, limit, out)``: writes into ``out`` (n_robots, k) the values of the
            kind's k sensors from their raw readings ``raw`` (n_robots, k) and the rows'
            ``limit`` (k,); values lie in [-limit, limit] (``signed``) or [0, limit].
        signed: the value may be negative (bounds [-limit, limit]), else [0, limit].
        proximity: the observation reads it reversed, as a proximity (``1 - value / limit``:
            0 = nothing in range, 1 = touching), like the range sensors.
    """

    name: str
    element: str
    component: int
    unit: str
    read: Callable[[np.ndarray, np.ndarray, np.ndarray], None]
    signed: bool = False
    proximity: bool = False

    @property
    def sensor_type(self) -> mujoco.mjtSensor:
        """MuJoCo's sensor type of :attr:`element`."""
        return getattr(mujoco.mjtSensor, f"mjSENS_{self.element.upper()}")


#: The sensor kinds, by name. ``range`` is the Cyber Rodent's IR rangefinder.
SENSOR_KINDS: dict[str, SensorKind] = {
    "range": SensorKind("range", "rangefinder", 0, "m", _read_range, proximity=True),
}


def register_sensor_kind(kind: SensorKind) -> None:
    """Add a sensor kind (``docs/extending.md`` §8). A name already taken is refused."""
    if kind.name in SENSOR_KINDS:
        raise ValueError(f"sensor kind {kind.name!r} is already registered")
    if not hasattr(mujoco.mjtSensor, f"mjSENS_{kind.element.upper()}"):
        raise ValueError(
            f"sensor kind {kind.name!r}: element {kind.element!r} is not a MuJoCo sensor"
        )
    SENSOR_KINDS[kind.name] = kind


def unregister_sensor_kind(name: str) -> None:
    """Remove a kind added by :func:`register_sensor_kind` (``range`` stays)."""
    if name == "range":
        raise ValueError("sensor kind 'range' is built in")
    SENSOR_KINDS.pop(name, None)


# --- the sensor table --------------------------------------------------------------------------
@dataclass(frozen=True)
class SensorRow:
    """One sensor of a robot.

    Attributes:
        name: the MJCF sensor's name (also its observation entry's name).
        kind: its kind, a key of :data:`SENSOR_KINDS`.
        limit: the largest value it reads in the kind's unit: a range sensor's range (m;
            beyond it the reading saturates), a gyro's largest rate.
        bearing_deg: the direction it faces in the robot's frame, degrees counter-clockwise
            from straight ahead (checked against its site's axis for a range sensor).
        site: the MJCF site it sits at; defaults to ``name``. A row whose sensor the file lacks
            is added at this site when the world is built.
    """

    name: str
    kind: str
    limit: float
    bearing_deg: float = 0.0
    site: str = ""

    @property
    def site_name(self) -> str:
        return self.site or self.name


@dataclass(frozen=True)
class RobotParts:
    """The MJCF names of the parts the world and the survival mechanics find by name.

    Every robot file names its parts this way (``assets/mjcf/cyber_rodent.xml`` is the
    reference); :meth:`RobotModel.from_mjcf` refuses a file that lacks one.
    """

    root_body: str = "chassis"
    chassis_geom: str = "chassis_geom"
    left_motor: str = "left_motor"
    right_motor: str = "right_motor"
    left_wheel_joint: str = "left_wheel"
    right_wheel_joint: str = "right_wheel"
    left_wheel_geom: str = "left_wheel_contact"
    right_wheel_geom: str = "right_wheel_contact"
    led_geom: str = "led"
    face_geom: str = "face"
    teeth_geom: str = "teeth"
    ir_port_site: str = "ir_port"
    camera_site: str = "camera_mount"


def _round(value: float) -> float:
    """A length or speed read from the model, to the micrometre (µm/s): the MJCF writes
    numbers to 6-8 digits, so 37.142857 rad/s x 0.035 m is the 1.3 m/s it stands for."""
    return round(float(value), 6)


@dataclass(frozen=True)
class RobotModel:
    """One kind of robot (see the module docstring). Build it with :meth:`from_mjcf`.

    Attributes:
        name: its name, a key of :data:`ROBOTS` (``WorldConfig.robot``).
        xml: the MJCF file, a name under the assets directory or a path.
        sensors: the sensor table, in the order the observation and the readings use.
        proximity: indices into the range sensors (rows of kind ``range``, in table order) of
            the proximity inputs the behaviours and the controller read (the Cyber Rodent's
            five front and one back sensor).
        parts: the MJCF part names.
        wheel_radius: m, the wheel contact sphere's radius.
        half_wheel_base: m, from a wheel's contact point to the robot's centre line.
        top_speed: m/s, the largest wheel rim speed (servo ``ctrlrange`` x wheel radius).
        body_length: m, the chassis box's length.
        footprint_radius: m, the radius of the smallest disc about the robot's origin that
            holds every geom's outline seen from above.
        body_radius: m, the clearance disc placement keeps free (the footprint rounded up to
            the centimetre).
        mass: kg, the robot's total mass.
        motor_time_constant: s, the wheel servos' first-order lag.
    """

    name: str
    xml: str
    sensors: tuple[SensorRow, ...]
    proximity: tuple[int, ...]
    parts: RobotParts
    wheel_radius: float
    half_wheel_base: float
    top_speed: float
    body_length: float
    footprint_radius: float
    body_radius: float
    mass: float
    motor_time_constant: float

    # --- the sensor table, by kind -------------------------------------------------------------
    def rows_of(self, kind: str) -> tuple[SensorRow, ...]:
        """The sensor rows of ``kind``, in table order."""
        return tuple(row for row in self.sensors if row.kind == kind)

    @property
    def range_sensors(self) -> tuple[SensorRow, ...]:
        """The range sensors (kind ``range``), whose readings :meth:`World.range_readings`
        returns in this order."""
        return self.rows_of("range")

    @property
    def n_range(self) -> int:
        return len(self.range_sensors)

    @property
    def range_limits(self) -> np.ndarray:
        """(n_range,) each range sensor's range, m."""
        return np.array([row.limit for row in self.range_sensors], dtype=np.float64)

    @property
    def other_sensors(self) -> tuple[SensorRow, ...]:
        """The rows of every kind but ``range``, in table order (:meth:`World.sensor_values`)."""
        return tuple(row for row in self.sensors if row.kind != "range")

    @property
    def max_wheel_omega(self) -> float:
        """rad/s, the wheel servos' command limit."""
        return self.top_speed / self.wheel_radius

    def with_sensors(self, *rows: SensorRow, name: str | None = None) -> RobotModel:
        """This robot with ``rows`` added to its sensor table (checked against its file and
        added to its model at build time where the file lacks them)."""
        return RobotModel.from_mjcf(
            name or self.name,
            self.xml,
            (*self.sensors, *rows),
            self.proximity,
            self.parts,
        )

    # --- building -------------------------------------------------------------------------------
    def xml_path(self) -> Path:
        """The MJCF file's absolute path."""
        path = Path(self.xml)
        return path if path.is_absolute() else asset_path(self.xml)

    @classmethod
    def from_mjcf(
        cls,
        name: str,
        xml: str,
        sensors: tuple[SensorRow, ...],
        proximity: tuple[int, ...],
        parts: RobotParts | None = None,
    ) -> RobotModel:
        """Read a robot's body and drive from its MJCF file and check its sensor table.

        Raises:
            ValueError: one line naming what the file and the table disagree on: a missing
                part, a sensor of another type, a range sensor facing elsewhere than its row
                says, a proximity index out of range, an unknown kind.
        """
        parts = parts or RobotParts()
        path = Path(xml) if Path(xml).is_absolute() else asset_path(xml)
        spec = mujoco.MjSpec.from_file(str(path))
        _add_missing_sensors(spec, sensors)
        try:
            model = spec.compile()
        except ValueError as error:  # MuJoCo's message, e.g. a sensor's missing site
            first = str(error).strip().splitlines()[0]
            raise ValueError(f"robot {name!r}: {path.name} does not compile: {first}") from None
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)

        def obj(kind: mujoco.mjtObj, part: str) -> int:
            idx = int(mujoco.mj_name2id(model, kind, part))
            if idx < 0:
                what = kind.name[6:].lower()
                raise ValueError(f"robot {name!r}: {path.name} has no {what} {part!r}")
            return idx

        left = obj(mujoco.mjtObj.mjOBJ_GEOM, parts.left_wheel_geom)
        right = obj(mujoco.mjtObj.mjOBJ_GEOM, parts.right_wheel_geom)
        motor = obj(mujoco.mjtObj.mjOBJ_ACTUATOR, parts.left_motor)
        obj(mujoco.mjtObj.mjOBJ_ACTUATOR, parts.right_motor)
        chassis = obj(mujoco.mjtObj.mjOBJ_GEOM, parts.chassis_geom)
        for geom in (parts.led_geom, parts.face_geom, parts.teeth_geom):
            obj(mujoco.mjtObj.mjOBJ_GEOM, geom)
        for site in (parts.ir_port_site, parts.camera_site):
            obj(mujoco.mjtObj.mjOBJ_SITE, site)
        obj(mujoco.mjtObj.mjOBJ_BODY, parts.root_body)
        wheel_radius = float(model.geom_size[left, 0])
        _check_sensors(name, path.name, model, data, sensors)
        n_range = sum(row.kind == "range" for row in sensors)
        for index in proximity:
            if not 0 <= index < n_range:
                raise ValueError(
                    f"robot {name!r}: proximity index {index} must be in [0, {n_range - 1}]"
                )
        footprint = _footprint_radius(model, data)
        return cls(
            name=name,
            xml=xml,
            sensors=tuple(sensors),
            proximity=tuple(proximity),
            parts=parts,
            wheel_radius=_round(wheel_radius),
            half_wheel_base=_round(
                (abs(data.geom_xpos[left, 1]) + abs(data.geom_xpos[right, 1])) / 2
            ),
            top_speed=_round(model.actuator_ctrlrange[motor, 1] * wheel_radius),
            body_length=_round(2 * model.geom_size[chassis, 0]),
            footprint_radius=_round(footprint),
            body_radius=math.ceil(round(footprint * 100, 6)) / 100,
            mass=_round(model.body_subtreemass[obj(mujoco.mjtObj.mjOBJ_BODY, parts.root_body)]),
            motor_time_constant=_round(model.actuator_dynprm[motor, 0]),
        )


def _add_missing_sensors(spec: mujoco.MjSpec, sensors: tuple[SensorRow, ...]) -> None:
    present = {s.name for s in spec.sensors}
    for row in sensors:
        if row.kind not in SENSOR_KINDS:
            known = ", ".join(sorted(SENSOR_KINDS))
            raise ValueError(f"sensor {row.name!r}: kind must be one of {known}, got {row.kind!r}")
        if row.name not in present:
            kind = SENSOR_KINDS[row.kind]
            spec.add_sensor(
                name=row.name,
                type=kind.sensor_type,
                objtype=mujoco.mjtObj.mjOBJ_SITE,
                objname=row.site_name,
            )


def _check_sensors(
    name: str, file: str, model: mujoco.MjModel, data: mujoco.MjData, rows: tuple[SensorRow, ...]
) -> None:
    for row in rows:
        kind = SENSOR_KINDS[row.kind]
        sid = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, row.name))
        if sid < 0:
            raise ValueError(f"robot {name!r}: {file} has no sensor {row.name!r}")
        if model.sensor_type[sid] != kind.sensor_type:
            raise ValueError(
                f"robot {name!r}: sensor {row.name!r} is not a {kind.element} (kind {row.kind!r})"
            )
        if not row.limit > 0:
            raise ValueError(f"robot {name!r}: sensor {row.name!r} limit must be > 0")
        if kind.component >= model.sensor_dim[sid]:
            raise ValueError(
                f"robot {name!r}: sensor {row.name!r} has {model.sensor_dim[sid]} components, "
                f"kind {row.kind!r} reads component {kind.component}"
            )
        if row.kind == "range":
            # A rangefinder measures along its site's +z axis: the row's bearing must be it.
            site = int(model.sensor_objid[sid])
            axis = data.site_xmat[site].reshape(3, 3)[:, 2]
            bearing = math.degrees(math.atan2(axis[1], axis[0]))
            gap = (bearing - row.bearing_deg + 180.0) % 360.0 - 180.0
            if abs(gap) > 0.5:
                raise ValueError(
                    f"robot {name!r}: sensor {row.name!r} faces {bearing:.1f} deg, "
                    f"its row says {row.bearing_deg:g}"
                )


def _footprint_radius(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """The largest distance from the robot's origin, seen from above, of any point of any geom:
    a sphere's or upright cylinder's rim, else the corners of the geom's bounding box."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    far = 0.0
    round_types = (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CYLINDER)
    for g in range(model.ngeom):
        upright = data.geom_xmat[g, 8] > 1 - 1e-9
        if int(model.geom_type[g]) in round_types and (
            upright or int(model.geom_type[g]) == mujoco.mjtGeom.mjGEOM_SPHERE
        ):
            rim = float(np.hypot(*data.geom_xpos[g, :2])) + float(model.geom_size[g, 0])
            far = max(far, rim)
            continue
        centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        corners = centre + signs * half  # (8, 3) in the geom's frame
        world = data.geom_xpos[g] + corners @ data.geom_xmat[g].reshape(3, 3).T
        far = max(far, float(np.hypot(world[:, 0], world[:, 1]).max()))
    return far


# --- the built-in robots -----------------------------------------------------------------------
#: The Cyber Rodent's sensors in ``sensordata`` order: index 0 is the long-range sensor facing
#: forward, 0..4 the front arc, 5 the back, 6/7 the sides (docs/design.md §4).
CYBER_RODENT_SENSORS: tuple[SensorRow, ...] = (
    SensorRow("range_front", "range", 1.0, 0.0),
    SensorRow("range_front_left30", "range", 0.3, 30.0),
    SensorRow("range_front_right30", "range", 0.3, -30.0),
    SensorRow("range_front_left60", "range", 0.3, 60.0),
    SensorRow("range_front_right60", "range", 0.3, -60.0),
    SensorRow("range_back", "range", 0.3, 180.0),
    SensorRow("range_left", "range", 0.3, 90.0),
    SensorRow("range_right", "range", 0.3, -90.0),
)
#: The "six proximity" sensors of Search and the controller: the 5 front and the back one.
CYBER_RODENT_PROXIMITY: tuple[int, ...] = (0, 1, 2, 3, 4, 5)

#: An e-puck / Thymio class robot's eight IR proximity sensors: the Cyber Rodent's layout (its
#: sites are named and placed alike in ``small_disc.xml``), each reaching 8 cm (4-10 cm on the
#: real robots).
SMALL_DISC_SENSORS: tuple[SensorRow, ...] = tuple(
    dataclasses.replace(row, limit=0.08) for row in CYBER_RODENT_SENSORS
)

#: How to build each registered robot: name → a function returning its model. A builder runs
#: once, on first use (:func:`robot_model`).
_BUILDERS: dict[str, Callable[[], RobotModel]] = {
    "cyber_rodent": lambda: RobotModel.from_mjcf(
        "cyber_rodent", C.ROBOT_XML, CYBER_RODENT_SENSORS, CYBER_RODENT_PROXIMITY
    ),
    "small_disc": lambda: RobotModel.from_mjcf(
        "small_disc", "small_disc.xml", SMALL_DISC_SENSORS, CYBER_RODENT_PROXIMITY
    ),
}
_BUILT: dict[str, RobotModel] = {}


def robot_names() -> tuple[str, ...]:
    """The registered robots' names (``WorldConfig.robot``'s choices)."""
    return tuple(_BUILDERS)


#: The robots' registry, by name (read it through :func:`robot_model`).
ROBOTS = _BUILDERS


def robot_model(name: str = "cyber_rodent") -> RobotModel:
    """The registered robot ``name``, built from its file on first use."""
    if name not in _BUILDERS:
        raise ValueError(f"robot must be one of {', '.join(robot_names())}, got {name!r}")
    if name not in _BUILT:
        _BUILT[name] = _BUILDERS[name]()
    return _BUILT[name]


def register_robot(robot: RobotModel | Callable[[], RobotModel], name: str | None = None) -> None:
    """Add a robot to the registry (``docs/extending.md`` §9): a model, or a function that
    builds one on first use (then give ``name``). A name already taken is refused."""
    key = robot.name if isinstance(robot, RobotModel) else name
    if not key:
        raise ValueError("register_robot: a builder function needs a name")
    if key in _BUILDERS:
        raise ValueError(f"robot {key!r} is already registered")
    if isinstance(robot, RobotModel):
        _BUILDERS[key] = lambda: robot
        _BUILT[key] = robot
    else:
        _BUILDERS[key] = robot


def unregister_robot(name: str) -> None:
    """Remove a robot added by :func:`register_robot` (the built-in ones stay)."""
    if name in ("cyber_rodent", "small_disc"):
        raise ValueError(f"robot {name!r} is built in")
    _BUILDERS.pop(name, None)
    _BUILT.pop(name, None)


def cyber_rodent() -> RobotModel:
    """The paper's robot (``WorldConfig.robot``'s default)."""
    return robot_model("cyber_rodent")


__all__ = [
    "CYBER_RODENT_PROXIMITY",
    "CYBER_RODENT_SENSORS",
    "ROBOTS",
    "SENSOR_KINDS",
    "SMALL_DISC_SENSORS",
    "RobotModel",
    "RobotParts",
    "SensorKind",
    "SensorRow",
    "cyber_rodent",
    "register_robot",
    "register_sensor_kind",
    "robot_model",
    "robot_names",
    "unregister_robot",
    "unregister_sensor_kind",
]
