"""Logs of a simulated "true robot": hidden parameters, realistic faults (validation only).

:func:`true_robot` draws a hidden hardware (each robot's drive, the IR and camera noise) from a
seed; :func:`simulate_log` runs it in the full world (3 robots, 6 packs by default) under a
scripted wander (the behaviours' discrete wheel commands, held 1-5 steps, with an IR reflex that
turns away from what is close in front) and records what a real robot would log, with the faults
of :class:`LogFaults`: tracker noise and dropped frames, encoder noise and glitches, clock
jitter (each step lasts a random number of physics substeps, and the logged time stamps carry
their own error).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from cyber_rodent.commands import COMMAND_SPEEDS
from cyber_rodent.profiles import RangeNoise, RangeSensorNoise, VisionUncertainty
from cyber_rodent.sysid.log import CAMERA_CLASSES
from cyber_rodent.sysid.replay import DriveWriter
from cyber_rodent.validation import integer, number, validate_fields
from cyber_rodent.vision import CameraConfig, make_provider
from cyber_rodent.vision.types import VisionFrame
from cyber_rodent.world import World, WorldConfig


@dataclass(frozen=True)
class LogFaults:
    """The imperfections of a synthetic log.

    Attributes:
        tracker_std: m, std of the overhead tracker's position error; default 0.003.
        tracker_yaw_std_deg: degrees, std of its heading error; default 1.
        tracker_drop: probability that a tracker frame is lost (``tracked`` 0); default 0.03.
        encoder_std: m/s, std of the encoders' speed error; default 0.01.
        encoder_glitch: probability that an encoder reading is a glitch (a spike of
            U[0.5, 2] m/s either way); default 0.01.
        substep_jitter: the physics substeps of a control step vary by up to this many either
            way (24 +- 2 at the default timestep: +-17 ms); default 2.
        clock_std: s, std of each logged time stamp's error; default 0.002.
    """

    tracker_std: float = number(0.003, 0.0, 0.1, unit="m")
    tracker_yaw_std_deg: float = number(1.0, 0.0, 10.0, unit="deg")
    tracker_drop: float = number(0.03, 0.0, 0.5)
    encoder_std: float = number(0.01, 0.0, 0.5, unit="m/s")
    encoder_glitch: float = number(0.01, 0.0, 0.5)
    substep_jitter: int = integer(2, 0, 10, unit="substeps")
    clock_std: float = number(0.002, 0.0, 0.02, unit="s")

    def __post_init__(self) -> None:
        validate_fields(self, "faults.")


@dataclass(frozen=True)
class TrueRobot:
    """A hidden hardware: per-robot drives (n, 4) as :data:`~cyber_rodent.sysid.replay.
    DRIVE_NAMES`, and the IR and camera noise."""

    drives: np.ndarray
    range_noise: RangeNoise
    vision: VisionUncertainty

    def parameters(self) -> dict[str, float]:
        """Every hidden value by the name the fit reports it under."""
        out: dict[str, float] = {}
        for r, drive in enumerate(self.drives):
            for name, value in zip(
                ("gain_left", "gain_right", "motor_lag", "friction"), drive, strict=True
            ):
                out[f"robot{r}.{name}"] = float(value)
        out["range_noise.std"] = self.range_noise.std
        out["range_noise.dropout"] = self.range_noise.dropout
        out["vision.bearing_std_deg"] = self.vision.bearing_std_deg
        out["vision.distance_rel_std"] = self.vision.distance_rel_std
        out["vision.dropout"] = self.vision.dropout
        return out


def sensor_columns(
    ranges: np.ndarray | None, frame: VisionFrame | None, r: int
) -> dict[str, float]:
    """Robot ``r``'s IR and camera columns of a log row from a world's noisy readings
    (``ranges``: every robot's) and vision frame (empty where the camera did not see); either
    may be None (no such columns)."""
    row: dict[str, float] = {}
    if ranges is not None:
        row.update({f"ir{i}": float(v) for i, v in enumerate(ranges[r])})
    if frame is None:
        return row
    areas = {c: math.nan for c in range(3)}
    for blob in frame.blobs[r] if frame.blobs else []:
        if abs(blob.distance - frame.distance[r, blob.cls]) < 1e-12:
            areas[blob.cls] = blob.area
    for c, name in enumerate(CAMERA_CLASSES):
        seen = bool(frame.visible[r, c])
        row[f"cam_{name}_seen"] = float(seen)
        row[f"cam_{name}_bearing"] = float(frame.bearing[r, c]) if seen else math.nan
        row[f"cam_{name}_distance"] = float(frame.distance[r, c]) if seen else math.nan
        row[f"cam_{name}_area"] = (
            areas[c] if seen and not math.isnan(areas[c]) else (0.0 if seen else math.nan)
        )
    return row


@dataclass(frozen=True)
class HardwareSpread:
    """The uniform ranges hidden hardware is drawn from (each a (low, high) pair).

    Attributes:
        gain: each wheel's gain; lag: s, motor lag; friction: wheel-floor friction factor;
        ir_std: m, IR noise; ir_dropout; bearing_deg, distance_rel, miss: the camera's
        bearing and relative distance noise and miss rate.
    """

    gain: tuple[float, float] = (0.75, 1.15)
    lag: tuple[float, float] = (0.04, 0.15)
    friction: tuple[float, float] = (0.6, 1.4)
    ir_std: tuple[float, float] = (0.005, 0.04)
    ir_dropout: tuple[float, float] = (0.0, 0.06)
    bearing_deg: tuple[float, float] = (1.0, 8.0)
    distance_rel: tuple[float, float] = (0.03, 0.2)
    miss: tuple[float, float] = (0.02, 0.2)


#: Named spreads: ``typical`` (robots within about 15 % of the model: the recovery study's) and
#: ``worn`` (a worn or mis-built robot: weak, unequal wheels, sluggish motors, slippery tyres).
SPREADS = {
    "typical": HardwareSpread(),
    "worn": HardwareSpread(gain=(0.5, 0.85), lag=(0.15, 0.3), friction=(0.4, 1.0)),
}


def true_robot(seed: int, n_robots: int = 3, spread: str = "typical") -> TrueRobot:
    """A hidden hardware drawn from ``seed`` within the ranges of ``SPREADS[spread]``
    (``typical``: gains U[0.75, 1.15] per wheel, motor lag U[0.04, 0.15] s, friction factor
    U[0.6, 1.4], IR noise U[0.005, 0.04] m with dropout U[0, 0.06], camera bearing U[1, 8] deg,
    distance U[0.03, 0.2], miss rate U[0.02, 0.2])."""
    s = SPREADS[spread]
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x7E57]))
    drives = np.column_stack(
        [
            rng.uniform(*s.gain, size=(n_robots, 2)),
            rng.uniform(*s.lag, size=n_robots),
            rng.uniform(*s.friction, size=n_robots),
        ]
    )
    ranges = RangeNoise(
        std=float(rng.uniform(*s.ir_std)), dropout=float(rng.uniform(*s.ir_dropout))
    )
    vision = VisionUncertainty(
        bearing_std_deg=float(rng.uniform(*s.bearing_deg)),
        distance_rel_std=float(rng.uniform(*s.distance_rel)),
        dropout=float(rng.uniform(*s.miss)),
    )
    return TrueRobot(drives, ranges, vision)


def simulate_log(
    robot: TrueRobot,
    seconds: float,
    seed: int,
    faults: LogFaults | None = None,
    n_packs: int = 6,
    control_dt: float = 0.2,
) -> tuple[pd.DataFrame, float, np.ndarray]:
    """A run log of ``robot`` wandering for ``seconds`` (see the module docstring).

    Returns:
        The table (columns of the encoders, tracker, ir, led and camera groups), the field size
        and the packs' positions.
    """
    faults = faults or LogFaults()
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x106]))
    n = len(robot.drives)
    world = World(WorldConfig(n_robots=n, n_packs=n_packs), rng)
    writer = DriveWriter(world)
    for r in range(n):
        writer.set(r, robot.drives[r])
    range_noise = RangeSensorNoise(robot.range_noise, world.range_max, rng)
    camera = CameraConfig(noise=robot.vision.noise())
    vision = make_provider("geometric", world, camera, rng)
    substeps = round(control_dt / world.config.timestep)
    steps = int(round(seconds / control_dt))
    command = rng.integers(len(COMMAND_SPEEDS), size=n)
    hold = rng.integers(1, 6, size=n)
    led = rng.random(n) < 0.5
    rows: list[dict[str, float]] = []
    t = 0.0
    for k in range(steps):
        world.set_led(led)
        poses = world.poses()
        wheels = writer.wheel_speeds()
        ranges = range_noise.apply(world.range_readings())
        frame = vision.observe()
        for r in range(n):
            row: dict[str, float] = {
                "step": k,
                "t": 1.0 + t + rng.normal(0, faults.clock_std),
                "robot": r,
            }
            if ranges[r, 0] < 0.15 or min(ranges[r, 1], ranges[r, 2]) < 0.1:
                command[r], hold[r] = (4 if rng.random() < 0.5 else 5), 3  # turn away
            elif hold[r] <= 0:
                command[r], hold[r] = rng.integers(len(COMMAND_SPEEDS)), rng.integers(1, 6)
            hold[r] -= 1
            row["cmd_left"], row["cmd_right"] = COMMAND_SPEEDS[command[r]]
            for side, speed in zip(("wheel_left", "wheel_right"), wheels[r], strict=True):
                value = speed + rng.normal(0, faults.encoder_std)
                if rng.random() < faults.encoder_glitch:
                    value += rng.choice((-1, 1)) * rng.uniform(0.5, 2.0)
                row[side] = value
            tracked = rng.random() >= faults.tracker_drop
            row["tracked"] = float(tracked)
            if tracked:
                row["x"] = poses[r, 0] + rng.normal(0, faults.tracker_std)
                row["y"] = poses[r, 1] + rng.normal(0, faults.tracker_std)
                yaw = poses[r, 2] + rng.normal(0, math.radians(faults.tracker_yaw_std_deg))
                row["yaw"] = (yaw + math.pi) % (2 * math.pi) - math.pi
            else:
                row["x"] = row["y"] = row["yaw"] = math.nan
            row.update(sensor_columns(ranges, frame, r))
            row["led"] = float(led[r])
            rows.append(row)
        if rng.random() < 0.05:
            led = rng.random(n) < 0.5
        world.set_wheel_speeds(COMMAND_SPEEDS[command, 0], COMMAND_SPEEDS[command, 1])
        jitter = int(rng.integers(-faults.substep_jitter, faults.substep_jitter + 1))
        world.step(substeps + jitter)
        t = world.time
    return pd.DataFrame(rows), world.config.field_size, world.pack_positions()


__all__ = [
    "SPREADS",
    "HardwareSpread",
    "LogFaults",
    "TrueRobot",
    "sensor_columns",
    "simulate_log",
    "true_robot",
]
