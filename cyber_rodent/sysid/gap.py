"""The reality gap: how far a profile's simulation is from the logs, sensor by sensor.

On the held-out segments (:meth:`~cyber_rodent.sysid.fit.SysidConfig.held_out`; every segment
of a log the fit never saw):

* ``pose_<h>s``: position divergence (m) of the replay from the tracker at horizon ``h`` s after
  a segment's start (the row nearest ``t0 + h``; untracked rows skipped);
* ``wheel``: |simulated - logged| wheel speed, m/s, per row;
* ``ir``, ``cam_bearing``, ``cam_distance``: the 1-Wasserstein distance between the logged
  residuals (logged minus the posed world's noise-free value) and the residuals the profile's
  noise model predicts for the same readings (one draw, fixed seed): 0 when the noise model
  matches the robot in distribution; ``cam_miss``: |logged - predicted| miss rate.

A profile's drive is its fitted robot's values (:class:`~cyber_rodent.profiles.FittedActuators`)
or, for any other profile, the model as built.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import stats

from cyber_rodent.profiles import FittedActuators, HardwareProfile, RangeNoise, RangeSensorNoise
from cyber_rodent.sysid.fit import SysidConfig, sensor_samples
from cyber_rodent.sysid.log import RunLog
from cyber_rodent.sysid.replay import NOMINAL_DRIVE, Replayer, segments

#: Horizons of the pose divergence, s.
HORIZONS = (1.0, 2.0, 5.0, 10.0)


def drive_of(profile: HardwareProfile | None, robot: int) -> np.ndarray:
    """The drive a profile gives logged robot ``robot`` (module docstring)."""
    a = profile.actuators if profile is not None else None
    if isinstance(a, FittedActuators) and a.enabled:
        k = robot % a.n_fitted
        g = a.wheel_gain[k]
        return np.array([g[0], g[1], a.motor_lag[k], a.friction_scale[k]])
    return NOMINAL_DRIVE.copy()


def gap_samples(
    logs: list[RunLog], profile: HardwareProfile | None, config: SysidConfig, all_segments: bool
) -> dict[str, np.ndarray]:
    """Per-metric error samples of ``profile`` on the held-out segments (all segments with
    ``all_segments``)."""
    out: dict[str, list[float]] = {f"pose_{h:g}s": [] for h in HORIZONS}
    out["wheel"] = []
    keep: set[tuple[int, int, int]] = set()
    for li, log in enumerate(logs):
        replayer = Replayer(log)
        robots = list(log.robots)
        for s in segments(log, config.segment_s):
            if not (all_segments or config.held_out(s)):
                continue
            keep.add((li, s.robot, s.index))
            speeds, poses = replayer.run(s, drive_of(profile, robots.index(s.robot)))
            rows = s.rows
            if "wheel_left" in rows:
                logged = rows[["wheel_left", "wheel_right"]].to_numpy(dtype=float)
                out["wheel"] += list(np.abs(speeds[1:] - logged[1:]).ravel())
            if "tracked" in rows:
                t = rows["t"].to_numpy(dtype=float) - float(rows["t"].iloc[0])
                tracked = rows["tracked"].to_numpy(dtype=bool)
                xy = rows[["x", "y"]].to_numpy(dtype=float)
                for h in HORIZONS:
                    k = int(np.argmin(np.abs(t - h)))
                    if abs(t[k] - h) < 0.15 and tracked[k] and tracked[0]:
                        out[f"pose_{h:g}s"].append(float(np.hypot(*(poses[k, :2] - xy[k]))))
    sensors = sensor_samples(logs, config, keep)
    rng = np.random.default_rng(0)
    noise = profile.range_noise if profile is not None else RangeNoise(enabled=False)
    predicted_ir = RangeSensorNoise(noise, sensors.ir_max, rng).apply(sensors.ir_sim.copy())
    out["ir_observed"] = list((sensors.ir_obs - sensors.ir_sim).ravel())
    out["ir_predicted"] = list((predicted_ir - sensors.ir_sim).ravel())
    vision = profile.vision.noise() if profile is not None and profile.vision.enabled else None
    seen = sensors.cam_seen
    n = int(seen.sum())
    b_sd = math.radians(vision.bearing_std_deg) if vision else 0.0
    d_sd = vision.distance_rel_std if vision else 0.0
    out["cam_bearing_observed"] = list(np.degrees(sensors.cam_bearing[seen]))
    out["cam_bearing_predicted"] = list(np.degrees(rng.normal(0, b_sd, n)))
    out["cam_distance_observed"] = list(sensors.cam_ratio[seen])
    out["cam_distance_predicted"] = list(rng.normal(0, d_sd, n))
    out["cam_miss_observed"] = [float(1 - seen.mean())] if len(seen) else []
    out["cam_miss_predicted"] = [vision.dropout if vision else 0.0]
    return {k: np.asarray(v, dtype=float) for k, v in out.items()}


def gap_table(samples: dict[str, dict[str, np.ndarray]]) -> pd.DataFrame:
    """One row per metric and profile label: median, 90th percentile (errors) or the
    distance between observed and predicted distributions (sensor noise)."""
    rows = []
    for label, s in samples.items():
        for h in HORIZONS:
            v = s[f"pose_{h:g}s"]
            rows.append((label, f"pose_{h:g}s", "m", len(v), *_quantiles(v)))
        v = s["wheel"]
        rows.append((label, "wheel", "m/s", len(v), *_quantiles(v)))
        for name, unit in (("ir", "m"), ("cam_bearing", "deg"), ("cam_distance", "relative")):
            obs, pred = s[f"{name}_observed"], s[f"{name}_predicted"]
            w = stats.wasserstein_distance(obs, pred) if len(obs) and len(pred) else math.nan
            rows.append((label, f"{name}_w1", unit, len(obs), w, math.nan))
        miss = abs(s["cam_miss_observed"][0] - s["cam_miss_predicted"][0]) if len(
            s["cam_miss_observed"]) else math.nan  # fmt: skip
        rows.append((label, "cam_miss_abs_error", "probability", 1, miss, math.nan))
    return pd.DataFrame(rows, columns=["profile", "metric", "unit", "n", "median_or_value", "p90"])


def _quantiles(v: np.ndarray) -> tuple[float, float]:
    if not len(v):
        return math.nan, math.nan
    return float(np.median(v)), float(np.quantile(v, 0.9))


def gap_figure(samples: dict[str, dict[str, np.ndarray]], path: str, title: str = "") -> None:
    """Pose divergence against horizon, wheel speed error and the IR and camera residuals,
    each profile against the logs, as one PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cyber_rodent.atomic import atomic_output

    fig, ax = plt.subplots(1, 4, figsize=(17, 4))
    colours = ("tab:red", "tab:blue", "tab:green")
    for (label, s), colour in zip(samples.items(), colours, strict=False):
        med = [np.median(s[f"pose_{h:g}s"]) if len(s[f"pose_{h:g}s"]) else np.nan for h in HORIZONS]
        q90 = [
            np.quantile(s[f"pose_{h:g}s"], 0.9) if len(s[f"pose_{h:g}s"]) else np.nan
            for h in HORIZONS
        ]
        ax[0].plot(HORIZONS, med, "o-", color=colour, label=f"{label}: median")
        ax[0].plot(HORIZONS, q90, "o--", color=colour, alpha=0.6, label=f"{label}: 90th pct")
        w = np.sort(s["wheel"])
        ax[1].plot(w, np.linspace(0, 1, len(w)), color=colour, label=label)
        bins = np.linspace(-0.15, 0.15, 61)
        ax[2].hist(np.clip(s["ir_predicted"], -0.15, 0.15), bins, histtype="step", color=colour,
                   density=True, label=f"{label} model")  # fmt: skip
        bins_b = np.linspace(-25, 25, 51)
        ax[3].hist(np.clip(s["cam_bearing_predicted"], -25, 25), bins_b, histtype="step",
                   color=colour, density=True, label=f"{label} model")  # fmt: skip
    first = next(iter(samples.values()))
    ax[2].hist(np.clip(first["ir_observed"], -0.15, 0.15), np.linspace(-0.15, 0.15, 61),
               color="grey", alpha=0.5, density=True, label="log")  # fmt: skip
    ax[3].hist(np.clip(first["cam_bearing_observed"], -25, 25), np.linspace(-25, 25, 51),
               color="grey", alpha=0.5, density=True, label="log")  # fmt: skip
    ax[0].set(xlabel="horizon (s)", ylabel="position divergence (m)", title="pose, held-out")
    ax[1].set(xlabel="|wheel speed error| (m/s)", ylabel="CDF", title="encoders, held-out",
              xscale="log")  # fmt: skip
    ax[2].set(xlabel="IR reading - noise-free (m, clipped ±0.15)", ylabel="density",
              title="IR residuals", yscale="log")  # fmt: skip
    ax[3].set(xlabel="bearing - noise-free (deg)", ylabel="density", title="camera bearing")
    for a in ax:
        a.legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    with atomic_output(path) as temp:
        fig.savefig(temp, dpi=110)
    plt.close(fig)


__all__ = ["HORIZONS", "drive_of", "gap_figure", "gap_samples", "gap_table"]
