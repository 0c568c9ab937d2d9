"""The fit's error model: a parametric bootstrap that re-simulates the logged run.

A bootstrap over log segments measures how much a fit moves when the segments change; it
cannot see a fit that is wrong the same way on every segment. The drive fit is: the replay
lacks the other robots, and a robot that seldom slips shows its wheel-floor friction hardly at
all. So the fit's error is also estimated by simulation:

* **Noise of the log** (:func:`log_noise`), from the fit's residuals: the encoders' noise (the
  robust spread of first differences of logged minus replayed wheel speeds, / sqrt 2), their
  glitches (residuals beyond 6 of those standard deviations and 0.2 m/s: their share and
  sizes), and the tracker's position and heading noise (robust spread of second differences,
  / sqrt 6; smooth drift of the replay cancels out of both differences). The time stamps'
  noise comes from the robots' rows of one step: their spread about the step's mean
  (robust, times sqrt(n / (n - 1)) for n robots); one robot, or a shared clock, shows none.
* **A replicate** (:func:`replicate`) re-runs the log in a world with all its robots and packs,
  with the fitted drives, IR and camera noise, each robot driven by its logged commands for
  the logged step lengths. At the first row of each of its segments a robot is put back in
  the state the log records there (:func:`~cyber_rodent.sysid.replay.set_start_state`), so the
  replicate follows the log's paths and meets the walls and robots the log met. It records
  what the log records, with that noise, the log's own dropped tracker frames, and every
  other column (commands, LED, events) as logged. A step lasts as long as the mean of its
  robots' logged stamps says; each row's time stamp is that time plus the clock noise.
* The fit is repeated on every replicate, from its usual start; the refits' spread and their
  bias about the fitted values (the truth of the replicates) are the fit's simulated error.

Not in it: the noise of a clock a log cannot show (one robot's only), and any way the robot
differs from the model beyond the fitted parameters.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from cyber_rodent.profiles import RangeNoise, RangeSensorNoise, VisionUncertainty
from cyber_rodent.sysid.log import RunLog, wrap_angle
from cyber_rodent.sysid.replay import DriveWriter, Replayer, Segment, set_start_state
from cyber_rodent.sysid.synthetic import sensor_columns
from cyber_rodent.vision import CameraConfig, make_provider
from cyber_rodent.world import World, WorldConfig

#: Median absolute deviation to the standard deviation of a normal distribution.
MAD_TO_SD = 1.4826
#: An encoder residual is a glitch beyond this many standard deviations ...
GLITCH_SDS = 6.0
#: ... and this many m/s.
GLITCH_MIN = 0.2


@dataclass(frozen=True)
class LogNoise:
    """The measurement noise of a log, as estimated from a fit's residuals.

    Attributes:
        encoder_std: m/s, the encoders' noise.
        glitch_rate: share of encoder readings that are glitches.
        glitches: m/s, the glitches' sizes seen (drawn from when a replicate glitches).
        tracker_std: m, the tracker's position noise.
        tracker_yaw_std: rad, its heading noise.
        clock_std: s, the time stamps' noise.
    """

    encoder_std: float = 0.0
    glitch_rate: float = 0.0
    glitches: tuple[float, ...] = ()
    tracker_std: float = 0.0
    tracker_yaw_std: float = 0.0
    clock_std: float = 0.0


def _robust_sd(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return MAD_TO_SD * float(np.median(np.abs(x - np.median(x)))) if len(x) else 0.0


def log_noise(
    replayers: list[Replayer], fitted: dict[int, list[tuple[int, Segment]]],
    drives: dict[int, np.ndarray],
) -> LogNoise:  # fmt: skip
    """Estimate a log's noise (module docstring) from the replays of the ``fitted`` segments
    of each robot ((log index, segment) pairs) under its fitted drive."""
    wheel_d1, wheel_res, pos_d2, yaw_d2 = [], [], [], []
    for robot, segs in fitted.items():
        for li, seg in segs:
            speeds, poses = replayers[li].run(seg, drives[robot])
            rows = seg.rows
            if "wheel_left" in rows:
                r = rows[["wheel_left", "wheel_right"]].to_numpy(dtype=float)[1:] - speeds[1:]
                wheel_res.append(r.ravel())
                wheel_d1.append(np.diff(r, axis=0).ravel())
            if "tracked" in rows:
                ok = rows["tracked"].to_numpy(dtype=bool)
                e = rows[["x", "y", "yaw"]].to_numpy(dtype=float) - poses
                e[:, 2] = wrap_angle(e[:, 2])
                triple = ok[:-2] & ok[1:-1] & ok[2:]
                d2 = e[2:] - 2 * e[1:-1] + e[:-2]
                d2[:, 2] = wrap_angle(d2[:, 2])
                pos_d2.append(d2[triple, :2].ravel())
                yaw_d2.append(d2[triple, 2])
    out = LogNoise(clock_std=clock_noise(replayers))
    if wheel_res:
        sd = _robust_sd(np.concatenate(wheel_d1)) / math.sqrt(2)
        res = np.concatenate(wheel_res)
        dev = res - np.median(res)
        glitch = np.abs(dev) > max(GLITCH_SDS * sd, GLITCH_MIN)
        out = dataclasses.replace(out, encoder_std=sd, glitch_rate=float(glitch.mean()),
                                  glitches=tuple(map(float, dev[glitch])))  # fmt: skip
    if pos_d2:
        out = dataclasses.replace(
            out, tracker_std=_robust_sd(np.concatenate(pos_d2)) / math.sqrt(6),
            tracker_yaw_std=_robust_sd(np.concatenate(yaw_d2)) / math.sqrt(6),
        )  # fmt: skip
    return out


def clock_noise(replayers: list[Replayer]) -> float:
    """The time stamps' noise, from the spread of the robots' stamps of one step about their
    mean (module docstring), over the logs of ``replayers``."""
    devs = []
    for replayer in replayers:
        table = replayer.log.table
        counts = table.groupby("step")["t"].transform("size").to_numpy()
        n = int(counts.max()) if len(counts) else 0
        if n < 2:
            continue
        full = counts == n
        mean = table.groupby("step")["t"].transform("mean").to_numpy()
        devs.append((table["t"].to_numpy() - mean)[full] * math.sqrt(n / (n - 1)))
    return _robust_sd(np.concatenate(devs)) if devs else 0.0


def replicate(
    log: RunLog,
    drives: dict[int, np.ndarray],
    range_noise: RangeNoise,
    vision: VisionUncertainty,
    noise: LogNoise,
    starts: set[tuple[int, int]],
    rng: np.random.Generator,
    timestep: float = WorldConfig.timestep,
) -> RunLog:
    """One replicate of ``log`` (module docstring). ``drives``: robot id -> fitted drive;
    ``starts``: the (robot id, step) rows where a robot is put back in its logged state (a
    robot's first row always is)."""
    table = log.table
    robots = log.robots
    n = len(robots)
    config = WorldConfig(field_size=log.field_size, n_robots=n, n_packs=len(log.packs),
                         timestep=timestep, pack_gap=0.0, pack_wall_clearance=0.0)  # fmt: skip
    world = World(config)
    for j, (x, y) in enumerate(log.packs):
        world.set_pack_position(j, float(x), float(y))
    writer = DriveWriter(world)
    for i, robot in enumerate(robots):
        writer.set(i, drives[robot])
    ranges_on = "ir0" in table
    camera_on = "cam_led_seen" in table
    ir_noise = RangeSensorNoise(range_noise, world.range_max, rng)
    provider = make_provider("geometric", world, CameraConfig(noise=vision.noise()), rng)
    out = table.copy()
    empty = {c for c in out.columns if c.endswith("_area") and bool(table[c].isna().all())}
    flags = {c for c in out.columns if out[c].dtype == bool}
    by_step = {int(s): rows for s, rows in table.groupby("step")}
    true_t = {step: float(np.mean(rows["t"].to_numpy())) for step, rows in by_step.items()}
    begun: set[int] = set()
    steps = sorted(by_step)
    for k, step in enumerate(steps):
        rows = by_step[step]
        present = {int(r): idx for r, idx in zip(rows["robot"], rows.index, strict=True)}
        anchored = False
        for i, robot in enumerate(robots):
            if robot in present and (robot not in begun or (robot, step) in starts):
                set_start_state(writer, i, table.loc[present[robot]], drives[robot])
                begun.add(robot)
                anchored = True
        if anchored:
            mujoco.mj_forward(world.model, world.data)
        if "led" in rows:
            led = np.zeros(n, dtype=bool)
            for i, robot in enumerate(robots):
                if robot in present:
                    led[i] = bool(table.at[present[robot], "led"])
            world.set_led(led)
        poses, wheels = world.poses(), writer.wheel_speeds()
        readings = ir_noise.apply(world.range_readings()) if ranges_on else None
        frame = provider.observe() if camera_on else None
        cmd = np.zeros((n, 2))
        for i, robot in enumerate(robots):
            if robot not in present:
                continue
            idx = present[robot]
            cmd[i] = table.loc[idx, ["cmd_left", "cmd_right"]].to_numpy(dtype=float)
            if noise.clock_std > 0:
                out.at[idx, "t"] = true_t[step] + rng.normal(0.0, noise.clock_std)
            if "wheel_left" in table:
                value = wheels[i] + rng.normal(0.0, noise.encoder_std, size=2)
                glitch = rng.random(2) < noise.glitch_rate
                if glitch.any() and noise.glitches:
                    value[glitch] += rng.choice(np.asarray(noise.glitches), size=int(glitch.sum()))
                out.loc[idx, ["wheel_left", "wheel_right"]] = value
            if "tracked" in table and bool(table.at[idx, "tracked"]):
                xy = poses[i, :2] + rng.normal(0.0, noise.tracker_std, size=2)
                yaw = float(wrap_angle(poses[i, 2] + rng.normal(0.0, noise.tracker_yaw_std)))
                out.loc[idx, ["x", "y", "yaw"]] = (xy[0], xy[1], yaw)
            for name, value in sensor_columns(readings, frame, i).items():
                if name in out.columns and name not in empty:
                    out.at[idx, name] = bool(value) if name in flags else value
        if k + 1 == len(steps):
            break
        dt = true_t[steps[k + 1]] - true_t[step]
        world.set_wheel_speeds(cmd[:, 0], cmd[:, 1])
        world.step(max(1, round(dt / timestep)))
    return RunLog(log.path, out, log.field_size, log.packs)


__all__ = ["LogNoise", "log_noise", "replicate"]
