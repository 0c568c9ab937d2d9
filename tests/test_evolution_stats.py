"""The statistics recorder: the paper's Fig. 6 measures, hand-computed."""

from __future__ import annotations

import csv
import math

import pytest

from evolution.agent import Origin
from evolution.stats import StatisticsRecorder


def test_only_agents_that_completed_the_task_enter_the_fig6_means() -> None:
    stats = StatisticsRecorder()
    stats.record_full_life(0, batteries=10, matings=2)
    stats.record_full_life(0, batteries=20, matings=4)
    stats.record_full_life(0, batteries=30, matings=0)  # full life but never mated: excluded
    stats.record_death(0)  # died: excluded
    stats.record_reproduction(0, crossover=True)
    stats.record_reproduction(0, crossover=False)
    stats.record_birth(0, Origin.RANDOM)
    stats.record_birth(0, Origin.SPARE)
    stats.record_birth(0, Origin.SPARE)
    stats.record_birth(0, Origin.RANDOM)
    row = stats.close(0, spare_list_size=7)
    assert (row.completed, row.full_lifetimes, row.unmated, row.deaths) == (2, 3, 1, 1)
    assert (row.batteries_mean, row.batteries_std) == (15.0, 5.0)
    assert (row.matings_mean, row.matings_std) == (3.0, 1.0)
    # Fig. 7's measure: every full lifetime, unmated counted as 0 -> (10 + 20 + 0) / 3.
    assert row.batteries_full_life_mean == 10.0
    assert (row.reproductions, row.crossovers) == (2, 1)
    assert (row.new_offspring, row.new_from_spare, row.new_random) == (0, 2, 2)
    assert row.random_share == 0.5
    assert row.spare_list_size == 7


def test_empty_generation_has_nan_means() -> None:
    row = StatisticsRecorder().close(0, spare_list_size=0)
    assert row.completed == 0
    assert math.isnan(row.batteries_mean) and math.isnan(row.matings_std)
    assert math.isnan(row.random_share)


def test_generations_close_in_order_and_stay_closed() -> None:
    stats = StatisticsRecorder()
    stats.record_birth(1, Origin.OFFSPRING)  # a later generation may open early
    with pytest.raises(RuntimeError, match="expected 0"):
        stats.close(1, 0)
    stats.close(0, 0)
    with pytest.raises(RuntimeError, match="already closed"):
        stats.record_death(0)
    row = stats.close(1, 0)
    assert row.new_offspring == 1 and row.random_share == 0.0


def test_csv_round_trip(tmp_path) -> None:
    stats = StatisticsRecorder()
    stats.record_full_life(0, batteries=4, matings=1)
    stats.close(0, 3)
    path = tmp_path / "stats.csv"
    stats.write_csv(path)
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 1
    assert rows[0]["generation"] == "0"
    assert float(rows[0]["batteries_mean"]) == 4.0
    assert rows[0]["spare_list_size"] == "3"
