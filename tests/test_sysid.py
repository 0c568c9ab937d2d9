"""System identification: the run log's checks, the fitted profile, the noise fits."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from cyber_rodent.profiles import (
    FittedActuators,
    FittedProfile,
    HardwareProfile,
    RangeNoise,
    load_profile,
    profile_from_arg,
    save_profile,
)
from cyber_rodent.robot_step import LOG_MARK
from cyber_rodent.sysid.fit import fit_camera, fit_ir, ir_negative_log_likelihood
from cyber_rodent.sysid.log import read_log, write_log


def _table(n: int = 5) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "step": np.arange(n),
            "t": 0.2 * np.arange(n),
            "robot": np.zeros(n, dtype=int),
            "cmd_left": np.full(n, 0.2),
            "cmd_right": np.full(n, 0.2),
            "tracked": np.ones(n),
            "x": np.zeros(n),
            "y": np.zeros(n),
            "yaw": np.zeros(n),
        }
    )


def _write(tmp_path: Path, table: pd.DataFrame) -> Path:
    return write_log(tmp_path / "log.csv", table, 2.3, np.zeros((0, 2)))


def test_log_round_trip(tmp_path: Path) -> None:
    log = read_log(_write(tmp_path, _table()))
    assert log.groups == ("base", "tracker")
    assert log.robots == (0,)
    assert len(log.of_robot(0)) == 5


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda t: t.drop(columns="cmd_left"), "missing column cmd_left"),
        (lambda t: t.drop(columns="yaw"), "missing column yaw (group tracker"),
        (lambda t: t.assign(t=[0.0, 0.2, 0.1, 0.6, 0.8]), "column t, row 3: must increase"),
        (
            lambda t: t.assign(cmd_right=[0.2, math.nan, 0.2, 0.2, 0.2]),
            "column cmd_right, row 2: NaN",
        ),
        (
            lambda t: t.assign(cmd_left=[0.2, 0.2, 0.2, 0.2, 9.0]),
            "column cmd_left, row 5: out of range",
        ),
        (lambda t: t.assign(x=[0.0, 0.0, math.nan, 0.0, 0.0]), "column x, row 3: NaN"),
    ],
)
def test_bad_log_names_column_and_row(tmp_path: Path, change, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ValueError) as err:
        read_log(_write(tmp_path, change(_table())))
    assert message in str(err.value)
    assert "\n" not in str(err.value)


def test_dropped_tracker_frame_may_be_empty(tmp_path: Path) -> None:
    table = _table().assign(tracked=[1, 1, 0, 1, 1], x=[0, 0, math.nan, 0, 0])
    assert read_log(_write(tmp_path, table)).table["tracked"].sum() == 4


def test_not_a_log(tmp_path: Path) -> None:
    path = tmp_path / "x.csv"
    path.write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="not a run log"):
        read_log(path)
    path.write_text(LOG_MARK + '{"version": 2}\nstep\n1\n')
    with pytest.raises(ValueError, match="version must be 1"):
        read_log(path)


def test_fitted_actuators_sample_and_draw() -> None:
    a = FittedActuators(
        wheel_gain=((0.9, 1.1), (0.7, 0.8)), wheel_gain_sd=((0.0, 0.0), (0.0, 0.0)),
        friction_scale=(1.0, 1.2), friction_scale_sd=(0.0, 0.0),
        motor_lag=(0.06, 0.1), motor_lag_sd=(0.0, 0.0),
    )  # fmt: skip
    gain, friction, lag = a.sample(2, np.random.default_rng(0))
    assert sorted(lag.tolist()) == [0.06, 0.1]  # each fitted robot once
    assert a.drawn(np.random.default_rng(0)).wheel_gain == a.wheel_gain  # zero sd: unchanged
    with pytest.raises(ValueError, match="one entry per fitted robot"):
        FittedActuators(wheel_gain=((1.0, 1.0),), motor_lag=(0.05, 0.06))
    with pytest.raises(ValueError, match=r"actuators.wheel_gain\[0\]\[1\]"):
        FittedActuators(wheel_gain=((1.0, 9.0),))


def test_fitted_profile_file_round_trip_and_randomisation(tmp_path: Path) -> None:
    profile = FittedProfile(
        range_noise=RangeNoise(std=0.01, dropout=0.03),
        uncertainty=(("range_noise.std", 0.002),),
    )
    path = save_profile(tmp_path / "p.json", profile, {"logs": []})
    assert load_profile(path) == profile
    assert profile_from_arg(str(path)) == profile
    assert profile_from_arg("sim") is None and profile_from_arg("hardware") == HardwareProfile()
    with pytest.raises(ValueError, match="--profile must be one of sim, hardware or a profile"):
        profile_from_arg(str(tmp_path / "missing.json"))
    draws = [profile.randomised(np.random.default_rng(s)).range_noise.std for s in range(200)]
    assert abs(np.mean(draws) - 0.01) < 0.001 and 0.0015 < np.std(draws) < 0.0025
    assert profile.randomised(np.random.default_rng(1)) == profile.randomised(
        np.random.default_rng(1)
    )


def test_hardware_profile_randomisation_unchanged() -> None:
    """The hand-set profile's domain randomisation draws as it always did."""
    from cyber_rodent.profiles import randomised

    r = randomised(HardwareProfile(), np.random.default_rng(3))
    u = np.random.default_rng(3).random(8)
    assert r.range_noise.std == pytest.approx(0.02 * u[0])
    assert r.actuators.weak_gain == pytest.approx(1 - 0.3 * u[7])


def test_ir_likelihood_hand_computed() -> None:
    # one in-range reading 0.1 m off at std 0.1: -log((1 - p) phi(1) / std)
    nll = ir_negative_log_likelihood(0.1, 0.2, np.array([0.6]), np.array([0.5]), np.array([1.0]))
    assert nll == pytest.approx(-math.log(0.8 * math.exp(-0.5) / math.sqrt(2 * math.pi) / 0.1))
    # a saturated reading: p + (1 - p) P(noise > top - sim), here P = 0.5
    nll = ir_negative_log_likelihood(0.1, 0.2, np.array([1.0]), np.array([1.0]), np.array([1.0]))
    assert nll == pytest.approx(-math.log(0.2 + 0.8 * 0.5))


def test_ir_and_camera_fits_recover_known_noise() -> None:
    rng = np.random.default_rng(7)
    sim = rng.uniform(0.05, 0.9, size=(4000, 8))
    top = np.ones_like(sim)
    obs = np.clip(sim + rng.normal(0, 0.03, sim.shape), 0, 1)
    obs[rng.random(sim.shape) < 0.05] = 1.0
    std, dropout = fit_ir(obs, sim, top)
    assert std == pytest.approx(0.03, rel=0.03) and dropout == pytest.approx(0.05, abs=0.005)
    seen = rng.random(5000) >= 0.1
    bearing = np.where(seen, rng.normal(0, math.radians(4), 5000), np.nan)
    ratio = np.where(seen, rng.normal(0, 0.1, 5000), np.nan)
    b, d, miss = fit_camera(seen, bearing, ratio)
    assert b == pytest.approx(4, rel=0.05) and d == pytest.approx(0.1, rel=0.05)
    assert miss == pytest.approx(0.1, abs=0.01)


@pytest.fixture(scope="module")
def short_log(tmp_path_factory):  # type: ignore[no-untyped-def]
    """A 24 s log of hidden robot 101 (the fit's development seed), and its hidden values."""
    from cyber_rodent.sysid.synthetic import LogFaults, simulate_log, true_robot

    truth = true_robot(101, n_robots=2)
    faults = LogFaults(encoder_std=0.02, encoder_glitch=0.0, tracker_std=0.005,
                       tracker_yaw_std_deg=2.0, substep_jitter=0, clock_std=0.0)  # fmt: skip
    table, field, packs = simulate_log(truth, 24.0, seed=5, faults=faults)
    path = write_log(tmp_path_factory.mktemp("log") / "log.csv", table, field, packs)
    return read_log(path), truth, faults


def test_log_noise_reads_the_encoder_and_tracker_noise_off_the_residuals(short_log) -> None:  # type: ignore[no-untyped-def]
    from cyber_rodent.sysid.errors import log_noise
    from cyber_rodent.sysid.replay import Replayer, segments

    log, truth, faults = short_log
    per_robot = {r: [(0, s) for s in segments(log, 4.0) if s.robot == r] for r in log.robots}
    noise = log_noise([Replayer(log)], per_robot, dict(enumerate(truth.drives)))
    assert noise.encoder_std == pytest.approx(faults.encoder_std, rel=0.15)
    assert noise.tracker_std == pytest.approx(faults.tracker_std, rel=0.15)
    yaw_deg = math.degrees(noise.tracker_yaw_std)
    assert yaw_deg == pytest.approx(faults.tracker_yaw_std_deg, rel=0.15)
    assert noise.glitch_rate < 0.01


def test_a_noiseless_replicate_with_the_true_drives_follows_the_log(short_log) -> None:  # type: ignore[no-untyped-def]
    """Re-simulated from the logged start of each 4 s segment with the hidden drives and no
    noise, the replicate's poses stay within the log's tracker noise plus a little drift, and
    its time stamps, commands and dropped frames are the log's."""
    from cyber_rodent.sysid.errors import LogNoise, replicate
    from cyber_rodent.sysid.replay import segments

    log, truth, faults = short_log
    starts = {(s.robot, int(s.rows["step"].iloc[0])) for s in segments(log, 4.0)}
    rep = replicate(log, dict(enumerate(truth.drives)), truth.range_noise, truth.vision,
                    LogNoise(), starts, np.random.default_rng(0))  # fmt: skip
    a, b = log.table, rep.table
    for column in ("t", "step", "robot", "cmd_left", "cmd_right", "tracked", "led"):
        assert np.array_equal(a[column].to_numpy(), b[column].to_numpy()), column
    tracked = a["tracked"].to_numpy(dtype=bool)
    error = np.hypot(*(a.loc[tracked, c].to_numpy() - b.loc[tracked, c].to_numpy() for c in "xy"))
    assert np.median(error) < 3 * faults.tracker_std and np.quantile(error, 0.9) < 0.03
    assert np.isnan(b.loc[~tracked, "x"]).all()
    wheel = np.abs(a["wheel_left"].to_numpy() - b["wheel_left"].to_numpy())
    assert np.median(wheel) < 2 * faults.encoder_std


@pytest.mark.slow
def test_sysid_end_to_end_reports_every_error_part(short_log) -> None:  # type: ignore[no-untyped-def]
    from cyber_rodent.sysid.fit import SysidConfig, sysid

    log, truth, _ = short_log
    config = SysidConfig(segment_s=6.0, bootstrap=2, max_evals=40, bootstrap_evals=5,
                         replicates=2)  # fmt: skip
    result = sysid([log], config)
    assert set(result.parameters) == set(truth.parameters())
    for name, (_, se) in result.parameters.items():
        e = result.errors[name]
        assert e.replicates == 2
        assert se == pytest.approx(math.sqrt(e.segment_sd**2 + e.replicate_sd**2
                                             + e.replicate_bias**2))  # fmt: skip
    assert result.profile.actuators is not None
    assert result.profile.actuators.wheel_gain_sd[0][0] == result.parameters["robot0.gain_left"][1]


def test_clock_noise_is_the_spread_of_one_steps_stamps(tmp_path: Path) -> None:
    """Three robots stamp each step with independent N(0, 4 ms) errors about a shared time: the
    spread about each step's median, times sqrt(3/2), reads 4 ms back; one robot reads none."""
    from cyber_rodent.sysid.errors import clock_noise
    from cyber_rodent.sysid.replay import Replayer

    rng = np.random.default_rng(3)
    steps = 600
    parts = []
    for robot in range(3):
        t = _table(steps)
        t["robot"] = robot
        t["t"] = 1.0 + 0.2 * np.arange(steps) + rng.normal(0, 0.004, steps)
        parts.append(t)
    log = read_log(_write(tmp_path, pd.concat(parts, ignore_index=True)))
    assert clock_noise([Replayer(log)]) == pytest.approx(0.004, rel=0.1)
    single = read_log(write_log(tmp_path / "one.csv", parts[0], 2.3, np.zeros((0, 2))))
    assert clock_noise([Replayer(single)]) == 0.0


class _TwoBasins:
    """A replayer whose one wheel-speed residual is sqrt(E) for a drive error E with a shallow
    basin (E = 1) at the model's gains and a long lag, and the truth (E = 0) in a narrower
    basin at weak gains and a shorter lag, between the scan's points."""

    shallow = np.array([1.0, 1.0, 0.4, 1.0])
    deep = np.array([0.7, 0.7, 0.2, 1.0])

    def error(self, drive: np.ndarray) -> float:
        wide = np.sum(((drive - self.shallow) / np.array([0.6, 0.6, 0.3, 1.0])) ** 2)
        narrow = np.sum(((drive - self.deep) / np.array([0.15, 0.15, 0.1, 0.5])) ** 2)
        return float(min(1.0 + wide, narrow))

    def run(self, segment: object, drive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        speeds = np.array([[0.0, 0.0], [math.sqrt(self.error(drive)) * 0.02, 0.0]])
        return speeds, np.zeros((2, 3))


def test_fit_drive_searches_from_several_scanned_starts() -> None:
    """Hand-built: the best scanned start, gains 1.0 and lag 0.4 s (E = 1), lies in the shallow
    basin; the next are the truth's four neighbours (gains 0.6 or 0.8, lag 0.15 or 0.25 s:
    E = 2 (0.1 / 0.15)² + (0.05 / 0.1)² = 1.14). One search stays in the shallow basin; three
    find the truth."""
    from types import SimpleNamespace

    from cyber_rodent.sysid.fit import SysidConfig, fit_drive

    landscape = _TwoBasins()
    zeros = pd.DataFrame({"wheel_left": [0.0, 0.0], "wheel_right": [0.0, 0.0]})
    segs = [(0, SimpleNamespace(rows=zeros))]
    one = fit_drive([landscape], segs, SysidConfig(starts=1))  # type: ignore[list-item,arg-type]
    three = fit_drive([landscape], segs, SysidConfig(starts=3))  # type: ignore[list-item,arg-type]
    neighbour = 2 * (0.1 / 0.15) ** 2 + (0.05 / 0.1) ** 2
    assert landscape.error(np.array([0.8, 0.8, 0.15, 1.0])) == pytest.approx(neighbour)
    assert np.allclose(one, landscape.shallow, atol=0.02)
    assert landscape.error(one) == pytest.approx(1.0, abs=1e-3)
    assert np.allclose(three, landscape.deep, atol=0.02)
    assert landscape.error(three) < 1e-3
