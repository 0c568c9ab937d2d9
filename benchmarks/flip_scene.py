"""Robot-robot collisions that tip a Cyber Rodent over: scenes and model variants.

**Two-robot scene** (default). Two robots drive at each other with both wheels at the same
constant rim speed (``--speeds``, default 0.2-1.3 m/s), held through the impact and for
``--after`` seconds after it, at the runner's physics (``WorldConfig.timestep`` 1/120 s; a
control step is 24 substeps; stepped one substep at a time so that every substep can be
recorded: the commands are constant, so this is the same physics as ``World.step(24)``). Each
robot starts already cruising at its speed (free-joint velocity, wheel spin and motor
activation set to the command), at least 0.35 m and 0.5 s away, in a 6 m field with no packs.
Geometries (:data:`CASES`): robot 0 drives along +x; robot 1 approaches at ``phi`` from
head-on (0 head-on, 90 crossing at right angles), aimed so that robot 0's nose (the front of
its teeth) would meet a named point of robot 1: its nose (with a lateral offset), or its left
flank (T-bones; ``still*``: robot 1 stands still). Per case and speed: the lowest uprightness
(chassis z-axis . world z) of either robot and whether it tipped past 60 / 90 deg or ended
upside down, the highest centre of mass (3.5 cm at rest), the geom pairs in contact at the
largest tilt and (``--detail``) each robot-robot pair's peak normal force, the vertical
component of its normal at that peak (``nz``), its height and deepest penetration; per
variant, the vertical robot-robot contact impulse by pair class (the force that carries one
robot on another: :class:`LiftTally`).

**Other scenes.** ``--sweep N``: N random head-on encounters (offset 0-14 cm, +-10 deg,
0.8-1.3 m/s each, random impact phase within a step). ``--pile``: ``--pile-robots`` robots
in a ring all driving at its centre (the stress scene's centre phase, small), ``--pile-trials``
seeded draws. ``--stress``: the reported scene, 100 robots and 125 packs in an 11.5 m field,
random driving and every other 5 s (5-10 s, ...; ``--centre-first``: 0-5 s, ...) steering to
the centre at 1.2 m/s, for ``--stress-seconds``: tips per robot-hour. ``--trace N`` (pile,
stress) replays the last 1.2 s before each of the first N tips substep by substep and prints
the tipping robot's contacts with other bodies. ``--identity``: the variant against the base
model with the same seeded random commands, 1 robot (with and without packs) and the default
4-robot colony: the first control step at which qpos differs, bit for bit.

**Variants** (``--variant a,b``, :data:`VARIANTS`): one per hypothesis, applied in memory to
the assembled MJCF tree before compiling or to the compiled arrays (the repository's XML is
never touched). ``base`` is the model as shipped, which carries the fix (the teeth touch no
robot); ``published`` restores the collision bits of the model
the published results were run on, and every hypothesis variant is measured on top of it.

Run: ``python -m benchmarks.flip_scene [--variant published,base] [--speeds 0.2,0.4] [--cases head8]
[--detail] [--json PATH]``, ``... --sweep 400``, ``... --pile --pile-trials 60``,
``... --stress [--stress-seconds 150] [--seed 0] [--trace 2]``, ``... --identity``,
``... --variant published,base --render flip.png`` (the knock that flips the published model,
drawn from the side at a few times, one row per variant).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

import cyber_rodent.world as world_module
from cyber_rodent import constants as C
from cyber_rodent.robot import RobotParts, robot_model
from cyber_rodent.survival.watchdog import Watchdog
from cyber_rodent.world import World, WorldConfig

SPEEDS = (0.2, 0.4, 0.6, 0.8, 1.0, 1.3)  # m/s, rim speed of both wheels of both robots
FIELD = 6.0  # m: walls 3 m from the impact point
NOSE_X = 0.134  # m, front face of the teeth in the robot frame
HALF_WIDTH = 0.07  # m, chassis half width
APPROACH = 0.35  # m: each robot starts at least this far back along its path
MIN_LEAD = 0.5  # s: and at least this long before the nominal touch

#: The Cyber Rodent's MJCF part names (cyber_rodent.robot).
PARTS = RobotParts()


@dataclass(frozen=True)
class Case:
    """A collision geometry: robot 1 heads at ``pi - phi`` (deg; 0 = head-on) and robot 0's
    nose, at (NOSE_X, 0) of robot 0, would touch robot 1's local point ``target`` at the
    nominal moment. ``v1_scale`` scales robot 1's speed (0: it stands still)."""

    name: str
    phi: float
    target: tuple[float, float]
    note: str
    v1_scale: float = 1.0


CASES: tuple[Case, ...] = (
    Case("head0", 0, (NOSE_X, 0.0), "head-on, nose to nose"),
    Case("head4", 0, (NOSE_X, -0.045), "head-on, 4.5 cm offset (teeth half overlap)"),
    Case("head8", 0, (NOSE_X, -0.08), "head-on, 8 cm offset (teeth on chassis fronts)"),
    Case("head12", 0, (NOSE_X, -0.12), "head-on, 12 cm offset (chassis corners)"),
    Case("nose30", 30, (NOSE_X, 0.0), "30 deg, nose to nose"),
    Case("nose60", 60, (NOSE_X, 0.0), "60 deg, nose to nose"),
    Case("nose90", 90, (NOSE_X, 0.0), "90 deg crossing, nose to nose"),
    Case("flank30", 30, (0.0, HALF_WIDTH), "30 deg, nose into the flank's middle"),
    Case("flank60", 60, (0.0, HALF_WIDTH), "60 deg, nose into the flank's middle"),
    Case("flank90", 90, (0.0, HALF_WIDTH), "90 deg T-bone, flank middle"),
    Case("flank90f", 90, (0.08, HALF_WIDTH), "90 deg T-bone, flank front"),
    Case("flank90r", 90, (-0.08, HALF_WIDTH), "90 deg T-bone, flank rear"),
    Case("still90", 90, (0.0, HALF_WIDTH), "90 deg T-bone into a robot standing still", 0.0),
    Case("still0", 0, (NOSE_X, 0.0), "head-on into a robot standing still", 0.0),
)


# --- model variants (hypotheses), applied in memory ------------------------------------------
@dataclass(frozen=True)
class Variant:
    """A change to the model: ``mjcf`` edits the assembled MJCF tree before it is compiled,
    ``model`` the compiled arrays of a built world; ``timestep`` replaces the physics step
    (the scene keeps the simulated times, so it takes more substeps); ``published``: on the
    published model, whose teeth touch other robots (``WorldConfig.contacts``)."""

    name: str
    note: str
    mjcf: Callable[[object], None] | None = None
    model: Callable[[World], None] | None = None
    timestep: float = 1.0 / 120.0
    published: bool = False


def _robot_geoms(root: object, name: str) -> list[Any]:
    return [g for g in root.find_all("geom") if g.name == name]  # type: ignore[attr-defined]


def _geom_ids(world: World, name: str) -> np.ndarray:
    m = world.model
    return np.array(
        [
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, C.robot_prefix(i) + name)
            for i in range(world.config.n_robots)
        ]
    )


def _set(name: str, attr: str, value: object) -> Callable[[World], None]:
    def edit(world: World) -> None:
        getattr(world.model, attr)[_geom_ids(world, name)] = value

    return edit


def _chain(*edits: Callable[[World], None]) -> Callable[[World], None]:
    def edit(world: World) -> None:
        for e in edits:
            e(world)

    return edit


def _teeth_off_robots(world: World) -> None:
    """Teeth collide with floor, walls and packs only: a collision bit (4) of their own that
    every non-robot body geom also accepts."""
    m = world.model
    teeth = _geom_ids(world, PARTS.teeth_geom)
    m.geom_contype[teeth] = 4
    m.geom_conaffinity[teeth] = 0
    env = (world.geom_robot < 0) & ((m.geom_conaffinity & 2) != 0)
    m.geom_conaffinity[env] |= 4


def _wheels_on_bodies(world: World) -> None:
    """Wheel spheres also collide with bodies (bit 2): other robots, packs and walls."""
    for name in ("left_wheel_contact", "right_wheel_contact"):
        world.model.geom_conaffinity[_geom_ids(world, name)] = 1 | 2


def _no_floor_friction_for_body(world: World) -> None:
    """Chassis and teeth slide on the floor with the chassis' own friction (0.15): a geom
    priority makes their friction win over the floor's 1.0 (they still collide with it)."""
    for name in (PARTS.chassis_geom, PARTS.teeth_geom):
        ids = _geom_ids(world, name)
        world.model.geom_priority[ids] = 2
        world.model.geom_friction[ids, 0] = 0.15


def _chassis_down(root: object) -> None:
    """Chassis box 3 mm deeper at the bottom (3.2-9.5 cm): the teeth (3.4-5 cm) lie within
    its height."""
    for g in _robot_geoms(root, PARTS.chassis_geom):
        g.size = [0.11, 0.07, 0.0315]
        g.pos = [0.0, 0.0, 0.0635]


def _no_armature(world: World) -> None:
    """Wheel joints without the motors' reflected rotor inertia (armature 0.002 -> 0)."""
    m = world.model
    hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    m.dof_armature[m.jnt_dofadr[hinges]] = 0.0


def _com_lower(world: World) -> None:
    """Chassis centre of mass 1.5 cm lower (2.0 cm above the floor)."""
    m = world.model
    for i in range(world.config.n_robots):
        m.body_ipos[world.chassis_body[i], 2] = 0.020


VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        Variant("base", "the model as shipped (the fix: teeth touch no robot)"),
        Variant("published", "the published model: teeth touch other robots", published=True),
        Variant(
            "dt480", "published, timestep 1/480 s (4x finer)", published=True, timestep=1 / 480
        ),
        Variant(
            "dt1200", "published, timestep 1/1200 s (10x finer)", published=True, timestep=1 / 1200
        ),
        Variant(
            "teeth_mu15",
            "published, teeth friction 0.6 -> 0.15 (max rule: pack, wall, floor keep 0.6/1.0)",
            published=True,
            model=_set(PARTS.teeth_geom, "geom_friction", [0.15, 0.005, 0.0001]),
        ),
        Variant(
            "rr_mu0",
            "published, teeth and chassis friction 0 against each other (0.6, 0.15 -> 0)",
            published=True,
            model=_chain(
                _set(PARTS.teeth_geom, "geom_friction", [0.0, 0.005, 0.0001]),
                _set(PARTS.chassis_geom, "geom_friction", [0.0, 0.005, 0.0001]),
            ),
        ),
        Variant(
            "teeth_off",
            "published, teeth collide with no robot (by a model edit)",
            published=True,
            model=_teeth_off_robots,
        ),
        Variant(
            "wheels_on",
            "published, wheel spheres collide with bodies too",
            published=True,
            model=_wheels_on_bodies,
        ),
        Variant(
            "hard",
            "published, chassis and teeth contacts harder: solimp 0.95 0.99 0.001",
            published=True,
            model=_chain(
                _set(PARTS.chassis_geom, "geom_solimp", [0.95, 0.99, 0.001, 0.5, 2]),
                _set(PARTS.teeth_geom, "geom_solimp", [0.95, 0.99, 0.001, 0.5, 2]),
            ),
        ),
        Variant(
            "soft",
            "published, chassis and teeth contacts softer: solref 0.05 1",
            published=True,
            model=_chain(
                _set(PARTS.chassis_geom, "geom_solref", [0.05, 1.0]),
                _set(PARTS.teeth_geom, "geom_solref", [0.05, 1.0]),
            ),
        ),
        Variant(
            "body_floor_mu",
            "published, chassis and teeth slide on the floor at 0.15 (not the floor's 1.0)",
            published=True,
            model=_no_floor_friction_for_body,
        ),
        Variant(
            "chassis_down",
            "published, chassis box bottom 3.5 -> 3.2 cm",
            _chassis_down,
            published=True,
        ),
        Variant(
            "com_low",
            "published, chassis centre of mass 3.5 -> 2.0 cm high",
            published=True,
            model=_com_lower,
        ),
        Variant(
            "armature0",
            "published, wheel armature 0.002 -> 0 kg m^2",
            published=True,
            model=_no_armature,
        ),
        Variant("fix_dt480", "the fix at timestep 1/480 s", timestep=1 / 480),
        Variant("fix_dt1200", "the fix at timestep 1/1200 s", timestep=1 / 1200),
        Variant("fix_armature0", "the fix and wheel armature 0", model=_no_armature),
    )
}


@contextlib.contextmanager
def _patched_build(variant: Variant) -> Iterator[None]:
    """World() with ``variant``'s MJCF edit applied to the tree before compiling."""
    original = world_module.build_mjcf
    if variant.mjcf is None:
        yield
        return

    def build(*args: object, **kwargs: object) -> object:
        root = original(*args, **kwargs)  # type: ignore[arg-type]
        variant.mjcf(root)  # type: ignore[misc]
        return root

    world_module.build_mjcf = build
    try:
        yield
    finally:
        world_module.build_mjcf = original


def make_world(variant: Variant, config: WorldConfig) -> World:
    config = dataclasses.replace(
        config, timestep=variant.timestep, contacts="published" if variant.published else "fixed"
    )
    with _patched_build(variant):
        world = World(config, np.random.default_rng(0))
    if variant.model is not None:
        variant.model(world)
        _refresh_body_filters(world.model)
    mujoco.mj_forward(world.model, world.data)
    return world


def _refresh_body_filters(m: mujoco.MjModel) -> None:
    """Recompute the bodies' collision bits (MuJoCo's broadphase filters body pairs by the OR
    of their geoms' contype / conaffinity, compiled once) after geom bits were changed."""
    contype = np.zeros(m.nbody, dtype=np.int64)
    conaffinity = np.zeros(m.nbody, dtype=np.int64)
    np.bitwise_or.at(contype, m.geom_bodyid, m.geom_contype)
    np.bitwise_or.at(conaffinity, m.geom_bodyid, m.geom_conaffinity)
    m.body_contype[:] = contype
    m.body_conaffinity[:] = conaffinity


# --- the two-robot scene ---------------------------------------------------------------------
def _names(world: World) -> list[str]:
    m = world.model
    out = []
    for g in range(m.ngeom):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
        r = int(world.geom_robot[g])
        if r >= 0:
            name = f"r{r}." + name.split("/", 1)[1].replace("_geom", "").replace("_contact", "")
        out.append(name)
    return out


def _rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


class _Indices:
    def __init__(self, world: World) -> None:
        m = world.model
        n = world.config.n_robots
        self.wheel_dof = np.empty((n, 2), dtype=np.int64)
        self.motor_act = np.empty((n, 2), dtype=np.int64)
        for i in range(n):
            p = C.robot_prefix(i)
            for k, (joint, motor) in enumerate(
                (
                    (PARTS.left_wheel_joint, PARTS.left_motor),
                    (PARTS.right_wheel_joint, PARTS.right_motor),
                )
            ):
                j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, p + joint)
                a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, p + motor)
                self.wheel_dof[i, k] = m.jnt_dofadr[j]
                self.motor_act[i, k] = m.actuator_actadr[a]


def start_cruising(world: World, poses: np.ndarray, speeds: np.ndarray) -> None:
    """Put each robot at (x, y, yaw) already driving straight at its speed (m/s): free-joint
    velocity, wheel spin and motor activation as in steady driving, so that the impact
    happens at the speed commanded."""
    mujoco.mj_resetData(world.model, world.data)
    idx = _Indices(world)
    d = world.data
    for i, ((x, y, yaw), v) in enumerate(zip(poses, speeds, strict=True)):
        world.set_robot_pose(i, x, y, yaw)
        a = int(world.root_qvel_adr[i])
        d.qvel[a : a + 3] = (v * math.cos(yaw), v * math.sin(yaw), 0.0)
        d.qvel[idx.wheel_dof[i]] = v / world.wheel_radius
        d.act[idx.motor_act[i]] = v / world.wheel_radius
    world.set_wheel_speeds(np.asarray(speeds), np.asarray(speeds))
    mujoco.mj_forward(world.model, world.data)


def _start_poses(case: Case, v: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Start poses (2, 3), speeds (2,), and the nominal touch time."""
    psi = math.pi - math.radians(case.phi)
    v1 = v * case.v1_scale
    # At the nominal touch: robot 0 at the origin facing +x, robot 1 where its local point
    # ``target`` is on robot 0's nose.
    c1 = np.array([NOSE_X, 0.0]) - _rot(psi) @ np.asarray(case.target)
    lead = max(MIN_LEAD, APPROACH / v)
    heading1 = np.array([math.cos(psi), math.sin(psi)])
    for _ in range(20):  # back off until the robots' discs are apart
        p0 = np.array([-v * lead, 0.0])
        p1 = c1 - v1 * lead * heading1
        if np.hypot(*(p1 - p0)) > 2 * robot_model().body_radius + 0.02:
            break
        lead *= 1.5
    else:
        raise ValueError(f"case {case.name}: the robots do not approach each other")
    poses = np.array([[p0[0], p0[1], 0.0], [p1[0], p1[1], psi]])
    return poses, np.array([v, v1]), lead


@dataclass
class Result:
    case: str
    speed: float
    min_up: float
    min_robot: int
    t_min: float
    t_touch: float
    final_up: list[float]
    tipped60: bool
    tipped90: bool
    upside_down: bool
    on_side: bool
    z_com_max: float
    contacts_at_max: list[str]
    contacts_at_60: list[str]
    rr_contacts: dict[str, dict[str, float]] = field(default_factory=dict)
    lift: dict[str, float] = field(default_factory=dict)

    @property
    def tip(self) -> str:
        if self.upside_down:
            return "UD"
        if self.on_side:
            return "side"
        if self.tipped90:
            return "90"
        if self.tipped60:
            return "60"
        return "-"


def _contact_pairs(world: World, names: list[str], robot_robot_only: bool = False) -> list[str]:
    d = world.data
    out = []
    for c in d.contact[: d.ncon]:
        r1, r2 = world.geom_robot[c.geom1], world.geom_robot[c.geom2]
        if robot_robot_only and (r1 < 0 or r2 < 0 or r1 == r2):
            continue
        pair = "|".join(sorted((names[c.geom1], names[c.geom2])))
        if pair not in out:
            out.append(pair)
    return out


def run_case(world: World, case: Case, v: float, after: float = 2.5) -> Result:
    """Drive the two robots of ``world`` into each other and measure the tilt."""
    names = _names(world)
    poses, speeds, lead = _start_poses(case, v)
    start_cruising(world, poses, speeds)
    m, d = world.model, world.data
    steps = round((lead + after) / m.opt.timestep)
    min_up, min_robot, t_min = 1.0, 0, 0.0
    contacts_at_max: list[str] = []
    contacts_at_60: list[str] = []
    z_max = 0.0
    t_touch = math.nan
    rr: dict[str, dict[str, float]] = {}
    force = np.zeros(6)
    tally = LiftTally(world)
    for _ in range(steps):
        world.step(1)
        tally.sample()
        up = world.uprightness()
        z_max = max(z_max, float(d.subtree_com[world.chassis_body, 2].max()))
        for ci in range(d.ncon):
            c = d.contact[ci]
            r1, r2 = world.geom_robot[c.geom1], world.geom_robot[c.geom2]
            if r1 < 0 or r2 < 0 or r1 == r2:
                continue
            if math.isnan(t_touch):
                t_touch = d.time
            mujoco.mj_contactForce(m, d, ci, force)
            pair = "|".join(sorted((names[c.geom1], names[c.geom2])))
            rec = rr.setdefault(
                pair, {"peak_N": 0.0, "nz": 0.0, "z_cm": 0.0, "impulse_Ns": 0.0, "pen_mm": 0.0}
            )
            rec["impulse_Ns"] += float(force[0]) * m.opt.timestep
            rec["pen_mm"] = max(rec["pen_mm"], float(-c.dist) * 1000)
            if force[0] > rec["peak_N"]:
                rec["peak_N"] = float(force[0])
                rec["nz"] = float(abs(c.frame[2]))
                rec["z_cm"] = float(c.pos[2] * 100)
        lowest = int(np.argmin(up))
        if up[lowest] < min_up:
            min_up, min_robot, t_min = float(up[lowest]), lowest, d.time
            contacts_at_max = _contact_pairs(world, names)
            if min_up < 0.5 and not contacts_at_60:
                contacts_at_60 = contacts_at_max
    final = world.uprightness()
    return Result(
        case=case.name,
        speed=v,
        min_up=min_up,
        min_robot=min_robot,
        t_min=t_min - lead,
        t_touch=t_touch - lead,
        final_up=[float(u) for u in final],
        tipped60=min_up < 0.5,
        tipped90=min_up < 0.0,
        upside_down=bool(final.min() < -0.5),
        on_side=bool(-0.5 <= final.min() < 0.5),
        z_com_max=z_max,
        contacts_at_max=contacts_at_max,
        contacts_at_60=contacts_at_60,
        rr_contacts={k: {kk: round(vv, 3) for kk, vv in v.items()} for k, v in rr.items()},
        lift=tally.as_dict(),
    )


def run_scene(
    variant: Variant, cases: list[Case], speeds: list[float], after: float
) -> list[Result]:
    world = make_world(variant, WorldConfig(field_size=FIELD, n_robots=2, n_packs=0))
    return [run_case(world, case, v, after) for case in cases for v in speeds]


def _short_rr(rr: dict[str, dict[str, float]], top: int = 2) -> str:
    items = sorted(rr.items(), key=lambda kv: -kv[1]["peak_N"])[:top]
    return " ".join(
        f"{k}:{v['peak_N']:.0f}N/nz{v['nz']:.2f}@{v['z_cm']:.1f}cm/pen{v['pen_mm']:.0f}mm"
        for k, v in items
    )


def print_table(variant: Variant, results: list[Result], verbose: bool = False) -> None:
    print(f"\n== variant {variant.name}: {variant.note}")
    print(
        f"{'case':9s} {'v':>4s} {'min_up':>7s} {'who':>3s} {'t':>5s} {'tip':>4s} "
        f"{'zCoM':>5s}  contacts at max tilt | robot-robot peaks"
    )
    for r in results:
        at_max = ",".join(c for c in r.contacts_at_max if "floor" not in c or r.tipped60)
        print(
            f"{r.case:9s} {r.speed:4.1f} {r.min_up:7.3f} r{r.min_robot:<2d} {r.t_min:5.2f} "
            f"{r.tip:>4s} {r.z_com_max * 100:5.1f}  {at_max or '-'} | {_short_rr(r.rr_contacts)}"
        )


def print_matrix(
    variants: list[Variant], cases: list[Case], speeds: list[float], table: dict[str, list[Result]]
) -> None:
    """One line per variant and case: the minimum uprightness at each speed (tip marks)."""
    print(
        "\nper speed (m/s, both robots): minimum uprightness of either robot (* past 60 deg,"
        " ! past 90 deg, U ends upside down) and the highest centre of mass (cm; 3.5 at rest)"
    )
    head = " ".join(f"{v:>10.1f}" for v in speeds)
    print(f"{'variant':13s} {'case':9s} {head}")
    for variant in variants:
        by = {(r.case, r.speed): r for r in table[variant.name]}
        for case in cases:
            cells = []
            for v in speeds:
                r = by[(case.name, v)]
                mark = "U" if r.upside_down else "!" if r.tipped90 else "*" if r.tipped60 else " "
                cells.append(f"{r.min_up:5.2f}{mark}{r.z_com_max * 100:4.1f}")
            print(f"{variant.name:13s} {case.name:9s} {' '.join(cells)}")
        flips = sum(r.tipped60 for r in table[variant.name])
        ud = sum(r.upside_down for r in table[variant.name])
        lift: dict[str, float] = {}
        for r in table[variant.name]:
            for k, val in r.lift.items():
                lift[k] = lift.get(k, 0.0) + val
        print(
            f"{variant.name:13s} {'total':9s} past 60 deg: {flips}/{len(table[variant.name])}"
            f", upside down at the end: {ud}; vertical robot-robot impulse (N s): "
            + ", ".join(
                f"{k.removeprefix('lift_Ns_')} {v:.1f}"
                for k, v in lift.items()
                if k.startswith("lift_Ns_") and k != "lift_Ns_other"
            )
        )


def encounter(
    world: World, offset: float, phi: float, speed: float, shift: float = 0.0, after: float = 2.0
) -> tuple[float, float]:
    """One head-on encounter in a two-robot ``world``: robot 1 approaches at ``phi`` deg from
    head-on, aimed ``offset`` m to the right of robot 0's nose, both cruising at ``speed`` m/s,
    robot 0 starting ``shift`` m further forward (the impact's phase within a physics step).
    Returns the lowest uprightness of either robot and the highest centre of mass (m)."""
    case = Case("sweep", phi, (NOSE_X, -offset), "")
    poses, speeds, lead = _start_poses(case, speed)
    poses[0, 0] += shift
    start_cruising(world, poses, speeds)
    lowest, z = 1.0, 0.0
    for _ in range(round((lead + after) / world.model.opt.timestep)):
        world.step(1)
        lowest = min(lowest, float(world.uprightness().min()))
        z = max(z, float(world.data.subtree_com[world.chassis_body, 2].max()))
    return lowest, z


def sweep(variant: Variant, n: int, seed: int = 5, after: float = 2.0) -> dict[str, Any]:
    """``n`` random head-on encounters (:func:`encounter`): lateral offset U(0, 14 cm),
    approach angle U(-10, 10) deg, both robots at the same speed U(0.8, 1.3) m/s, the impact's
    phase within a physics step drawn too (robot 0 starts up to 2 cm further forward). Counts
    the runs in which a robot tipped past 60 deg and lists them."""
    world = make_world(variant, WorldConfig(field_size=FIELD, n_robots=2, n_packs=0))
    rng = np.random.default_rng(seed)
    flips, lifted = [], 0
    for _ in range(n):
        b, phi, v = rng.uniform(0.0, 0.14), rng.uniform(-10, 10), rng.uniform(0.8, 1.3)
        shift = rng.uniform(0, 0.02)
        lowest, z = encounter(world, b, phi, v, shift, after)
        lifted += z > 0.055
        if lowest < 0.5:
            flips.append(
                {
                    "offset_m": float(b),
                    "phi_deg": float(phi),
                    "speed": float(v),
                    "shift_m": float(shift),
                    "min_up": round(lowest, 3),
                }
            )
    return {
        "variant": variant.name,
        "runs": n,
        "past_60": len(flips),
        "com_above_5_5cm": int(lifted),
        "flips": flips,
    }


#: The encounter of ``--sweep 400`` (seed 5) that throws the published model's robot onto its
#: back: lateral offset (m), approach angle (deg), speed (m/s), robot 0's head start (m).
FLIP_KNOCK = (0.07473702742593587, -1.9141885176872258, 1.2563521097066594, 0.013092952307341837)
#: Seconds after the start at which :func:`render_knock` draws its frames.
RENDER_TIMES = (0.4, 0.55, 0.7, 1.2, 2.5)


def render_knock(
    variants: list[Variant],
    path: str,
    knock: tuple[float, float, float, float] = FLIP_KNOCK,
    times: tuple[float, ...] = RENDER_TIMES,
    size: int = 320,
) -> dict[str, list[float]]:
    """Draw :data:`FLIP_KNOCK` in each variant (one row each) at ``times`` from the side, the
    uprightness of the lower robot in each frame's caption; write a PNG to ``path``."""
    from cyber_rodent.render import draw_caption, write_png

    rows, ups = [], {}
    for variant in variants:
        world = make_world(variant, WorldConfig(field_size=FIELD, n_robots=2, n_packs=0))
        offset, phi, speed, shift = knock
        case = Case("knock", phi, (NOSE_X, -offset), "")
        poses, speeds, lead = _start_poses(case, speed)
        poses[0, 0] += shift
        start_cruising(world, poses, speeds)
        m = world.model
        m.vis.global_.offwidth = max(m.vis.global_.offwidth, size)
        m.vis.global_.offheight = max(m.vis.global_.offheight, size)
        renderer = mujoco.Renderer(m, height=size, width=size)
        camera = mujoco.MjvCamera()
        camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        camera.lookat[:] = (NOSE_X, 0.0, 0.05)
        camera.distance, camera.azimuth, camera.elevation = 0.85, 60.0, -12.0
        option = mujoco.MjvOption()
        option.flags[mujoco.mjtVisFlag.mjVIS_RANGEFINDER] = False
        frames, row_ups = [], []
        for when in times:
            while world.data.time < when - 1e-9:
                world.step(1)
            up = float(world.uprightness().min())
            renderer.update_scene(world.data, camera, option)
            image = renderer.render().copy()
            draw_caption(image, f"{variant.name} t={world.data.time:.2f}s up={up:+.2f}")
            frames.append(image)
            row_ups.append(round(up, 3))
        renderer.close()
        rows.append(np.concatenate(frames, axis=1))
        ups[variant.name] = row_ups
    write_png(np.concatenate(rows, axis=0), path)
    return ups


# --- mass properties ------------------------------------------------------------------------
def mass_report(world: World) -> dict[str, Any]:
    m, d = world.model, world.data
    b = int(world.chassis_body[0])
    mujoco.mj_forward(m, d)
    com = d.xmat[b].reshape(3, 3).T @ (d.subtree_com[b] - d.xpos[b])  # in the robot frame
    return {
        "mass_kg": float(m.body_subtreemass[b]),
        "com_x_cm": float(com[0] * 100),
        "com_z_cm": float(com[2] * 100),
        "chassis_inertia": [float(x) for x in m.body_inertia[b]],
    }


# --- the 100-robot stress scene -------------------------------------------------------------
def _trace(world: World, names: list[str], history: list[Any], robot: int) -> list[dict[str, Any]]:
    """Replay the last control steps of ``history`` (states and commands) substep by substep
    into a copy of the data, recording robot ``robot``'s tilt, height and every contact it has
    with another robot or a pack (pair, normal force, normal's z, contact height)."""
    m = world.model
    d = mujoco.MjData(m)
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state, _ = history[0]
    mujoco.mj_setState(m, d, state, spec)
    b = int(world.chassis_body[robot])
    rows = []
    force = np.zeros(6)
    substeps = round(0.2 / m.opt.timestep)
    for _, ctrl in history:
        d.ctrl[:] = ctrl
        for _ in range(substeps):
            mujoco.mj_step(m, d)
            contacts = []
            for ci in range(d.ncon):
                c = d.contact[ci]
                r1, r2 = world.geom_robot[c.geom1], world.geom_robot[c.geom2]
                if robot not in (r1, r2):
                    continue
                other = c.geom2 if r1 == robot else c.geom1
                if world.geom_robot[other] == robot or names[other] == C.FLOOR_GEOM:
                    continue
                mine = c.geom1 if r1 == robot else c.geom2
                mujoco.mj_contactForce(m, d, ci, force)
                # normal from geom1 to geom2; sign so that + z pushes robot ``robot`` up
                nz = c.frame[2] * (1.0 if mine == c.geom2 else -1.0)
                contacts.append(
                    f"{names[mine]}<{names[other]} {force[0]:.0f}N nz{nz:+.2f} "
                    f"z{c.pos[2] * 100:.1f} pen{-c.dist * 1000:.1f}mm"
                )
            v = d.qvel[world.root_qvel_adr[robot] : world.root_qvel_adr[robot] + 3]
            rows.append(
                {
                    "t": round(d.time, 4),
                    "up": round(float(d.xmat[b, 8]), 3),
                    "z_com_cm": round(float(d.subtree_com[b, 2]) * 100, 2),
                    "v": [round(float(x), 2) for x in v],
                    "contacts": contacts,
                }
            )
    return rows


def stress(
    variant: Variant,
    seconds: float,
    seed: int = 0,
    report_every: float = 10.0,
    trace: int = 0,
    centre_first: bool = False,
) -> dict[str, Any]:
    """The reported scene: 100 robots, 125 packs, 11.5 m field; random driving, and every other
    5 s (5-10 s, 15-20 s, ...) all robots steer to the field's centre at 1.2 m/s. Counts the
    robots' tips past 60 deg (each crossing from above 0.5 uprightness to below it) and the
    robots that are upside down at the end (``centre_first``: the centre phases are 0-5 s,
    10-15 s, ...). The runner's watchdog (:class:`~cyber_rodent.survival.watchdog.Watchdog`,
    the paper's rules, every robot taken as running an agent, none docked) watches the scene
    too: its tips and stuck spells, their robot-steps and the longest of each.
    ``trace``: replay the first ``trace`` tips' last
    second substep by substep and keep the tipping robot's contacts."""
    cfg = WorldConfig(field_size=11.5, n_robots=100, n_packs=125)
    world = make_world(variant, cfg)
    world.reset(np.random.default_rng(seed))
    names = _names(world)
    rng = np.random.default_rng(seed + 1)
    n = cfg.n_robots
    substeps = round(0.2 / world.model.opt.timestep)
    left = rng.uniform(-0.3, 1.3, n)
    right = rng.uniform(-0.3, 1.3, n)
    tipped = np.zeros(n, dtype=bool)
    tips = 0
    tip_log: list[tuple[float, int]] = []
    traces: list[dict[str, Any]] = []
    history: list[Any] = []
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(world.model, spec))
    steps = round(seconds / 0.2)
    tally = LiftTally(world)
    wheels = np.zeros((n, 2))
    watchdog = Watchdog(world, wheels, np.zeros(n, dtype=bool), np.zeros(n, dtype=np.int64))
    watched: dict[str, list[int]] = {"tipped": [], "stuck": []}
    t0 = time.perf_counter()
    for k in range(steps):
        t = k * 0.2
        redraw = rng.random(n) < 0.2
        left = np.where(redraw, rng.uniform(-0.3, 1.3, n), left)
        right = np.where(redraw, rng.uniform(-0.3, 1.3, n), right)
        if int(t // 5.0) % 2 == (0 if centre_first else 1):
            pose = world.poses()
            err = np.arctan2(-pose[:, 1], -pose[:, 0]) - pose[:, 2]
            err = np.arctan2(np.sin(err), np.cos(err))
            w = np.clip(3.0 * err, -6.0, 6.0)
            b = robot_model().half_wheel_base
            cmd_l, cmd_r = 1.2 - w * b, 1.2 + w * b
            scale = np.maximum(1.0, np.maximum(np.abs(cmd_l), np.abs(cmd_r)) / 1.2)
            wheels[:, 0], wheels[:, 1] = cmd_l / scale, cmd_r / scale
        else:
            wheels[:, 0], wheels[:, 1] = left, right
        world.set_wheel_speeds(wheels[:, 0], wheels[:, 1])
        if trace:
            mujoco.mj_getState(world.model, world.data, state, spec)
            history.append((state.copy(), world.data.ctrl.copy()))
            del history[:-6]
        for _ in range(substeps):
            world.step(1)
            tally.sample()
        up = world.uprightness()
        new = (up < 0.5) & ~tipped
        for i in np.flatnonzero(new):
            tip_log.append((round(world.time, 2), int(i)))
            if len(traces) < trace:
                traces.append(
                    {
                        "robot": int(i),
                        "t": world.time,
                        "rows": _trace(world, names, history, int(i)),
                    }
                )
        tips += int(new.sum())
        tipped = up < 0.5
        seen = watchdog.observe()
        if seen is not None:
            watched["tipped"] += [lasted for _, lasted in seen.tip_ended]
            watched["stuck"] += [lasted for _, lasted in seen.stuck_ended]
        if report_every and (k + 1) % round(report_every / 0.2) == 0:
            print(
                f"  [{variant.name}] t={world.time:6.1f} s tips={tips} "
                f"tipped now={int(tipped.sum())} wall {time.perf_counter() - t0:.0f} s",
                file=sys.stderr,
                flush=True,
            )
    up = world.uprightness()
    robot_hours = n * seconds / 3600
    open_spells = {"tipped": watchdog.state.tipped_steps, "stuck": watchdog.state.stuck_steps}
    for kind, running in open_spells.items():
        watched[kind] += [int(x) for x in running if x > 0]
    watch = {f"watchdog_{kind}": {"spells": len(spells), "robot_steps": int(sum(spells)),
                                  "longest_steps": max(spells, default=0),
                                  "per_robot_hour": len(spells) / robot_hours}
             for kind, spells in watched.items()}  # fmt: skip
    return {
        "variant": variant.name,
        "seconds": seconds,
        "seed": seed,
        "centre_first": centre_first,
        "tips_past_60": tips,
        "robots_tipped_at_end": int((up < 0.5).sum()),
        "robots_upside_down_at_end": int((up < -0.5).sum()),
        "robot_hours": robot_hours,
        "tips_per_robot_hour": tips / robot_hours,
        "tips": tip_log,
        **watch,
        **tally.as_dict(),
        "wall_s": round(time.perf_counter() - t0, 1),
        "traces": traces,
    }


# --- lifting between robots ---------------------------------------------------------------------
#: Robot-robot geom pair classes, for :class:`LiftTally`.
PAIR_CLASSES = ("teeth-chassis", "chassis-chassis", "teeth-teeth", "other")


class LiftTally:
    """Per substep, the vertical component of every robot-robot contact force (the force that
    carries one robot on another), summed over time as an impulse (N s) per geom pair class,
    and the robot-seconds that a robot's centre of mass spends 2 cm or more above its height
    at rest ("riding": lifted onto something)."""

    def __init__(self, world: World) -> None:
        m = world.model
        self.world = world
        self.robot = world.geom_robot
        kind = np.full(m.ngeom, 2, dtype=np.int64)  # 0 chassis, 1 teeth, 2 other
        kind[world.chassis_geom] = 0
        kind[world.teeth_geom] = 1
        self.kind = kind
        self.lift = np.zeros(len(PAIR_CLASSES))
        self.riding_s = 0.0
        self.dt = m.opt.timestep

    def sample(self) -> None:
        d = self.world.data
        self.riding_s += self.dt * int((d.subtree_com[self.world.chassis_body, 2] > 0.055).sum())
        n = d.ncon
        if n == 0:
            return
        con = d.contact
        g = con.geom[:n]
        r1, r2 = self.robot[g[:, 0]], self.robot[g[:, 1]]
        rr = (r1 >= 0) & (r2 >= 0) & (r1 != r2)
        if not rr.any():
            return
        fn = d.efc_force[con.efc_address[:n][rr]]
        nz = np.abs(con.frame[:n, 2][rr])
        k1, k2 = self.kind[g[rr, 0]], self.kind[g[rr, 1]]
        cls = np.where(
            (k1 + k2 == 1) & (np.maximum(k1, k2) == 1),
            0,
            np.where((k1 == 0) & (k2 == 0), 1, np.where((k1 == 1) & (k2 == 1), 2, 3)),
        )
        np.add.at(self.lift, cls, fn * nz * self.dt)

    def as_dict(self) -> dict[str, Any]:
        lift = zip(PAIR_CLASSES, self.lift, strict=True)
        out = {f"lift_Ns_{c}": round(float(v), 2) for c, v in lift}
        out["riding_robot_s"] = round(self.riding_s, 2)
        return out


# --- pile-ups: N robots converging on one point ------------------------------------------------
def pile(
    variant: Variant,
    n: int = 24,
    trials: int = 20,
    v: float = 1.2,
    seconds: float = 5.0,
    seed: int = 7,
    trace: int = 0,
) -> dict[str, Any]:
    """``n`` robots in a ring (inner radius about n x 5 cm, at least 0.6 m; 0.6 m wide; no two
    closer than their discs, 2 x body_radius + 2 cm), each
    headed at the centre (+-20 deg) at 80-100 % of ``v``, driving straight for ``seconds``
    with the command held: the stress scene's centre phase in miniature. Counts tips past 60 deg
    (each robot's crossings of 0.5 uprightness) over ``trials`` seeded draws."""
    world = make_world(variant, WorldConfig(field_size=FIELD, n_robots=n, n_packs=0))
    names = _names(world)
    rng = np.random.default_rng(seed)
    substeps = round(0.2 / world.model.opt.timestep)
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(world.model, spec))
    per_trial: list[int] = []
    traces: list[dict[str, Any]] = []
    min_up: list[float] = []
    upside_down = 0
    tally = LiftTally(world)
    t0 = time.perf_counter()
    for _ in range(trials):
        radius = max(0.6, n * 0.32 / (2 * math.pi))
        xy: list[np.ndarray] = []
        while len(xy) < n:  # rejection: discs of body_radius + 1 cm apart
            a, r = rng.uniform(0, 2 * math.pi), radius + rng.uniform(0, 0.6)
            p = np.array([r * math.cos(a), r * math.sin(a)])
            if all(np.hypot(*(p - q)) > 2 * robot_model().body_radius + 0.02 for q in xy):
                xy.append(p)
        pos = np.array(xy)
        yaw = np.arctan2(-pos[:, 1], -pos[:, 0]) + rng.uniform(-0.35, 0.35, n)
        poses = np.column_stack([pos, yaw])
        start_cruising(world, poses, v * rng.uniform(0.8, 1.0, n))
        tipped = np.zeros(n, dtype=bool)
        count, lowest, history = 0, 1.0, []
        for _ in range(round(seconds / 0.2)):
            if trace:
                mujoco.mj_getState(world.model, world.data, state, spec)
                history.append((state.copy(), world.data.ctrl.copy()))
                del history[:-6]
            for _ in range(substeps):
                world.step(1)
                tally.sample()
            up = world.uprightness()
            new = (up < 0.5) & ~tipped
            for i in np.flatnonzero(new):
                if len(traces) < trace:
                    rows = _trace(world, names, history, int(i))
                    traces.append({"robot": int(i), "t": world.time, "rows": rows})
            count += int(new.sum())
            tipped |= up < 0.5
            lowest = min(lowest, float(up.min()))
        upside_down += int((world.uprightness() < -0.5).sum())
        per_trial.append(count)
        min_up.append(round(lowest, 3))
    return {
        "variant": variant.name,
        "n_robots": n,
        "trials": trials,
        "speed": v,
        "seconds": seconds,
        "tips_past_60": int(sum(per_trial)),
        "trials_with_a_tip": int(sum(c > 0 for c in per_trial)),
        "upside_down_at_end": upside_down,
        "per_trial": per_trial,
        "min_up_per_trial": min_up,
        **tally.as_dict(),
        "wall_s": round(time.perf_counter() - t0, 1),
        "traces": traces,
    }


# --- does a variant change anything without robot-robot contact? -----------------------------
def identity(
    variant: Variant, n_robots: int, n_packs: int, seconds: float, seed: int = 0
) -> dict[str, Any]:
    """Drive ``n_robots`` robots among ``n_packs`` packs in the default field with the same
    seeded random commands (redrawn with probability 0.2 per control step, rim speeds
    U(-0.3, 1.3) m/s; every robot keeps driving, into walls and packs too) in the base model and
    in ``variant``, and compare every control step's qpos bit for bit. Reports the first step
    at which they differ, the first base-model contact between a robot's teeth and another
    robot, and the count of control steps with such a contact."""
    cfg = WorldConfig(n_robots=n_robots, n_packs=n_packs)
    worlds = [make_world(VARIANTS["base"], cfg), make_world(variant, cfg)]
    for w in worlds:
        w.reset(np.random.default_rng(seed))
    rng = np.random.default_rng(seed + 1)
    n = n_robots
    left, right = rng.uniform(-0.3, 1.3, n), rng.uniform(-0.3, 1.3, n)
    base = worlds[0]
    teeth = set(base.teeth_geom.tolist())
    first_diff = first_teeth = None
    teeth_steps = env_steps = 0
    floor = int(mujoco.mj_name2id(base.model, mujoco.mjtObj.mjOBJ_GEOM, C.FLOOR_GEOM))
    max_dev = 0.0
    for _ in range(round(seconds / 0.2)):
        redraw = rng.random(n) < 0.2
        left = np.where(redraw, rng.uniform(-0.3, 1.3, n), left)
        right = np.where(redraw, rng.uniform(-0.3, 1.3, n), right)
        touched = env = False
        for w in worlds:
            w.set_wheel_speeds(left, right)
        for _ in range(round(0.2 / base.model.opt.timestep)):
            for w in worlds:
                w.step(1)
            d = base.data
            for g1, g2 in d.contact.geom[: d.ncon]:
                r1, r2 = base.geom_robot[g1], base.geom_robot[g2]
                if r1 >= 0 and r2 >= 0 and r1 != r2 and (g1 in teeth or g2 in teeth):
                    touched = True
                if (r1 < 0) != (r2 < 0) and floor not in (g1, g2):
                    env = True
        env_steps += env
        if touched:
            teeth_steps += 1
            if first_teeth is None:
                first_teeth = round(base.time, 2)
        if first_diff is None and not np.array_equal(worlds[0].data.qpos, worlds[1].data.qpos):
            first_diff = round(base.time, 2)
        dev = np.hypot(*(worlds[0].poses()[:, :2] - worlds[1].poses()[:, :2]).T).max()
        max_dev = max(max_dev, float(dev))
    return {
        "variant": variant.name,
        "n_robots": n_robots,
        "n_packs": n_packs,
        "seconds": seconds,
        "first_qpos_difference_s": first_diff,
        "first_teeth_robot_contact_s": first_teeth,
        "control_steps": round(seconds / 0.2),
        "control_steps_with_wall_or_pack_contact": env_steps,
        "control_steps_with_teeth_robot_contact": teeth_steps,
        "max_position_difference_m": round(max_dev, 4),
    }


def _print_trace(tr: dict[str, Any]) -> None:
    print(f"-- trace: robot {tr['robot']} tipped by t={tr['t']:.2f} s")
    last = None
    for row in tr["rows"]:
        key = (round(row["up"], 2), tuple(c.split(" ")[0] for c in row["contacts"]))
        if key != last or row["up"] < 0.99:
            print(
                f"   t={row['t']:.3f} up={row['up']:+.3f} zCoM={row['z_com_cm']:.1f}cm"
                f" v={row['v']} " + "; ".join(row["contacts"])
            )
        last = key


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="base", help=f"comma list of {','.join(VARIANTS)}")
    parser.add_argument("--cases", default="", help="comma list of case names (default all)")
    parser.add_argument("--speeds", default=",".join(str(s) for s in SPEEDS))
    parser.add_argument("--after", type=float, default=2.5, help="s simulated after touch")
    parser.add_argument("--detail", action="store_true", help="one line per run")
    parser.add_argument("--json", default="", help="write all results to this path")
    parser.add_argument("--stress", action="store_true", help="run the 100-robot scene")
    parser.add_argument("--stress-seconds", type=float, default=150.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--trace", type=int, default=0, help="stress/pile: trace the first N tips")
    parser.add_argument("--pile", action="store_true", help="run the pile-up scene")
    parser.add_argument("--sweep", type=int, default=0, help="N random head-on encounters")
    parser.add_argument(
        "--identity",
        action="store_true",
        help="compare each variant's trajectories with the base model's (1 and 4 robots)",
    )
    parser.add_argument("--identity-seconds", type=float, default=300.0)
    parser.add_argument("--pile-robots", type=int, default=24)
    parser.add_argument("--pile-trials", type=int, default=20)
    parser.add_argument("--pile-speed", type=float, default=1.2)
    parser.add_argument(
        "--centre-first", action="store_true", help="stress: steer to the centre in 0-5 s"
    )
    parser.add_argument("--render", default="", help="draw the flipping knock per variant (PNG)")
    args = parser.parse_args(argv)
    if args.render:
        ups = render_knock([VARIANTS[v] for v in args.variant.split(",") if v], args.render)
        print(f"wrote {args.render}; lowest uprightness per frame: {ups}")
        return

    variants = [VARIANTS[v] for v in args.variant.split(",") if v]
    cases = [c for c in CASES if not args.cases or c.name in args.cases.split(",")]
    speeds = [float(s) for s in args.speeds.split(",") if s]
    out: dict[str, Any] = {"speeds": speeds, "cases": [dataclasses.asdict(c) for c in cases]}
    base_world = make_world(VARIANTS["base"], WorldConfig(field_size=FIELD, n_robots=2, n_packs=0))
    out["mass"] = mass_report(base_world)
    print("mass properties (base):", out["mass"])
    table: dict[str, list[Result]] = {}
    if args.sweep:
        out["sweep"] = []
        for variant in variants:
            res = sweep(variant, args.sweep)
            print(json.dumps(res))
            out["sweep"].append(res)
    elif args.identity:
        out["identity"] = []
        for variant in variants:
            for n_robots, n_packs in ((1, 5), (1, 0), (4, 5)):
                res = identity(variant, n_robots, n_packs, args.identity_seconds, args.seed)
                print(json.dumps(res))
                out["identity"].append(res)
    elif args.pile:
        out["pile"] = []
        for variant in variants:
            res = pile(
                variant, args.pile_robots, args.pile_trials, args.pile_speed, trace=args.trace
            )
            print(json.dumps({k: v for k, v in res.items() if k != "traces"}))
            for tr in res["traces"]:
                _print_trace(tr)
            out["pile"].append(res)
    elif not args.stress:
        for variant in variants:
            table[variant.name] = run_scene(variant, cases, speeds, args.after)
            if args.detail:
                print_table(variant, table[variant.name])
        print_matrix(variants, cases, speeds, table)
        out["scene"] = {
            name: [dataclasses.asdict(r) for r in results] for name, results in table.items()
        }
    else:
        out["stress"] = []
        for variant in variants:
            res = stress(
                variant,
                args.stress_seconds,
                args.seed,
                trace=args.trace,
                centre_first=args.centre_first,
            )
            print(json.dumps({k: v for k, v in res.items() if k != "traces"}))
            for tr in res["traces"]:
                _print_trace(tr)
            out["stress"].append(res)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
