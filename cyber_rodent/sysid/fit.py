"""Fit a :class:`~cyber_rodent.profiles.FittedProfile` to run logs (``cyber-rodent sysid``).

* **Drive**, per robot: wheel gains (left, right), motor lag and friction factor minimise the
  replay's error (:mod:`~cyber_rodent.sysid.replay`): wheel speeds (encoders, scaled by
  ``wheel_sd``) and poses (tracker, ``pose_sd`` and ``yaw_sd_deg``) of every row after a
  segment's first, summed under a soft-L1 loss (``2 (sqrt(1 + (r/2)^2) - 1)``), so encoder
  glitches and collisions with robots the replay lacks weigh little, by scipy's bounded
  Nelder-Mead (derivative-free: contacts make the replay's error non-smooth, and a
  finite-difference trust-region method stalled at its start), from the best few of a scan
  of gains and motor lags (:func:`fit_drive`). Dropped tracker frames contribute nothing.
* **IR noise**: at every step where every robot's pose is known, the world is posed as logged
  and the noise-free readings computed; std and dropout maximise the likelihood of the logged
  readings under the profile's model (Gaussian, clipped to [0, range], a dropout reads the full
  range), by ``scipy.optimize.minimize`` (L-BFGS-B).
* **Camera noise**: at the same steps, for each robot and class with exactly one target in view,
  the miss rate is the share of them the log did not see (the binomial maximum likelihood);
  bearing and relative distance noise are the Gaussian std from the median absolute deviation
  of the logged minus simulated values (robust to a target the log saw but the posed world
  does not).

Uncertainty (:class:`ParameterError`): every parameter is refitted on ``bootstrap`` resamples
(with replacement) of the fitting segments (their standard deviation: how much the fit moves
with the segments), and on ``replicates`` re-simulations of the logs with the fitted values
(:mod:`~cyber_rodent.sysid.errors`: their spread and their bias about the fitted values, which
the segment bootstrap cannot see). The standard error reported combines the three. Segments numbered
``holdout_every - 1``, ``2 holdout_every - 1``, ... of each robot are held out: never fitted,
left for ``cyber-rodent gap``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats

from cyber_rodent.profiles import (
    FieldLayout,
    FittedActuators,
    FittedProfile,
    RangeNoise,
    VisionUncertainty,
)
from cyber_rodent.sysid.errors import MAD_TO_SD, log_noise, replicate
from cyber_rodent.sysid.log import CAMERA_CLASSES, RunLog, wrap_angle
from cyber_rodent.sysid.replay import DRIVE_NAMES, NOMINAL_DRIVE, Replayer, Segment, segments
from cyber_rodent.validation import integer, number, validate_fields
from cyber_rodent.vision import CameraConfig
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.world import World, WorldConfig

DRIVE_LOW = np.array([0.1, 0.1, 0.005, 0.05])
DRIVE_HIGH = np.array([3.0, 3.0, 0.5, 5.0])
DRIVE_SCALE = np.array([0.1, 0.1, 0.02, 0.3])
#: Both wheels' gains and the motor lags (s) whose pairs a fresh fit scans for the starts of
#: its searches (:func:`fit_drive`).
GAIN_SCAN = (0.6, 0.8, 1.0, 1.2)
LAG_SCAN = (0.02, 0.05, 0.1, 0.15, 0.25, 0.4)
#: Residuals (in units of their scales) beyond which the loss grows linearly, not squared.
SOFT_L1_SCALE = 2.0
#: The camera's fitted values, by the names the fit reports them under.
CAMERA_NAMES = ("vision.bearing_std_deg", "vision.distance_rel_std", "vision.dropout")


@dataclass(frozen=True)
class SysidConfig:
    """How ``cyber-rodent sysid`` fits (and ``gap`` splits) a log.

    Attributes:
        segment_s: s, length of a log segment (the unit of replay, bootstrap and hold-out);
            default 10 (the gap report's longest horizon).
        holdout_every: every this many segments of a robot, one is held out (0: none);
            default 4.
        bootstrap: bootstrap resamples for the uncertainties; default 20.
        seed: seed of the bootstrap's resampling; default 0.
        wheel_sd: m/s, scale of a wheel-speed residual (about the encoders' noise); default 0.02.
        pose_sd: m, scale of a position residual; default 0.02.
        yaw_sd_deg: degrees, scale of a heading residual; default 3.
        max_evals: replays allowed to each search of a full fit of one robot; default 200.
        bootstrap_evals: replays allowed to each bootstrap refit (warm-started); default 30.
        starts: a fresh fit searches from this many of the best scanned starts
            (:func:`fit_drive`), each with ``max_evals`` replays; default 3.
        replicates: re-simulated replicates of the logs for the error model
            (:mod:`~cyber_rodent.sysid.errors`; 0: the segment bootstrap alone); default 8.
    """

    segment_s: float = number(10.0, 1.0, 120.0, unit="s")
    holdout_every: int = integer(4, 0, 1000)
    bootstrap: int = integer(20, 2, 10_000)
    seed: int = integer(0, 0)
    wheel_sd: float = number(0.02, 1e-4, 10.0, unit="m/s")
    pose_sd: float = number(0.02, 1e-4, 10.0, unit="m")
    yaw_sd_deg: float = number(3.0, 0.01, 180.0, unit="deg")
    max_evals: int = integer(200, 5, 100_000)
    bootstrap_evals: int = integer(30, 2, 100_000)
    starts: int = integer(3, 1, len(GAIN_SCAN) * len(LAG_SCAN))
    replicates: int = integer(8, 0, 10_000)

    def __post_init__(self) -> None:
        validate_fields(self, "sysid.")

    def held_out(self, segment: Segment) -> bool:
        """Is ``segment`` held out of the fit?"""
        k = self.holdout_every
        return k > 0 and segment.index % k == k - 1


@dataclass(frozen=True)
class ParameterError:
    """One fitted value's error estimate.

    Attributes:
        segment_sd: the standard deviation of its refits over resampled log segments.
        replicate_sd: the standard deviation of its refits on the re-simulated replicates.
        replicate_bias: their mean minus the fitted value.
        replicates: how many replicates it was refitted on.
    """

    segment_sd: float
    replicate_sd: float
    replicate_bias: float
    replicates: int

    @property
    def total(self) -> float:
        """The reported standard error: ``sqrt(segment_sd² + replicate_sd² + replicate_bias²)``."""
        return math.sqrt(self.segment_sd**2 + self.replicate_sd**2 + self.replicate_bias**2)


@dataclass
class SysidResult:
    """What a fit found.

    Attributes:
        profile: the fitted profile.
        parameters: name -> (value, standard error: :attr:`ParameterError.total`); drive values
            per robot as ``robot<id>.<name>``.
        fitted_segments, held_out: (log, robot, segment) of the segments used and kept out.
        errors: name -> the parts of its standard error.
    """

    profile: FittedProfile
    parameters: dict[str, tuple[float, float]]
    fitted_segments: list[tuple[int, int, int]] = field(default_factory=list)
    held_out: list[tuple[int, int, int]] = field(default_factory=list)
    errors: dict[str, ParameterError] = field(default_factory=dict)


def _segment_residuals(
    replayer: Replayer, segment: Segment, drive: np.ndarray, config: SysidConfig
) -> np.ndarray:
    speeds, poses = replayer.run(segment, drive)
    rows = segment.rows
    parts = []
    if "wheel_left" in rows:
        logged = rows[["wheel_left", "wheel_right"]].to_numpy(dtype=float)
        parts.append(((speeds[1:] - logged[1:]) / config.wheel_sd).ravel())
    if "tracked" in rows:
        tracked = rows["tracked"].to_numpy(dtype=bool)[1:, None]
        xy = rows[["x", "y"]].to_numpy(dtype=float)[1:]
        yaw = rows["yaw"].to_numpy(dtype=float)[1:]
        pos = np.where(tracked, (poses[1:, :2] - xy) / config.pose_sd, 0.0)
        ang = np.where(tracked[:, 0], wrap_angle(poses[1:, 2] - yaw), 0.0)
        parts += [pos.ravel(), ang / math.radians(config.yaw_sd_deg)]
    return np.concatenate(parts) if parts else np.zeros(0)


def fit_drive(
    replayers: list[Replayer],
    segs: list[tuple[int, Segment]],
    config: SysidConfig,
    start: np.ndarray = NOMINAL_DRIVE,
    max_evals: int | None = None,
    counts: np.ndarray | None = None,
    step: float = 1.0,
    scan: bool = True,
) -> np.ndarray:
    """One robot's drive minimising the replay residuals of ``segs`` ((log index, segment)
    pairs; ``counts``: how often each one counts, for the bootstrap), from ``start`` with an
    initial simplex of ``step`` x :data:`DRIVE_SCALE` (a bootstrap refit starts at the fit
    with a small one: a large first simplex whose vertices all cost more returns the start
    itself, and a standard error of zero). With ``scan``, it searches instead from each of the
    ``config.starts`` best pairs of a gain of :data:`GAIN_SCAN` (both wheels) and a motor lag
    of :data:`LAG_SCAN` (friction as in ``start``), and keeps the best end: the error is not
    convex in the lag, and gain and lag trade off. A search started at the model's 0.05 s
    stayed near it for a robot whose lag was 0.15 s (development robot 101, robot 2), and one
    started at the best lag for the model's gains stayed near 0.4 s for weak robots whose lag
    was 0.17 s (worn true robot 2001: error 3,416 there against 329 at the truth)."""
    counts = np.ones(len(segs), dtype=int) if counts is None else counts
    used = [(i, s, c) for (i, s), c in zip(segs, counts, strict=True) if c > 0]

    def residuals(theta: np.ndarray) -> np.ndarray:
        parts = []
        for i, s, c in used:
            r = _segment_residuals(replayers[i], s, theta, config)
            parts.extend([r] * int(c))
        return np.concatenate(parts)

    def cost(theta: np.ndarray) -> float:
        r = residuals(np.clip(theta, DRIVE_LOW, DRIVE_HIGH))
        return float(np.sum(2.0 * (np.sqrt(1.0 + (r / SOFT_L1_SCALE) ** 2) - 1.0)))

    def search(x0: np.ndarray) -> optimize.OptimizeResult:
        simplex = np.vstack([x0, np.clip(x0 + np.diag(DRIVE_SCALE) * step, DRIVE_LOW, DRIVE_HIGH)])
        return optimize.minimize(
            cost, x0, method="Nelder-Mead", bounds=list(zip(DRIVE_LOW, DRIVE_HIGH, strict=True)),
            options={"maxfev": max_evals or config.max_evals, "initial_simplex": simplex,
                     "xatol": 1e-4, "fatol": 1e-3},
        )  # fmt: skip

    x0 = np.clip(start, DRIVE_LOW, DRIVE_HIGH)
    starts = [x0]
    if scan:
        grid = [np.array([g, g, lag, x0[3]]) for g in GAIN_SCAN for lag in LAG_SCAN]
        starts = sorted(grid, key=cost)[: config.starts]
    best = min((search(x) for x in starts), key=lambda result: float(result.fun))
    return np.asarray(np.clip(best.x, DRIVE_LOW, DRIVE_HIGH))


@dataclass
class SensorSamples:
    """The logged and posed-world sensor values of the steps with every pose known.

    Attributes:
        ir_obs, ir_sim, ir_max: (rows, 8) logged readings, noise-free readings, sensor range.
        ir_block: (rows,) the bootstrap block (log, robot's segment) of each row.
        cam_seen: (k,) the log saw the single target in view; cam_bearing, cam_ratio: (k,)
            logged minus simulated bearing (rad), logged / simulated distance - 1 (NaN where
            not seen); cam_block: (k,) blocks.
    """

    ir_obs: np.ndarray
    ir_sim: np.ndarray
    ir_max: np.ndarray
    ir_block: np.ndarray
    cam_seen: np.ndarray
    cam_bearing: np.ndarray
    cam_ratio: np.ndarray
    cam_block: np.ndarray


def sensor_samples(
    logs: list[RunLog], config: SysidConfig, keep: set[tuple[int, int, int]] | None = None
) -> SensorSamples:
    """Pose a world as each log says at every fully tracked step (rows of segments in
    ``keep`` only, when given) and collect logged vs simulated IR and camera values."""
    ir_obs, ir_sim, ir_max, ir_block = [], [], [], []
    cam_seen, cam_b, cam_r, cam_block = [], [], [], []
    for li, log in enumerate(logs):
        table = log.table
        if "tracked" not in table or ("ir0" not in table and "cam_led_seen" not in table):
            continue
        robots = log.robots
        n = len(robots)
        config_w = WorldConfig(field_size=log.field_size, n_robots=n, n_packs=len(log.packs),
                               pack_gap=0.0, pack_wall_clearance=0.0)  # fmt: skip
        world = World(config_w)
        for j, (x, y) in enumerate(log.packs):
            world.set_pack_position(j, float(x), float(y))
        provider = GeometricVision(world, CameraConfig())
        segment_of = {}
        for s in segments(log, config.segment_s):
            for step in s.rows["step"]:
                segment_of[(s.robot, int(step))] = s.index
        by_step = table.groupby("step")
        for step, rows in by_step:
            if len(rows) != n or not rows["tracked"].all():
                continue
            rows = rows.set_index("robot").loc[list(robots)]
            for i, (x, y, yaw) in enumerate(rows[["x", "y", "yaw"]].to_numpy(dtype=float)):
                world.set_robot_pose(i, x, y, yaw)
            if "led" in rows:
                world.set_led(rows["led"].to_numpy(dtype=bool))
            import mujoco

            mujoco.mj_forward(world.model, world.data)
            targets = provider.measure_targets() if "cam_led_seen" in rows else None
            ranges = world.range_readings() if "ir0" in rows else None
            for i, robot in enumerate(robots):
                seg = segment_of.get((robot, int(step)))
                if seg is None or (keep is not None and (li, robot, seg) not in keep):
                    continue
                block = li * 1_000_000 + robot * 10_000 + seg
                row = rows.iloc[i]
                if ranges is not None:
                    ir_obs.append(row[[f"ir{k}" for k in range(8)]].to_numpy(dtype=float))
                    ir_sim.append(ranges[i].copy())
                    ir_max.append(world.range_max[i])
                    ir_block.append(block)
                if targets is not None:
                    for c, name in enumerate(CAMERA_CLASSES):
                        inview = np.flatnonzero(targets.visible[i] & (provider.target_cls == c))
                        if len(inview) != 1:
                            continue
                        t = inview[0]
                        seen = bool(row[f"cam_{name}_seen"])
                        cam_seen.append(seen)
                        cam_block.append(block)
                        if seen:
                            cam_b.append(
                                float(
                                    wrap_angle(row[f"cam_{name}_bearing"] - targets.bearing[i, t])
                                )
                            )
                            cam_r.append(
                                float(row[f"cam_{name}_distance"] / targets.distance[i, t] - 1.0)
                            )
                        else:
                            cam_b.append(math.nan)
                            cam_r.append(math.nan)

    def arr(x: list, width: int = 0) -> np.ndarray:  # type: ignore[type-arg]
        return np.asarray(x, dtype=float).reshape((-1, width) if width else (-1,))

    return SensorSamples(
        arr(ir_obs, 8), arr(ir_sim, 8), arr(ir_max, 8), np.asarray(ir_block, dtype=np.int64),
        np.asarray(cam_seen, dtype=bool), arr(cam_b), arr(cam_r),
        np.asarray(cam_block, dtype=np.int64),
    )  # fmt: skip


def ir_negative_log_likelihood(
    std: float, dropout: float, obs: np.ndarray, sim: np.ndarray, top: np.ndarray
) -> float:
    """-log L of logged IR readings under :class:`~cyber_rodent.profiles.RangeNoise`: a
    reading is ``clip(sim + N(0, std), 0, top)``, or ``top`` with probability ``dropout``."""
    eps = 1e-12
    at_top = obs >= top - 1e-9
    at_zero = obs <= 1e-9
    mid = ~(at_top | at_zero)
    z = (obs - sim) / std
    ll = np.empty(obs.shape)
    ll[mid] = np.log((1 - dropout) * stats.norm.pdf(z[mid]) / std + eps)
    ll[at_top] = np.log(dropout + (1 - dropout) * stats.norm.sf((top - sim)[at_top] / std) + eps)
    ll[at_zero] = np.log((1 - dropout) * stats.norm.cdf(-sim[at_zero] / std) + eps)
    return float(-ll.sum())


def fit_ir(obs: np.ndarray, sim: np.ndarray, top: np.ndarray) -> tuple[float, float]:
    """IR std (m) and dropout by maximum likelihood (L-BFGS-B on log std, logit dropout)."""

    def nll(u: np.ndarray) -> float:
        return ir_negative_log_likelihood(math.exp(u[0]), 1 / (1 + math.exp(-u[1])), obs, sim, top)

    result = optimize.minimize(nll, np.array([math.log(0.02), -3.0]), method="L-BFGS-B",
                               bounds=[(math.log(1e-4), 0.0), (-12.0, 5.0)])  # fmt: skip
    return math.exp(result.x[0]), 1 / (1 + math.exp(-result.x[1]))


def fit_camera(
    seen: np.ndarray, bearing: np.ndarray, ratio: np.ndarray
) -> tuple[float, float, float]:
    """Camera bearing std (deg), relative distance std and miss rate (module docstring)."""
    if not len(seen):
        return 0.0, 0.0, 0.0
    miss = float(1.0 - seen.mean())
    b, r = bearing[seen], ratio[seen]
    bearing_deg = math.degrees(MAD_TO_SD * float(np.median(np.abs(b)))) if len(b) else 0.0
    rel = MAD_TO_SD * float(np.median(np.abs(r))) if len(r) else 0.0
    return min(bearing_deg, 90.0), min(rel, 1.0), miss


def _resample(blocks: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Row indices of a bootstrap resample of ``blocks`` (whole blocks, with replacement)."""
    unique = np.unique(blocks)
    chosen = rng.choice(unique, size=len(unique), replace=True)
    return np.concatenate([np.flatnonzero(blocks == b) for b in chosen])


SegmentIds = list[tuple[int, int, int]]


def _fitting_segments(
    logs: list[RunLog], config: SysidConfig
) -> tuple[dict[int, list[tuple[int, Segment]]], SegmentIds, SegmentIds]:
    """Each robot's (log index, segment) pairs to fit, and the (log, robot, segment) numbers
    of the segments fitted and held out."""
    robots = sorted({r for log in logs for r in log.robots})
    per_robot: dict[int, list[tuple[int, Segment]]] = {r: [] for r in robots}
    fitted: SegmentIds = []
    held: SegmentIds = []
    for li, log in enumerate(logs):
        for s in segments(log, config.segment_s):
            (held if config.held_out(s) else fitted).append((li, s.robot, s.index))
            if not config.held_out(s):
                per_robot[s.robot].append((li, s))
    for r, segs in per_robot.items():
        if not segs:
            raise ValueError(f"logs: robot {r} has no segment of {config.segment_s:g} s to fit")
    return per_robot, fitted, held


def _sensor_values(samples: SensorSamples) -> dict[str, float]:
    values: dict[str, float] = {}
    if len(samples.ir_obs):
        std, dropout = fit_ir(samples.ir_obs, samples.ir_sim, samples.ir_max)
        values.update({"range_noise.std": std, "range_noise.dropout": dropout})
    if len(samples.cam_seen):
        cam = fit_camera(samples.cam_seen, samples.cam_bearing, samples.cam_ratio)
        values.update(zip(CAMERA_NAMES, cam, strict=True))
    return values


def _sensor_bootstrap(samples: SensorSamples, config: SysidConfig,
                      rng: np.random.Generator) -> dict[str, float]:  # fmt: skip
    """Each sensor value's standard deviation over resamples of the sample blocks."""
    out: dict[str, float] = {}
    if len(samples.ir_obs):
        boot: list[tuple[float, ...]] = []
        for _ in range(config.bootstrap):
            idx = _resample(samples.ir_block, rng)
            boot.append(fit_ir(samples.ir_obs[idx], samples.ir_sim[idx], samples.ir_max[idx]))
        sds = np.std(np.asarray(boot), axis=0, ddof=1)
        out.update({"range_noise.std": float(sds[0]), "range_noise.dropout": float(sds[1])})
    if len(samples.cam_seen):
        boot = []
        for _ in range(config.bootstrap):
            idx = _resample(samples.cam_block, rng)
            boot.append(
                fit_camera(samples.cam_seen[idx], samples.cam_bearing[idx], samples.cam_ratio[idx])
            )
        sds = np.std(np.asarray(boot), axis=0, ddof=1)
        out.update(zip(CAMERA_NAMES, map(float, sds), strict=True))
    return out


def _noise_models(values: dict[str, float]) -> tuple[RangeNoise, VisionUncertainty]:
    range_noise = RangeNoise(enabled=False)
    vision = VisionUncertainty(enabled=False)
    if "range_noise.std" in values:
        range_noise = RangeNoise(std=values["range_noise.std"],
                                 dropout=values["range_noise.dropout"])  # fmt: skip
    if CAMERA_NAMES[0] in values:
        vision = VisionUncertainty(bearing_std_deg=values[CAMERA_NAMES[0]],
                                   distance_rel_std=values[CAMERA_NAMES[1]],
                                   dropout=values[CAMERA_NAMES[2]])  # fmt: skip
    return range_noise, vision


def _drive_values(drives: dict[int, np.ndarray]) -> dict[str, float]:
    return {f"robot{r}.{name}": float(d[k]) for r, d in drives.items()
            for k, name in enumerate(DRIVE_NAMES)}  # fmt: skip


def sysid(logs: list[RunLog], config: SysidConfig | None = None) -> SysidResult:
    """Fit a profile to ``logs`` (see the module docstring).

    Raises:
        ValueError: the logs hold nothing to fit (no encoder or tracker columns).
    """
    config = config or SysidConfig()
    if not any({"encoders", "tracker"} & set(log.groups) for log in logs):
        raise ValueError("logs: no encoders or tracker columns to fit the drive from "
                         "(wheel_left/wheel_right or tracked/x/y/yaw)")  # fmt: skip
    rng = np.random.default_rng(np.random.SeedSequence([config.seed, 0xB007]))
    replayers = [Replayer(log) for log in logs]
    per_robot, fitted, held = _fitting_segments(logs, config)
    drives = {r: fit_drive(replayers, segs, config) for r, segs in per_robot.items()}
    segment_sd: dict[str, float] = {}
    for r, segs in per_robot.items():
        boot = []
        for _ in range(config.bootstrap):
            counts = np.bincount(rng.integers(len(segs), size=len(segs)), minlength=len(segs))
            boot.append(fit_drive(replayers, segs, config, drives[r], config.bootstrap_evals,
                                  counts, 0.1, scan=False))  # fmt: skip
        sd = np.std(np.asarray(boot), axis=0, ddof=1)
        segment_sd.update({f"robot{r}.{n}": float(v) for n, v in zip(DRIVE_NAMES, sd, strict=True)})
    keep = set(fitted)
    samples = sensor_samples(logs, config, keep)
    values = {**_drive_values(drives), **_sensor_values(samples)}
    segment_sd.update(_sensor_bootstrap(samples, config, rng))
    range_noise, vision = _noise_models(values)
    replicate_values = []
    if config.replicates:
        noise = log_noise(replayers, per_robot, drives)
        starts = [{(s.robot, int(s.rows["step"].iloc[0])) for s in segments(log, config.segment_s)}
                  for log in logs]  # fmt: skip
        for k in range(config.replicates):
            rep_rng = np.random.default_rng(np.random.SeedSequence([config.seed, 0xE77, k]))
            rep_logs = [replicate(log, drives, range_noise, vision, noise, starts[li], rep_rng)
                        for li, log in enumerate(logs)]  # fmt: skip
            rep_segs, _, _ = _fitting_segments(rep_logs, config)
            rep_drives = {r: fit_drive(replayers, segs, config) for r, segs in rep_segs.items()}
            rep_samples = sensor_samples(rep_logs, config, keep)
            replicate_values.append({**_drive_values(rep_drives), **_sensor_values(rep_samples)})
    errors: dict[str, ParameterError] = {}
    for name, value in values.items():
        reps = np.array([v[name] for v in replicate_values if name in v])
        spread = float(np.std(reps, ddof=1)) if len(reps) > 1 else 0.0
        bias = float(reps.mean() - value) if len(reps) else 0.0
        errors[name] = ParameterError(segment_sd.get(name, 0.0), spread, bias, len(reps))
    parameters = {name: (value, errors[name].total) for name, value in values.items()}
    d = np.array([drives[r] for r in per_robot])
    sd = np.array([[parameters[f"robot{r}.{n}"][1] for n in DRIVE_NAMES] for r in per_robot])
    actuators = FittedActuators(
        wheel_gain=tuple((float(a), float(b)) for a, b in d[:, :2]),
        wheel_gain_sd=tuple((float(a), float(b)) for a, b in sd[:, :2]),
        friction_scale=tuple(map(float, d[:, 3])),
        friction_scale_sd=tuple(map(float, sd[:, 3])),
        motor_lag=tuple(map(float, d[:, 2])),
        motor_lag_sd=tuple(map(float, sd[:, 2])),
    )
    uncertainty = tuple((name, parameters[name][1]) for name in values
                        if not name.startswith("robot"))  # fmt: skip
    n_packs = max(len(log.packs) for log in logs)
    profile = FittedProfile(
        range_noise=range_noise, vision=vision, actuators=actuators,
        field=FieldLayout(n_robots=len(per_robot), n_packs=n_packs),
        uncertainty=uncertainty,
    )  # fmt: skip
    return SysidResult(profile, parameters, fitted, held, errors)


__all__ = ["ParameterError", "SensorSamples", "SysidConfig", "SysidResult", "fit_camera",
           "fit_drive", "fit_ir", "ir_negative_log_likelihood", "sensor_samples",
           "sysid"]  # fmt: skip
