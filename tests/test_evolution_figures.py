"""Figures: the aggregation over runs (hand-computed) and that files are written and decode."""

from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pandas as pd
import pytest

from evolution.lab.figures import (
    aggregate_runs,
    plot_completions,
    plot_fig6,
    plot_per_robot,
    pool_per_robot,
    summarise_runs,
)


def table(batteries, matings) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "generation": np.arange(len(batteries)),
            "batteries_mean": batteries,
            "matings_mean": matings,
        }
    )


def test_aggregate_runs_hand_computed() -> None:
    a = table([10.0, 20.0, np.nan], [1.0, 2.0, 3.0])
    b = table([14.0, 20.0, 6.0], [3.0, 2.0, 1.0])
    agg = aggregate_runs([a, b], "batteries_mean")
    assert agg["mean"].tolist()[:2] == [12.0, 20.0]
    assert agg["std"].tolist()[:2] == [2.0, 0.0]  # population std of (10, 14) is 2
    # Generation 2: only run b has completed agents.
    assert agg.loc[2, "mean"] == 6.0 and agg.loc[2, "runs"] == 1


def test_aggregate_runs_different_lengths() -> None:
    agg = aggregate_runs([table([1.0, 2.0], [0, 0]), table([3.0], [0])], "batteries_mean")
    assert agg["runs"].tolist() == [2, 1] and agg["mean"].tolist() == [2.0, 2.0]


def test_aggregate_runs_errors() -> None:
    with pytest.raises(ValueError, match="at least one"):
        aggregate_runs([], "batteries_mean")
    with pytest.raises(ValueError, match="lacks"):
        aggregate_runs([pd.DataFrame({"generation": [0]})], "batteries_mean")


def test_summarise_runs_hand_computed() -> None:
    a = table([1.0, 2.0, 4.0, 6.0], [1.0, 1.0, 2.0, 2.0])
    b = table([3.0, 4.0, 8.0], [1.0, 3.0, 4.0])  # shorter: the last common generation is 2
    summary = summarise_runs({"ee": [a, b]}, window=2).set_index("span")
    last, late = summary.loc["last"], summary.loc["last 2"]
    assert last["generations"] == "2" and late["generations"] == "1-2"
    assert last["runs"] == 2
    # Generation 2: batteries 4 and 8 -> mean 6, population std 2; matings 2 and 4 -> 3, 1.
    assert (last["batteries_mean_mean"], last["batteries_mean_std"]) == (6.0, 2.0)
    assert (last["matings_mean_mean"], last["matings_mean_std"]) == (3.0, 1.0)
    # Generations 1-2: run a (2 + 4) / 2 = 3, run b (4 + 8) / 2 = 6 -> mean 4.5, std 1.5.
    assert (late["batteries_mean_mean"], late["batteries_mean_std"]) == (4.5, 1.5)
    with pytest.raises(ValueError, match="window must be"):
        summarise_runs({"ee": [a]}, window=0)


def test_plot_fig6_writes_png_and_pdf(tmp_path) -> None:
    rng = np.random.default_rng(0)
    runs = {
        m: [table(rng.uniform(10, 25, 8), rng.uniform(1, 4, 8)) for _ in range(3)]
        for m in ("ee", "ce")
    }
    paths = plot_fig6(runs, tmp_path / "fig6")
    assert [p.suffix for p in paths] == [".png", ".pdf"]
    image = iio.imread(paths[0])
    assert image.ndim == 3 and image.shape[0] > 300 and image.std() > 10
    assert paths[1].read_bytes().startswith(b"%PDF")


def test_plot_per_robot(tmp_path) -> None:
    rows = [
        {"generation": g, "robot": r, "batteries_mean": g + r} for g in range(5) for r in range(3)
    ]
    paths = plot_per_robot(pd.DataFrame(rows), tmp_path / "fig7")
    plain = iio.imread(paths[0])
    assert plain.shape[0] > 200
    banded = pd.DataFrame(rows).assign(batteries_std=1.0)  # a mean over runs: ± std bands
    image = iio.imread(plot_per_robot(banded, tmp_path / "fig7_band")[0])
    assert image.shape == plain.shape and not np.array_equal(image, plain)
    with pytest.raises(ValueError, match="empty"):
        plot_per_robot(
            pd.DataFrame(columns=["generation", "robot", "batteries_mean"]), tmp_path / "x"
        )


def test_pool_per_robot_hand_computed() -> None:
    a = pd.DataFrame(
        {"generation": [0, 0, 1], "robot": [0, 1, 0], "batteries_mean": [2.0, 4.0, 6.0]}
    )
    b = pd.DataFrame({"generation": [0, 0], "robot": [0, 1], "batteries_mean": [4.0, 4.0]})
    pooled = pool_per_robot([a, b]).set_index(["generation", "robot"])
    assert pooled.loc[(0, 0)].tolist() == [3.0, 1.0, 2]  # mean of 2 and 4, std 1, two runs
    assert pooled.loc[(0, 1)].tolist() == [4.0, 0.0, 2]
    assert pooled.loc[(1, 0)].tolist() == [6.0, 0.0, 1]  # only run a reached generation 1
    with pytest.raises(ValueError, match="at least one"):
        pool_per_robot([])


def test_plot_completions(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)

    def completed_run(n: int) -> pd.DataFrame:
        completed = rng.integers(5, 40, n)
        return pd.DataFrame(
            {"generation": np.arange(n), "completed": completed, "full_lifetimes": completed + 20}
        )

    runs = {"ee": [completed_run(8) for _ in range(3)], "ce": [completed_run(6)]}
    paths = plot_completions(runs, tmp_path / "completions")
    assert [p.suffix for p in paths] == [".png", ".pdf"]
    image = iio.imread(paths[0])
    assert image.ndim == 3 and image.shape[0] > 200 and image.std() > 10
    assert paths[1].read_bytes().startswith(b"%PDF")
    # One method, one run of two generations (no std band): still drawn.
    assert plot_completions({"ee": [completed_run(2)]}, tmp_path / "short")[0].exists()
    with pytest.raises(ValueError, match="at least one run"):
        plot_completions({"ee": []}, tmp_path / "none")
