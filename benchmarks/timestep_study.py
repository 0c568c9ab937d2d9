"""Timestep study: trajectories at candidate timesteps vs a 5x finer reference.

Four robots drive scripted, collision-free patterns (figure-eights tracked at up to 1 m/s,
with hard spins in place and catch-up sprints; see :func:`script`) for 10 s of simulated time,
in the default world. For each candidate timestep ``dt``, the reference runs the script at
``dt / 5`` and records the wheel commands of every 0.1 s control step; the candidate replays
exactly those commands open-loop at ``dt``. So both runs get identical inputs and any
difference is integration error (a closed-loop law would add its own bifurcations). The
figure of merit is the largest distance between the two runs' robot positions at any control
step. A timestep passes if that is below 2 cm. The default ``WorldConfig.timestep`` is the
largest passing candidate.

Run: ``python -m benchmarks.timestep_study``
"""

from __future__ import annotations

import argparse
import math

import mujoco
import numpy as np

from cyber_rodent.world import World, WorldConfig

TOLERANCE = 0.02  # m
DURATION = 10.0  # s
CONTROL_DT = 0.1  # s
START = np.array([[-0.55, -0.55, 0.3], [0.55, -0.55, 2.0], [0.55, 0.55, -2.5], [-0.55, 0.55, 1.0]])


def reference(t: float) -> np.ndarray:
    """(4, 2) reference points: a figure-eight (0.7 m wide, 4 s period) in each quadrant."""
    w = 2 * math.pi * (t + np.arange(4) * 0.7) / 4.0
    centre = START[:, :2]
    return centre + 0.35 * np.column_stack([np.sin(w), np.sin(w) * np.cos(w)])


def script(t: float, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Wheel speeds (m/s) at time t: track the figure-eights, with spins in place.

    A deterministic tracking law (drive toward the moving reference point, turn toward it)
    keeps the robots in their quadrants; every 2.5 s each robot spins in place left, then
    right (0.3 s each, at 0.6 m/s wheel speed), then catches up. The reference run records
    the commands this law gives; the candidate replays them.
    """
    target = reference(t)
    delta = target - pose[:, :2]
    heading_err = np.arctan2(delta[:, 1], delta[:, 0]) - pose[:, 2]
    heading_err = np.arctan2(np.sin(heading_err), np.cos(heading_err))
    v = np.clip(2.5 * np.hypot(delta[:, 0], delta[:, 1]), 0.0, 1.0) * np.cos(heading_err)
    w = np.clip(4.0 * heading_err, -8.0, 8.0)
    left, right = v - w * 0.08, v + w * 0.08
    # Spin left, then right by as much: the robot turns hard and ends facing its path again.
    phase = (t + np.arange(4) * 0.6) % 2.5
    spin = np.where(phase < 0.3, 1.0, np.where(phase < 0.6, -1.0, 0.0))
    left = np.where(spin != 0, -0.6 * spin, left)
    right = np.where(spin != 0, 0.6 * spin, right)
    return left, right


def trajectory(dt: float, commands: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Drive the 4 robots for ``DURATION`` at timestep ``dt``.

    Args:
        dt: physics timestep.
        commands: (steps, 2, 4) wheel commands to replay open-loop; ``None`` runs the tracking
            law of :func:`script` closed-loop and records its commands.

    Returns:
        poses (steps, 4, 3) after every control step, and the commands (steps, 2, 4) used.
    """
    world = World(WorldConfig(n_robots=4, n_packs=5, timestep=dt), np.random.default_rng(0))
    start = np.column_stack([reference(0.0), START[:, 2]])
    for i, (x, y, yaw) in enumerate(start):
        world.set_robot_pose(i, x, y, yaw)
    for j in range(world.config.n_packs):  # packs out of the way, along the walls
        world.set_pack_position(j, -0.9 + 0.45 * j, 1.05)
    mujoco.mj_forward(world.model, world.data)
    substeps = round(CONTROL_DT / dt)
    steps = round(DURATION / CONTROL_DT)
    record = np.empty((steps, 2, 4)) if commands is None else commands
    poses = []
    for k in range(steps):
        if commands is None:
            record[k] = script(k * CONTROL_DT, world.poses())
        world.set_wheel_speeds(*record[k])
        world.step(substeps)
        poses.append(world.poses())
    return np.array(poses), record


def _parse_seconds(text: str) -> float:
    """A timestep written as a decimal (``0.005``) or a fraction (``1/120``)."""
    num, _, den = text.strip().partition("/")
    return float(num) / float(den) if den else float(num)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--candidates",
        default="0.002,0.0025,0.004,0.005,0.00625,1/150,1/140,1/130,1/120,1/110,0.01,0.0125,0.02",
        help="comma-separated timesteps in s (fractions like 1/120 allowed); each must divide "
        "the 0.1 s control step",
    )
    args = parser.parse_args(argv)
    candidates = [_parse_seconds(x) for x in args.candidates.split(",")]
    for dt in candidates:
        if abs(CONTROL_DT / dt - round(CONTROL_DT / dt)) > 1e-9:
            parser.error(f"candidate {dt} does not divide the {CONTROL_DT} s control step")
    print(f"{'dt (s)':>8} {'ref dt':>8} {'max pos err (m)':>16} {'final yaw err (deg)':>20} pass")
    passing = []
    for dt in candidates:
        fine, commands = trajectory(dt / 5)
        coarse, _ = trajectory(dt, commands)
        err = np.max(np.hypot(*(coarse[..., :2] - fine[..., :2]).transpose(2, 0, 1)))
        yaw_err = np.max(
            np.abs(np.remainder(coarse[-1, :, 2] - fine[-1, :, 2] + math.pi, 2 * math.pi) - math.pi)
        )
        ok = err < TOLERANCE
        if ok:
            passing.append(dt)
        print(
            f"{dt:8.5f} {dt / 5:8.5f} {err:16.5f} {math.degrees(yaw_err):20.3f} "
            f"{'yes' if ok else 'NO'}"
        )
        extent = np.abs(fine[..., :2]).max()
        assert extent < 1.0, "script drove a robot into a wall; the study must be collision-free"
        gaps = [
            np.hypot(*(fine[:, a, :2] - fine[:, b, :2]).T).min()
            for a in range(4)
            for b in range(a + 1, 4)
        ]
        assert min(gaps) > 0.3, "script drove robots into each other"
    best = max(passing) if passing else None
    print(f"largest passing timestep: {best} s (WorldConfig default: {WorldConfig().timestep} s)")


if __name__ == "__main__":
    main()
