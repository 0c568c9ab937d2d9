"""A log's wheel commands replayed in MuJoCo with a candidate drive, segment by segment.

A row of a log is what the robot measured at its time ``t`` (encoders, pose, sensors) and the
command it then sent, held until the next row's time. A replay puts one robot at the logged
pose of a segment's first row (the field centre, facing +x, if that row has no pose), sets its
wheels and motor state to the logged wheel speeds and previous command, and steps the physics
``round(dt / timestep)`` substeps for each row's time step ``dt`` (so clock jitter in the log is
replayed as logged). It returns the simulated wheel speeds and poses at every later row. The
replay world holds the log's packs and walls but not the other robots.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import pandas as pd

from cyber_rodent import constants as C
from cyber_rodent.sysid.log import RunLog
from cyber_rodent.world import World, WorldConfig

#: A drive: left gain, right gain, motor lag (s), friction factor.
DRIVE_NAMES = ("gain_left", "gain_right", "motor_lag", "friction")
#: The model's drive as built.
NOMINAL_DRIVE = np.array([1.0, 1.0, 0.05, 1.0])


class DriveWriter:
    """Writes per-robot drives into a world's compiled model, relative to the model as built
    (the same quantities :func:`cyber_rodent.profiles.apply_actuators` changes)."""

    def __init__(self, world: World) -> None:
        from cyber_rodent.profiles import _wheel_ids

        self.world = world
        self.motors, self.geoms = _wheel_ids(world)
        m = world.model
        self.gain0 = m.actuator_gainprm[self.motors, 0].copy()
        self.friction0 = m.geom_friction[self.geoms, 0].copy()
        n = world.config.n_robots
        parts = world.robot.parts
        self.wheel_dof = np.array(
            [
                [
                    m.jnt_dofadr[
                        mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, C.robot_prefix(i) + j)
                    ]
                    for j in (parts.left_wheel_joint, parts.right_wheel_joint)
                ]
                for i in range(n)
            ]
        )
        self.act_adr = np.array([[m.actuator_actadr[a] for a in row] for row in self.motors])

    def set(self, robot: int, drive: np.ndarray) -> None:
        """Robot ``robot``'s drive (:data:`DRIVE_NAMES`)."""
        m = self.world.model
        motors, geoms = self.motors[robot], self.geoms[robot]
        m.actuator_gainprm[motors, 0] = self.gain0[robot] * drive[:2]
        m.actuator_dynprm[motors, 0] = drive[2]
        m.geom_friction[geoms, 0] = self.friction0[robot] * drive[3]

    def wheel_speeds(self) -> np.ndarray:
        """(n, 2) wheel rim speeds, m/s (what an encoder measures)."""
        speeds: np.ndarray = self.world.data.qvel[self.wheel_dof] * self.world.wheel_radius
        return speeds


def set_start_state(writer: DriveWriter, robot: int, row: pd.Series, drive: np.ndarray) -> None:
    """Put robot ``robot`` of ``writer``'s world in the state a log row records: its pose (the
    field centre, facing +x, if the row has none), its body and wheels moving at the logged
    wheel speeds (the command times the gains if there are none), and its motors' filtered
    command where those speeds settled. The caller runs ``mj_forward``."""
    w = writer.world
    d = w.data
    if "tracked" in row and bool(row["tracked"]):
        x, y, yaw = float(row["x"]), float(row["y"]), float(row["yaw"])
    else:
        x, y, yaw = 0.0, 0.0, 0.0
    w.set_robot_pose(robot, x, y, yaw)
    cmd = np.array([float(row["cmd_left"]), float(row["cmd_right"])])
    gains = np.maximum(np.asarray(drive[:2], dtype=float), 1e-3)
    if "wheel_left" in row:
        wheels = np.array([float(row["wheel_left"]), float(row["wheel_right"])])
        settled = wheels / gains
    else:
        wheels, settled = cmd * gains, cmd
    radius = w.wheel_radius
    v = wheels.mean()
    omega = (wheels[1] - wheels[0]) / (2 * w.robot.half_wheel_base)
    qv = int(w.root_qvel_adr[robot])
    d.qvel[qv : qv + 2] = (v * math.cos(yaw), v * math.sin(yaw))
    d.qvel[qv + 5] = omega
    d.qvel[writer.wheel_dof[robot]] = wheels / radius
    d.act[writer.act_adr[robot]] = settled / radius


@dataclass(frozen=True)
class Segment:
    """Rows ``start`` .. ``stop - 1`` of one robot's rows in a log.

    Attributes:
        robot: the robot's id in the log.
        index: the segment's number among the robot's segments (0, 1, ...).
        rows: the rows (a copy, fresh index).
    """

    robot: int
    index: int
    rows: pd.DataFrame


def segments(log: RunLog, seconds: float) -> list[Segment]:
    """Each robot's rows cut into consecutive segments of ``seconds`` (the last shorter piece
    dropped if under half a segment), robot by robot."""
    out: list[Segment] = []
    for robot in log.robots:
        rows = log.of_robot(robot)
        t = rows["t"].to_numpy()
        edges = np.arange(t[0], t[-1] + 1e-9, seconds)
        k = 0
        for a in edges:
            part = rows[(t >= a) & (t < a + seconds)].reset_index(drop=True)
            if len(part) >= 2 and part["t"].iloc[-1] - part["t"].iloc[0] >= seconds / 2:
                out.append(Segment(robot, k, part))
                k += 1
    return out


class Replayer:
    """One robot in the log's field, replaying segments (see the module docstring).

    Args:
        log: the log (its field and packs).
        timestep: physics timestep, s (the world's default).
    """

    def __init__(self, log: RunLog, timestep: float = WorldConfig.timestep) -> None:
        config = WorldConfig(
            field_size=log.field_size, n_robots=1, n_packs=len(log.packs), timestep=timestep,
            pack_gap=0.0, pack_wall_clearance=0.0,
        )  # fmt: skip
        self.log = log
        self.world = World(config)
        for j, (x, y) in enumerate(log.packs):
            self.world.set_pack_position(j, float(x), float(y))
        self.drive = DriveWriter(self.world)
        self.timestep = timestep

    def run(self, segment: Segment, drive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rows, 2) simulated wheel speeds and (rows, 3) poses of ``segment`` under ``drive``;
        row 0 is the start state as set."""
        w, rows = self.world, segment.rows
        d = w.data
        mujoco.mj_resetData(w.model, d)
        self.drive.set(0, np.asarray(drive, dtype=float))
        cmd = rows[["cmd_left", "cmd_right"]].to_numpy(dtype=float)
        set_start_state(self.drive, 0, rows.iloc[0], drive)
        mujoco.mj_forward(w.model, d)
        t = rows["t"].to_numpy(dtype=float)
        n = len(rows)
        speeds, poses = np.empty((n, 2)), np.empty((n, 3))
        speeds[0], poses[0] = self.drive.wheel_speeds()[0], w.poses()[0]
        for k in range(n - 1):
            w.set_wheel_speeds(cmd[k, :1], cmd[k, 1:])
            w.step(max(1, round((t[k + 1] - t[k]) / self.timestep)))
            speeds[k + 1], poses[k + 1] = self.drive.wheel_speeds()[0], w.poses()[0]
        return speeds, poses


__all__ = ["DRIVE_NAMES", "NOMINAL_DRIVE", "DriveWriter", "Replayer", "Segment", "segments",
           "set_start_state"]  # fmt: skip
