"""The field with N Cyber Rodents and M battery packs, assembled from the MJCF parts.

The world is the one physical object that the dm-control tasks, the behaviour learners and the
evolution runner all step. It keeps the hot path lean: every per-step quantity (wheel commands,
range readings, poses, LED state) is a numpy view into ``MjData`` or a precomputed index, read as
one flat slice, never by name (named access measured ~40x the cost of a slice read).

Assembly uses ``dm_control.mjcf`` (the pattern of dm_control's walkers: one XML per part,
attached with a name prefix), so the same compiled model also backs a ``dm_control`` ``Physics``
for the tasks. Placement is re-drawn at :meth:`World.reset` without recompiling: robots are free
bodies (qpos), packs are static bodies (``model.body_pos``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from dm_control import mjcf

from cyber_rodent import constants as C
from cyber_rodent.assets import asset_path
from cyber_rodent.validation import integer, number, validate_fields

#: Colours of the LED (RGBA). Off is dark green, not invisible: a real LED is still there.
LED_ON_RGBA = np.array([0.1, 1.0, 0.1, 1.0])
LED_OFF_RGBA = np.array([0.05, 0.15, 0.05, 1.0])
#: Colour (RGBA) of an inactive pack's body (``WorldConfig.pack_reactivation_steps``): a dark,
#: unsaturated grey that no colour class of the camera's segmentation takes for blue.
PACK_INACTIVE_RGBA = np.array([0.15, 0.15, 0.15, 1.0])
#: Upper bound of ``WorldConfig.pack_reactivation_steps``, the same as the survival rules' step
#: counts (``cyber_rodent.survival.config.MAX_STEP_COUNT``): 1e6 control steps are longer than
#: any experiment; a larger count is a typo.
MAX_REACTIVATION_STEPS = 1_000_000

_PLACEMENT_MARGIN = 0.02  # m, extra gap between placed bodies and to the walls
_MAX_PACKING_DENSITY = 0.4  # share of the usable field area that placed discs may cover
_PLACEMENT_ATTEMPTS = 2000
#: Default extra clearance between a pack and the walls (m, ``WorldConfig.pack_wall_clearance``):
#: a robot (18 cm wide) can always pass between them, so no robot gets wedged in a pack-wall gap
#: it cannot turn in.
PACK_WALL_CLEARANCE = 0.2
#: Default smallest gap between two packs (m, ``WorldConfig.pack_gap``): wider than a robot
#: turning in place (0.28 m), so no robot gets jammed between two packs (a 19 cm gap once held
#: a robot for the rest of a run).
PACK_GAP = 0.3


def _usable_area() -> float:
    half = C.FIELD_SIZE / 2
    return (2 * half) ** 2


def _pack_placement_radius(pack_gap: float = PACK_GAP) -> float:
    """Packs are placed as discs this big, which keeps ``pack_gap`` between any two."""
    return max(C.PACK_RADIUS + pack_gap / 2, C.PACK_RADIUS + _PLACEMENT_MARGIN)


def _pack_wall_margin(pack_gap: float, pack_wall_clearance: float) -> float:
    """How much further from the walls than its placement disc a pack's centre stays: the
    disc already holds half the pack gap, so only the rest of the clearance is added."""
    return max(0.0, C.PACK_RADIUS + pack_wall_clearance - _pack_placement_radius(pack_gap))


def _disc_area(n_robots: int, n_packs: int, pack_gap: float = PACK_GAP) -> float:
    r_robot = C.BODY_RADIUS + _PLACEMENT_MARGIN
    r_pack = _pack_placement_radius(pack_gap)
    return math.pi * (n_robots * r_robot**2 + n_packs * r_pack**2)


def _pack_square(pack_gap: float, pack_wall_clearance: float) -> float:
    """Side of the square that the packs' placement discs stay within (m)."""
    return C.FIELD_SIZE - 2 * _pack_wall_margin(pack_gap, pack_wall_clearance)


def _packs_fit(n_packs: int, pack_gap: float, pack_wall_clearance: float) -> bool:
    """Do ``n_packs`` placement discs fit in the square the wall clearance leaves them?

    One pack fits wherever its centre has room; more must also stay within the packing
    density of that square (the rule the whole field's check applies to all discs together).
    """
    if n_packs == 0:
        return True
    r_pack = _pack_placement_radius(pack_gap)
    side = _pack_square(pack_gap, pack_wall_clearance)
    if side <= 2 * r_pack:
        return False
    return n_packs == 1 or n_packs * math.pi * r_pack**2 <= side**2 * _MAX_PACKING_DENSITY


def max_counts(
    pack_gap: float = PACK_GAP, pack_wall_clearance: float = PACK_WALL_CLEARANCE
) -> tuple[int, int]:
    """The largest robot count (with no packs) and pack count (with one robot) that fit."""
    budget = _usable_area() * _MAX_PACKING_DENSITY
    r_robot = C.BODY_RADIUS + _PLACEMENT_MARGIN
    r_pack = _pack_placement_radius(pack_gap)
    max_robots = int(budget / (math.pi * r_robot**2))
    max_packs = int((budget - math.pi * r_robot**2) / (math.pi * r_pack**2))
    while max_packs > 0 and not _packs_fit(max_packs, pack_gap, pack_wall_clearance):
        max_packs -= 1
    return max_robots, max_packs


#: The most robots (with no packs) and packs (with one robot) that fit in the field, with the
#: default pack gap.
MAX_ROBOTS, MAX_PACKS = max_counts()


@dataclass(frozen=True)
class WorldConfig:
    """Physical setup of the field.

    Attributes:
        n_robots: number of Cyber Rodents (paper, simulation: 4).
        n_packs: number of battery packs (paper, simulation: 5; hardware: 6).
        timestep: physics timestep in seconds. 1/120 s (24 substeps per 0.2 s control step)
            is the largest step, of those that divide the control step, whose trajectories
            stay within 2 cm of a 5x finer reference over 10 s of scripted driving
            (``benchmarks/timestep_study.py``: 1.90 cm; 1/110 s gives 2.39 cm).
        pack_gap: smallest gap between the edges of two packs placed by :meth:`World.reset`,
            m. The default 0.3 m is wider than a robot turning in place (0.28 m), so no robot
            gets jammed between two packs; a larger gap spreads the packs out (docs/design.md
            §9.18).
        pack_wall_clearance: smallest gap between a pack's edge and a wall at
            :meth:`World.reset`, m (half the pack gap if that is more). The default 0.2 m lets
            a robot (18 cm wide) pass between a pack and a wall (docs/design.md §9.18).
        pack_reactivation_steps: control steps a pack stays inactive after a robot docks onto
            it (docs/design.md §9.26). A docking during control step t makes the pack inactive
            at once, for the rest of step t and the N control steps after it (t+1 .. t+N); it
            is active again from control step t+N+1 (seen by that step's vision, dockable in
            that step's docking). An inactive pack is dark (invisible to both vision providers)
            and takes no new docking, but it is still a body that collides and hides what is
            behind it; a robot already docked onto it keeps recharging. 0, the default, is the
            paper's rule: packs are always available.

    The counts are bounded by what fits in the field: :data:`MAX_ROBOTS` and :data:`MAX_PACKS`
    (at the default pack gap and wall clearance), the packs alone in the square the wall
    clearance leaves them, and robots and packs together, each at the packing density the
    placement can still draw.
    """

    n_robots: int = integer(4, 1, MAX_ROBOTS, unit="robots", source="paper §3.2")
    n_packs: int = integer(5, 0, MAX_PACKS, unit="packs", source="paper §3.2")
    timestep: float = number(1.0 / 120.0, 1e-4, 0.05, unit="s", source="docs/design.md §4")
    pack_gap: float = number(PACK_GAP, 0.0, 1.5, unit="m", source="docs/design.md §9.18")
    pack_wall_clearance: float = number(
        PACK_WALL_CLEARANCE, 0.0, 0.8, unit="m", source="docs/design.md §9.18"
    )
    pack_reactivation_steps: int = integer(
        0, 0, MAX_REACTIVATION_STEPS, unit="control steps", source="docs/design.md §9.26"
    )

    def __post_init__(self) -> None:
        validate_fields(self)
        if not _packs_fit(self.n_packs, self.pack_gap, self.pack_wall_clearance):
            raise ValueError(
                f"n_packs={self.n_packs} packs do not fit in the {C.FIELD_SIZE} m field with "
                f"pack_gap={self.pack_gap} m and pack_wall_clearance="
                f"{self.pack_wall_clearance} m; reduce one of them"
            )
        area = _disc_area(self.n_robots, self.n_packs, self.pack_gap)
        if not area <= _usable_area() * _MAX_PACKING_DENSITY:
            raise ValueError(
                f"n_robots={self.n_robots} and n_packs={self.n_packs} do not fit in the "
                f"{C.FIELD_SIZE} m field together with pack_gap={self.pack_gap} m; reduce "
                "one of them"
            )


def dock_hold_name(robot: int) -> str:
    """Name of robot ``robot``'s docking-hold weld (an equality constraint of the world)."""
    return f"dock_hold_{robot}"


def build_mjcf(n_robots: int, n_packs: int, timestep: float) -> mjcf.RootElement:
    """The field's MJCF tree with ``n_robots`` robots and ``n_packs`` packs at the origin."""
    arena = mjcf.from_path(str(asset_path(C.ARENA_XML)))
    arena.option.timestep = timestep
    # MuJoCo's arena holds contacts and constraint rows; pile-ups grow with the robot count
    # (16 robots overflowed 4 MB). 4 MB per robot, at least the arena file's 16 MB.
    arena.size.memory = f"{max(16, 4 * n_robots)}M"
    robot_file = str(asset_path(C.ROBOT_XML))
    pack_file = str(asset_path(C.BATTERY_PACK_XML))
    for i in range(n_robots):
        robot = mjcf.from_path(robot_file)
        robot.model = f"{C.ROBOT_MODEL_PREFIX}_{i}"
        frame = arena.attach(robot)
        frame.add("freejoint")
        # Docking hold (cyber_rodent/survival.py): an inactive weld of the chassis to
        # the world. The survival mechanics switch it on while the robot recharges (setting
        # its relative pose to the pose at docking) and off when recharging ends. Inactive
        # equality constraints cost nothing in the solver.
        arena.equality.add(
            "weld",
            name=dock_hold_name(i),
            body1=robot.find("body", C.ROBOT_ROOT_BODY),
            active=False,
        )
    for j in range(n_packs):
        pack = mjcf.from_path(pack_file)
        pack.model = f"{C.PACK_MODEL_PREFIX}_{j}"
        arena.attach(pack)  # no joint: a static body fixed in the field
    return arena


class World:
    """N robots and M packs in the walled field, with fast per-step access.

    Args:
        config: the physical setup.
        rng: generator for the initial placement; :meth:`reset` takes its own.
    """

    def __init__(self, config: WorldConfig | None = None, rng: np.random.Generator | None = None):
        self.config = config or WorldConfig()
        self.mjcf_model = build_mjcf(
            self.config.n_robots, self.config.n_packs, self.config.timestep
        )
        self.physics = mjcf.Physics.from_mjcf_model(self.mjcf_model)
        self.model: mujoco.MjModel = self.physics.model.ptr
        self.data: mujoco.MjData = self.physics.data.ptr
        self._index()
        self.led_on = np.zeros(self.config.n_robots, dtype=bool)
        #: (n_packs,) the pack shows its colour and takes dockings (``set_pack_active``).
        self.pack_active = np.ones(self.config.n_packs, dtype=bool)
        self.reset(rng if rng is not None else np.random.default_rng(0))

    # --- indexing (once, off the hot path) --------------------------------------------------
    def _index(self) -> None:
        m = self.model
        n = self.config.n_robots

        def obj_id(kind: mujoco.mjtObj, name: str) -> int:
            idx = int(mujoco.mj_name2id(m, kind, name))
            if idx < 0:
                raise KeyError(f"model has no {kind.name} named {name!r}")
            return idx

        def contiguous(ids: list[int], what: str) -> slice:
            arr = np.asarray(ids)
            if not np.array_equal(arr, np.arange(arr[0], arr[0] + len(arr))):
                raise RuntimeError(f"{what} are not contiguous in the compiled model")
            return slice(int(arr[0]), int(arr[0]) + len(arr))

        sensor_adr = []
        motor_ids = []
        self.root_qpos_adr = np.empty(n, dtype=np.int64)
        self.root_qvel_adr = np.empty(n, dtype=np.int64)
        self.chassis_body = np.empty(n, dtype=np.int64)
        self.led_geom = np.empty(n, dtype=np.int64)
        self.face_geom = np.empty(n, dtype=np.int64)
        self.teeth_geom = np.empty(n, dtype=np.int64)
        self.chassis_geom = np.empty(n, dtype=np.int64)
        self.ir_port_site = np.empty(n, dtype=np.int64)
        self.camera_site = np.empty(n, dtype=np.int64)
        for i in range(n):
            p = C.robot_prefix(i)
            for name, _, _ in C.RANGE_SENSORS:
                sid = obj_id(mujoco.mjtObj.mjOBJ_SENSOR, p + name)
                sensor_adr.append(int(m.sensor_adr[sid]))
            motor_ids += [
                obj_id(mujoco.mjtObj.mjOBJ_ACTUATOR, p + C.LEFT_MOTOR),
                obj_id(mujoco.mjtObj.mjOBJ_ACTUATOR, p + C.RIGHT_MOTOR),
            ]
            self.chassis_body[i] = obj_id(mujoco.mjtObj.mjOBJ_BODY, p + C.ROBOT_ROOT_BODY)
            root = int(m.body_jntadr[m.body_rootid[self.chassis_body[i]]])
            if root < 0 or m.jnt_type[root] != mujoco.mjtJoint.mjJNT_FREE:
                raise RuntimeError(f"robot {i} chassis has no free joint")
            self.root_qpos_adr[i] = m.jnt_qposadr[root]
            self.root_qvel_adr[i] = m.jnt_dofadr[root]
            self.led_geom[i] = obj_id(mujoco.mjtObj.mjOBJ_GEOM, p + C.LED_GEOM)
            self.face_geom[i] = obj_id(mujoco.mjtObj.mjOBJ_GEOM, p + C.FACE_GEOM)
            self.teeth_geom[i] = obj_id(mujoco.mjtObj.mjOBJ_GEOM, p + C.TEETH_GEOM)
            self.chassis_geom[i] = obj_id(mujoco.mjtObj.mjOBJ_GEOM, p + C.CHASSIS_GEOM)
            self.ir_port_site[i] = obj_id(mujoco.mjtObj.mjOBJ_SITE, p + C.IR_PORT_SITE)
            self.camera_site[i] = obj_id(mujoco.mjtObj.mjOBJ_SITE, p + C.CAMERA_MOUNT_SITE)
        self._range_slice = contiguous(sensor_adr, "range sensors")
        self._ctrl_slice = contiguous(motor_ids, "wheel motors")
        self.range_max = np.tile(np.array([r for _, _, r in C.RANGE_SENSORS]), (n, 1))
        # Per-robot geom ids (every geom of every body under the chassis): for hiding a robot
        # from its own camera and for attributing contacts to robots.
        self.geom_robot = np.full(m.ngeom, -1, dtype=np.int64)
        root_of_body = m.body_rootid
        for i in range(n):
            robot_root = root_of_body[self.chassis_body[i]]
            self.geom_robot[root_of_body[m.geom_bodyid] == robot_root] = i

        self.pack_body = np.array(
            [
                obj_id(mujoco.mjtObj.mjOBJ_BODY, C.pack_prefix(j) + C.PACK_BODY)
                for j in range(self.config.n_packs)
            ],
            dtype=np.int64,
        )
        self.pack_geom = np.array(
            [
                obj_id(mujoco.mjtObj.mjOBJ_GEOM, C.pack_prefix(j) + C.PACK_GEOM)
                for j in range(self.config.n_packs)
            ],
            dtype=np.int64,
        )
        self.electrode_geom = np.array(
            [
                obj_id(mujoco.mjtObj.mjOBJ_GEOM, C.pack_prefix(j) + C.PACK_ELECTRODE_GEOM)
                for j in range(self.config.n_packs)
            ],
            dtype=np.int64,
        )
        #: (n_packs, 4) each pack body's own colour, restored when the pack is active again.
        self.pack_rgba = m.geom_rgba[self.pack_geom].astype(np.float64)
        self.top_camera = obj_id(mujoco.mjtObj.mjOBJ_CAMERA, C.TOP_CAMERA)
        # Wheel radius and top speed read from the compiled model (they must match constants).
        wheel_geom = obj_id(mujoco.mjtObj.mjOBJ_GEOM, C.robot_prefix(0) + "left_wheel_contact")
        self.wheel_radius = float(m.geom_size[wheel_geom, 0])
        self.max_wheel_omega = float(m.actuator_ctrlrange[motor_ids[0], 1])
        # Views into MjData for the hot path.
        self._ctrl: np.ndarray = self.data.ctrl[self._ctrl_slice].reshape(n, 2)
        self._ranges_raw: np.ndarray = self.data.sensordata[self._range_slice].reshape(n, C.N_RANGE)

    # --- placement ---------------------------------------------------------------------------
    def reset(self, rng: np.random.Generator) -> None:
        """Zero the dynamics and place robots and packs at random, without overlap.

        Robots get uniformly random headings. Placement uses rejection sampling with clearance
        ``BODY_RADIUS`` / ``PACK_RADIUS`` plus a margin, from walls and from each other; packs
        keep ``pack_gap`` between them and ``pack_wall_clearance`` from the walls. Every pack is
        active again.
        """
        mujoco.mj_resetData(self.model, self.data)
        cfg = self.config
        n, k = cfg.n_robots, cfg.n_packs
        radii = np.concatenate(
            [
                np.full(n, C.BODY_RADIUS + _PLACEMENT_MARGIN),
                np.full(k, _pack_placement_radius(cfg.pack_gap)),
            ]
        )
        pack_wall = _pack_wall_margin(cfg.pack_gap, cfg.pack_wall_clearance)
        wall_margin = np.concatenate([np.zeros(n), np.full(k, pack_wall)])
        centres = place_discs(radii, C.FIELD_SIZE / 2, rng, wall_margin)
        yaw = rng.uniform(-math.pi, math.pi, size=n)
        for i in range(n):
            self.set_robot_pose(i, centres[i, 0], centres[i, 1], yaw[i])
        for j in range(k):
            self.model.body_pos[self.pack_body[j], :2] = centres[n + j]
        self.led_on[:] = False
        self.model.geom_rgba[self.led_geom] = LED_OFF_RGBA
        self.pack_active[:] = True
        self.model.geom_rgba[self.pack_geom] = self.pack_rgba
        mujoco.mj_forward(self.model, self.data)

    def set_robot_pose(self, i: int, x: float, y: float, yaw: float) -> None:
        """Put robot ``i`` at rest on the floor at (x, y) facing ``yaw`` (call mj_forward after)."""
        a = int(self.root_qpos_adr[i])
        self.data.qpos[a : a + 3] = (x, y, 0.0)
        self.data.qpos[a + 3 : a + 7] = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
        v = int(self.root_qvel_adr[i])
        self.data.qvel[v : v + 6] = 0.0

    def set_pack_position(self, j: int, x: float, y: float) -> None:
        """Move static pack ``j`` (call mj_forward after)."""
        self.model.body_pos[self.pack_body[j], :2] = (x, y)

    # --- per-step access ---------------------------------------------------------------------
    def set_wheel_speeds(self, left: np.ndarray, right: np.ndarray) -> None:
        """Command wheel rim speeds in m/s for all robots; clipped to ±``TOP_SPEED``.

        Raises:
            ValueError: if any command is NaN or infinite.
        """
        left = np.asarray(left, dtype=float)
        right = np.asarray(right, dtype=float)
        if not (np.all(np.isfinite(left)) and np.all(np.isfinite(right))):
            raise ValueError("wheel speed commands must be finite (got NaN or inf)")
        self._ctrl[:, 0] = left
        self._ctrl[:, 1] = right
        self._ctrl *= 1.0 / self.wheel_radius
        np.clip(self._ctrl, -self.max_wheel_omega, self.max_wheel_omega, out=self._ctrl)

    def step(self, n_substeps: int = 1) -> None:
        """Advance the physics by ``n_substeps`` timesteps."""
        mujoco.mj_step(self.model, self.data, nstep=n_substeps)

    @property
    def range_sensordata(self) -> np.ndarray:
        """(n_robots, 8) live view of the rangefinders' raw ``sensordata`` (-1: no hit), for
        hot loops that saturate the readings themselves (see :meth:`range_readings`)."""
        return self._ranges_raw

    def range_readings(self, out: np.ndarray | None = None) -> np.ndarray:
        """(n_robots, 8) distances in metres, sensor order of ``constants.RANGE_SENSORS``.

        A ray that hits nothing within a sensor's range reads that sensor's range (the reading
        saturates, as an IR sensor's does).
        """
        raw = self._ranges_raw
        if out is None:
            out = np.empty_like(raw)
        np.copyto(out, raw)
        np.putmask(out, (raw < 0) | (raw > self.range_max), self.range_max)
        return out

    def poses(self) -> np.ndarray:
        """(n_robots, 3) array of x, y, yaw (rad) of each chassis."""
        xpos = self.data.xpos[self.chassis_body]
        xmat = self.data.xmat[self.chassis_body]
        yaw = np.arctan2(xmat[:, 3], xmat[:, 0])
        return np.column_stack([xpos[:, 0], xpos[:, 1], yaw])

    def uprightness(self) -> np.ndarray:
        """(n_robots,) body z-axis · world z: 1 upright, 0 on its side."""
        upright: np.ndarray = self.data.xmat[self.chassis_body, 8].copy()
        return upright

    def pack_positions(self) -> np.ndarray:
        """(n_packs, 2) x, y of each pack."""
        positions: np.ndarray = self.model.body_pos[self.pack_body, :2].copy()
        return positions

    def set_led(self, on: np.ndarray | bool, robot: int | None = None) -> None:
        """Switch LEDs on (green) or off (dark): all robots, or only ``robot``."""
        if robot is None:
            self.led_on[:] = np.broadcast_to(np.asarray(on, dtype=bool), self.led_on.shape)
        else:
            self.led_on[robot] = bool(on)
        self.model.geom_rgba[self.led_geom] = np.where(
            self.led_on[:, None], LED_ON_RGBA, LED_OFF_RGBA
        )

    def set_pack_active(self, pack: int, active: bool) -> None:
        """Show pack ``pack`` in its colour and let robots dock onto it, or make it inactive:
        dark grey (:data:`PACK_INACTIVE_RGBA`), invisible to vision, refusing new dockings
        (``WorldConfig.pack_reactivation_steps``)."""
        self.pack_active[pack] = bool(active)
        self.model.geom_rgba[self.pack_geom[pack]] = (
            self.pack_rgba[pack] if active else PACK_INACTIVE_RGBA
        )

    @property
    def time(self) -> float:
        return float(self.data.time)

    def replace(self, **changes: Any) -> World:
        """A new world with some config fields changed (placement from a fixed seed)."""
        return World(dataclasses.replace(self.config, **changes))


def place_discs(
    radii: np.ndarray,
    half_size: float,
    rng: np.random.Generator,
    wall_margin: np.ndarray | None = None,
) -> np.ndarray:
    """Centres for discs of ``radii`` inside [-half_size, half_size]², with no overlaps.

    ``wall_margin`` (per disc, default 0) keeps a disc that much further from the walls.

    Large discs are placed first (rejection sampling each), which keeps the draw order, and so
    the result, a pure function of the generator's state.

    Raises:
        ValueError: if the discs cannot be placed.
    """
    order = np.argsort(-radii, kind="stable")
    centres = np.zeros((len(radii), 2))
    margin = np.zeros(len(radii)) if wall_margin is None else np.asarray(wall_margin)
    placed: list[int] = []
    for idx in order:
        r = radii[idx]
        lim = half_size - r - margin[idx]
        if lim <= 0:
            raise ValueError(f"a disc of radius {r:.3f} m does not fit in the field")
        for _ in range(_PLACEMENT_ATTEMPTS):
            c = rng.uniform(-lim, lim, size=2)
            if not placed or np.all(np.hypot(*(centres[placed] - c).T) >= radii[placed] + r):
                centres[idx] = c
                placed.append(int(idx))
                break
        else:
            raise ValueError(
                f"could not place {len(radii)} bodies without overlap in the field; "
                "reduce n_robots, n_packs, pack_gap or pack_wall_clearance"
            )
    return centres
