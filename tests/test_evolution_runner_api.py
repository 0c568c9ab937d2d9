"""The three-line API: ``from evolution.lab import run; table = run(...)``.

Small, fast runs (4 robots x 2 agents, lifetime 80) with the reactive behaviours: results on
disk, resuming, refusing to overwrite, and clear errors for bad input that lose no data.
"""

from __future__ import annotations

import json
import math

import pandas as pd
import pytest

from behaviours import BehaviourPolicies
from evolution.checkpoint import CheckpointError
from evolution.config import EvolutionConfig
from evolution.lab.api import CHECKPOINT_DIR, OVERRIDES, make_config
from evolution.runner import RunConfig

REACTIVE = BehaviourPolicies.reactive()
SMALL = dict(population_size=8, n_robots=4, lifetime_steps=80, time_sharing_steps=40)


def _snapshot(directory) -> dict[str, bytes]:
    return {
        str(p.relative_to(directory)): p.read_bytes() for p in directory.rglob("*") if p.is_file()
    }


def test_three_lines() -> None:
    from evolution.lab import run

    table = run(method="ee", generations=2, seed=0, policies=REACTIVE, **SMALL)
    assert isinstance(table, pd.DataFrame)
    assert list(table["generation"]) == [0, 1]
    assert {"batteries_mean", "matings_mean", "deaths", "random_share", "spare_list_size"} <= set(
        table.columns
    )
    assert (table["method"] == "ee").all() and (table["seed"] == 0).all()


def test_out_dir_holds_statistics_events_run_record_and_checkpoints(tmp_path) -> None:
    from evolution.lab import run

    table = run("ce", 2, 1, out_dir=tmp_path, policies=REACTIVE, **SMALL)
    on_disk = pd.read_csv(tmp_path / "statistics.csv")
    pd.testing.assert_frame_equal(on_disk, table, check_dtype=False)
    events = pd.read_csv(tmp_path / "events.csv")
    assert set(events["kind"]) >= {"birth"}
    assert int((events["kind"] == "birth").sum()) == 16  # two CE replacements of 8
    record = json.loads((tmp_path / "run.json").read_text())
    assert record["seed"] == 1 and record["config"]["method"] == "ce"
    assert record["config"]["evolution"]["population_size"] == 8
    assert record["summary"]["completed_generations"] == 2
    assert record["policies"].startswith("reactive:")
    names = sorted(p.name for p in (tmp_path / CHECKPOINT_DIR).iterdir())
    assert names == ["gen_00001.ckpt", "gen_00002.ckpt"]


def test_resume_continues_bit_identically_and_never_overwrites(tmp_path) -> None:
    from evolution.lab import run

    first = tmp_path / "interrupted"
    run("ee", 1, 5, out_dir=first, policies=REACTIVE, **SMALL)
    before = _snapshot(first)
    # Without resume=True an existing run is refused, and nothing changes on disk.
    with pytest.raises(ValueError, match="already holds a run"):
        run("ee", 3, 5, out_dir=first, policies=REACTIVE, **SMALL)
    assert _snapshot(first) == before
    continued = run("ee", 3, 5, out_dir=first, policies=REACTIVE, resume=True, **SMALL)
    straight = run("ee", 3, 5, out_dir=tmp_path / "straight", policies=REACTIVE, **SMALL)
    pd.testing.assert_frame_equal(continued, straight)
    assert (first / "events.csv").read_bytes() == (
        tmp_path / "straight" / "events.csv"
    ).read_bytes()


def test_resume_keeps_a_finished_run_and_records_the_commits_that_advanced_it(
    tmp_path, monkeypatch
) -> None:
    from evolution.lab import api, run

    monkeypatch.setattr(api, "source_commit", lambda: "old")
    run("ee", 1, 5, out_dir=tmp_path, policies=REACTIVE, **SMALL)
    finished = _snapshot(tmp_path)
    monkeypatch.setattr(api, "source_commit", lambda: "new")
    # Resuming a finished run under other code changes no file: its record keeps "old".
    table = run("ee", 1, 5, out_dir=tmp_path, policies=REACTIVE, resume=True, **SMALL)
    assert _snapshot(tmp_path) == finished
    pd.testing.assert_frame_equal(table, pd.read_csv(tmp_path / "statistics.csv"))
    # Advancing it under "new" records "new", and "old" as the commit before it.
    run("ee", 2, 5, out_dir=tmp_path, policies=REACTIVE, resume=True, **SMALL)
    versions = json.loads((tmp_path / "run.json").read_text())["versions"]
    assert (versions["git_commit"], versions["earlier_commits"]) == ("new", ["old"])
    # A record cut short (the process died before its last write) is written again.
    record = json.loads((tmp_path / "run.json").read_text())
    record["summary"]["completed_generations"] = 1
    (tmp_path / "run.json").write_text(json.dumps(record))
    monkeypatch.setattr(api, "source_commit", lambda: "third")
    run("ee", 2, 5, out_dir=tmp_path, policies=REACTIVE, resume=True, **SMALL)
    record = json.loads((tmp_path / "run.json").read_text())
    assert record["summary"]["completed_generations"] == 2
    assert record["versions"]["earlier_commits"] == ["old", "new"]


def test_resume_with_another_config_or_a_corrupt_checkpoint_loses_nothing(tmp_path) -> None:
    from evolution.lab import run

    run("ee", 2, 0, out_dir=tmp_path, policies=REACTIVE, **SMALL)
    before = _snapshot(tmp_path)
    with pytest.raises(CheckpointError, match="different configuration"):
        run("ee", 3, 1, out_dir=tmp_path, policies=REACTIVE, resume=True, **SMALL)
    with pytest.raises(CheckpointError, match="'evolution-run-ee' run"):
        run("ce", 3, 0, out_dir=tmp_path, policies=REACTIVE, resume=True, **SMALL)
    changed = dict(SMALL, lifetime_steps=60)
    with pytest.raises(CheckpointError, match="different configuration"):
        run("ee", 3, 0, out_dir=tmp_path, policies=REACTIVE, resume=True, **changed)
    assert _snapshot(tmp_path) == before
    newest = tmp_path / CHECKPOINT_DIR / "gen_00002.ckpt"
    data = bytearray(newest.read_bytes())
    data[len(data) // 2] ^= 0x01
    newest.write_bytes(bytes(data))
    corrupt = _snapshot(tmp_path)
    with pytest.raises(CheckpointError, match="corrupt checkpoint"):
        run("ee", 3, 0, out_dir=tmp_path, policies=REACTIVE, resume=True, **SMALL)
    assert _snapshot(tmp_path) == corrupt


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (dict(population_size=10, n_robots=4), r"population_size \(10\) must be divisible"),
        (dict(crossover_probability=1.5), r"crossover_probability must be .* \[0, 1\]"),
        (dict(mutation_probability=-0.1), r"mutation_probability must be .* \[0, 1\]"),
        (dict(time_sharing_steps=500), r"time_sharing_steps must be an integer in \[1, 400\]"),
        (dict(n_packs=-1), r"n_packs must be an integer in \[0,"),
        (dict(lifetime=400), r"unknown config key 'lifetime'; closest: .*evolution.lifetime_steps"),
        (dict(vision="sonar"), "vision must be one of geometric, rendered"),
    ],
)
def test_bad_overrides_get_clear_errors(overrides, message, tmp_path) -> None:
    from evolution.lab import run

    with pytest.raises(ValueError, match=message):
        run("ee", 1, 0, out_dir=tmp_path / "run", policies=REACTIVE, **overrides)
    assert not (tmp_path / "run").exists()  # nothing was created


def test_bad_arguments_get_clear_errors() -> None:
    from evolution.lab import run

    with pytest.raises(ValueError, match="method must be one of ee, ce"):
        run("ga", 1, 0, policies=REACTIVE)
    with pytest.raises(ValueError, match=r"generations must be an integer in \[0, ∞\)"):
        run("ee", -1, 0, policies=REACTIVE)
    with pytest.raises(ValueError, match=r"seed must be an integer in \[0, ∞\)"):
        run("ee", 1, -3, policies=REACTIVE, **SMALL)
    with pytest.raises(ValueError, match="resume=True needs the out_dir"):
        run("ee", 1, 0, policies=REACTIVE, resume=True)


def test_missing_trained_values_name_the_reactive_alternative(tmp_path, monkeypatch) -> None:
    from evolution.lab import run

    monkeypatch.setenv("CYBER_RODENT_BEHAVIOUR_VALUES", str(tmp_path))  # an empty directory
    with pytest.raises(FileNotFoundError, match=r"BehaviourPolicies.reactive\(\)"):
        run("ee", 1, 0, **SMALL)


def test_make_config_applies_overrides_consistently() -> None:
    cfg = make_config(
        "ce", population_size=12, n_robots=3, max_energy=300.0, mutation_probability=0.2
    )
    assert isinstance(cfg, RunConfig) and cfg.method == "ce"
    assert cfg.world.n_robots == 3 and cfg.survival.max_energy == 300.0
    assert cfg.evolution.genetics.mutation_probability == 0.2
    assert cfg.evolution.genetics.crossover_probability == 0.6  # the paper's default kept
    base = make_config("ee", EvolutionConfig(population_size=8, n_robots=2), n_packs=3)
    assert base.world.n_packs == 3 and base.world.n_robots == 2
    assert "lifetime_steps" in OVERRIDES and "crossover_probability" in OVERRIDES
    default = make_config()
    assert default.evolution == EvolutionConfig() and default.world.n_packs == 5
    assert math.isclose(default.survival.control_dt, 0.2)
