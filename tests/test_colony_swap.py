"""The colony study's swap: each size's final population lives one generation in each world."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from benchmarks import colony_study as study
from benchmarks import colony_swap as swap
from evolution.lab.sweep import run_dir
from evolution.runner import EvolutionRunner

#: Two, four and eight robots, eight agents, EE at each and CE at 2 and 8, short lives: the
#: study of tests/test_colony_study.py with one more size and CE at both ends.
TINY = ["--sizes", "2,4,8", "--ce-sizes", "2,8", "--population", "8", "--seeds", "0",
        "--generations", "2", "--set", "evolution.lifetime_steps=40",
        "--set", "evolution.time_sharing_steps=10", "--workers", "1", "--no-estimate"]  # fmt: skip


@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("swap")
    out, published = root / "runs", root / "results"
    assert study.main(["--run", "--out", str(out), "--published", str(published),
                       "--figure", str(root / "figure.png"), *TINY]) == 0  # fmt: skip
    return out, published


def test_the_comparisons_pair_each_population_and_each_world() -> None:
    assert swap.comparisons((4, 100)) == [
        ("genomes, in the N = 100 world", ("n004", "n100"), ("n100", "n100")),
        ("genomes, in the N = 4 world", ("n004", "n004"), ("n100", "n004")),
        ("world, N = 4 genomes", ("n004", "n004"), ("n004", "n100")),
        ("world, N = 100 genomes", ("n100", "n004"), ("n100", "n100")),
    ]


@pytest.mark.parametrize("sizes", ["4", "4,4", "0,4", "4,a", "2,4,10"])
def test_bad_sizes_are_refused(sizes: str) -> None:
    with pytest.raises(study.StudyError, match="--sizes must be two distinct"):
        swap.parse_sizes(sizes)


def test_each_population_lives_a_generation_in_each_world(
    tiny_study: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out, published = tiny_study
    results = tmp_path / "results"
    for path in published.glob("n00*/*"):  # the published tables, without the analysis
        target = results / path.relative_to(published)
        target.mkdir(parents=True)
        for name in ("run.json", "statistics.csv"):
            (target / name).write_bytes((path / name).read_bytes())
    args = ["--out", str(out), "--published", str(results), "--seeds", "0", "--sizes", "2,8",
            "--between", "4"]  # fmt: skip
    assert swap.main([*args, "--workers", "1"]) == 0
    table = pd.read_csv(results / swap.SWAP_FILE)
    pairs = [("n002", "n002"), ("n002", "n008"), ("n008", "n002"), ("n008", "n008")]
    assert table[["method", "genomes", "world"]].values.tolist() == [
        ["ee", *pair] for pair in [*pairs, ("n002", "n004")]
    ] + [["ce", *pair] for pair in pairs] + [
        [method, "random", world] for method in ("ee", "ce") for world in ("n002", "n008")
    ]
    # the world's robots step the generation
    robots = table["world"].map({"n002": 2, "n004": 4, "n008": 8})
    assert (table["robot_steps"] == table["closed_at_step"] * robots).all()
    assert ((table["completed"] >= 0) & (table["completed"] <= 8)).all()
    # the random rows are the study runs' own generation 0
    for _, row in table[table["genomes"] == "random"].iterrows():
        first = pd.read_csv(run_dir(published, row["method"], 0, row["world"]) / "statistics.csv")
        assert row["closed_at_step"] == first.loc[0, "closed_at_step"]
        assert row["deaths"] == first.loc[0, "deaths"]
    # the evaluations start from the runs' final populations: the evolved genomes at home
    # are not the random ones the run started with
    home = table[(table["genomes"] == table["world"])].set_index(["method", "world"])
    random = table[table["genomes"] == "random"].set_index(["method", "world"])
    columns = list(swap.COLUMNS[:4])
    assert not home[columns].equals(random[columns])
    population = swap.final_population(run_dir(out, "ee", 0, "n008"))
    assert len(population) == 8
    # the same rows on two workers
    evaluations = swap.plan(out, results, [0], (2, 8))[:2]
    pd.testing.assert_frame_equal(
        swap.swap_table(evaluations, 2), table.iloc[:2].reset_index(drop=True),
        check_dtype=False,
    )  # fmt: skip
    tests = pd.read_csv(results / "swap_tests.csv")
    # the same command again reads every row back from --out/swap instead of running
    kept = sorted((out / swap.CACHE).glob("*.json"))
    planned = swap.plan(out, results, [0], (2, 8), (4,))
    assert [p.stem for p in kept] == sorted(e.name for e in planned)

    def no_run(*args: object, **kwargs: object) -> None:
        raise AssertionError("ran again")

    monkeypatch.setattr(EvolutionRunner, "run", no_run)
    assert swap.main([*args, "--workers", "1"]) == 0
    pd.testing.assert_frame_equal(pd.read_csv(results / swap.SWAP_FILE), table)
    # a row kept for other genomes or settings is measured again
    record = json.loads(kept[0].read_text())
    kept[0].write_text(json.dumps({**record, "fingerprint": "another"}))
    with pytest.raises(AssertionError, match="ran again"):
        swap.main([*args, "--workers", "1"])
    assert len(tests) == 2 * 4 * 3  # a seed each (none where no agent completed the task)
    assert set(tests["n_a"]) <= {0, 1} and set(tests["n_b"]) <= {0, 1}


def test_a_missing_run_exits_2_before_anything_is_written(
    tiny_study: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, published = tiny_study
    args = ["--out", str(out), "--published", str(tmp_path / "results"), "--seeds", "0"]
    assert swap.main([*args, "--sizes", "2,8", "--between", "4"]) == 2
    assert "--published: no" in capsys.readouterr().err
    assert swap.main(["--out", str(out), "--published", str(published), "--seeds", "0"]) == 2
    err = capsys.readouterr().err
    assert "n100" in err and "has not finished" in err and len(err.splitlines()) == 1
    assert swap.main([*args, "--sizes", "2,8", "--between", "8"]) == 2
    assert "--between must be" in capsys.readouterr().err
    assert swap.main([*args, "--sizes", "2,8", "--workers", "0"]) == 2
    assert not (tmp_path / "results").exists()
