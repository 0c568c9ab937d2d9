"""The Fig. 6 publishing command: per-run window means, the headline table, files written."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from benchmarks.paper_fig6 import headline, main, per_run_table


def statistics(method: str, seed: int, batteries: float, matings: float, generations: int = 120,
               ) -> pd.DataFrame:  # fmt: skip
    """A statistics table whose late generations hold known values (the early ones differ)."""
    gens = range(generations)
    return pd.DataFrame({
        "generation": list(gens),
        "completed": [70 if g >= 100 else 10 for g in gens],
        "batteries_mean": [batteries if g >= 100 else 1.0 for g in gens],
        "batteries_std": [0.0] * generations,
        "matings_mean": [matings if g >= 100 else 9.0 for g in gens],
        "matings_std": [0.0] * generations,
        "full_lifetimes": [90] * generations,
        "method": [method] * generations,
        "seed": [seed] * generations,
    })  # fmt: skip


def publish(root: Path, runs: dict[str, pd.DataFrame]) -> Path:
    """Lay out ``runs`` as a published results directory (statistics + run.json)."""
    for name, table in runs.items():
        run = root / name
        run.mkdir(parents=True)
        table.to_csv(run / "statistics.csv", index=False)
        table.to_csv(run / "statistics_per_robot.csv", index=False)
        (run / "run.json").write_text(json.dumps({"config": {"method": name[:2]}}))
    return root


def test_per_run_means_cover_generations_100_to_119_only() -> None:
    runs = {"ee": [statistics("ee", 0, 20.0, 4.0), statistics("ee", 1, 22.0, 3.0)],
            "ce": [statistics("ce", 0, 24.0, 2.0)]}  # fmt: skip
    table = per_run_table(runs, (100, 119))
    assert list(table["method"]) == ["ee", "ee", "ce"] and list(table["seed"]) == [0, 1, 0]
    assert list(table["batteries"]) == [20.0, 22.0, 24.0]
    assert list(table["matings"]) == [4.0, 3.0, 2.0]
    assert list(table["completed"]) == [70.0, 70.0, 70.0]


def test_headline_compares_with_the_paper_and_flags_numbers_outside_30_percent() -> None:
    runs = {"ee": [statistics("ee", s, 20.0 + s, 3.5) for s in range(2)],
            "ce": [statistics("ce", s, 25.0, 3.0) for s in range(2)]}  # fmt: skip
    table = per_run_table(runs, (100, 119))
    comparison = pd.DataFrame({"quantity": ["batteries", "matings"], "p_value": [0.5, 0.25]})
    lines = headline(table, comparison).splitlines()
    # EE batteries: mean 20.5 of the paper's 22 -> 0.93; std over runs sqrt(0.5) = 0.71
    assert lines[2] == "| EE batteries (2 runs) | 20.50 ± 0.71 | ≈ 22 | 0.93 | 0.5 |"
    assert lines[3] == "| EE matings (2 runs) | 3.50 ± 0.00 | ≈ 3.5 | 1.00 | 0.25 |"
    assert lines[4] == "| CE batteries (2 runs) | 25.00 ± 0.00 | ≈ 25 | 1.00 | 0.5 |"
    # CE matings 3.0 against 2: 1.5, outside the ±30 % the numbers are judged by
    assert lines[5] == "| CE matings (2 runs) | 3.00 ± 0.00 | ≈ 2 | 1.50 (outside ±30 %) | 0.25 |"


def test_main_draws_and_writes_from_published_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    runs = {f"{m}-seed00{s}": statistics(m, s, 20.0 + s, 3.0 + s)
            for m in ("ee", "ce") for s in range(3)}  # fmt: skip
    published = publish(tmp_path / "published", runs)
    main(["--out", str(tmp_path / "absent"), "--published", str(published),
          "--table-dir", str(tmp_path / "tables"),
          "--figure-dir", str(tmp_path / "images")])  # fmt: skip
    for name in ("fig6", "fig6_completions"):
        assert (tmp_path / "images" / f"{name}.png").stat().st_size > 0
        assert (tmp_path / "images" / f"{name}.pdf").stat().st_size > 0
    comparison = pd.read_csv(tmp_path / "tables" / "fig6_comparison.csv")
    batteries = comparison.set_index("quantity").loc["batteries"]
    assert batteries["ee_runs"] == 3 and batteries["generations"] == "100-119"
    assert len(pd.read_csv(tmp_path / "tables" / "fig6_runs.csv")) == 6
    assert "| EE batteries (3 runs) | 21.00 ± 1.00 |" in capsys.readouterr().out


def test_main_without_published_runs_says_so(tmp_path: Path) -> None:
    (tmp_path / "published").mkdir()
    with pytest.raises(SystemExit, match="no published run"):
        main(["--out", str(tmp_path / "absent"), "--published", str(tmp_path / "published"),
              "--table-dir", str(tmp_path / "t"), "--figure-dir", str(tmp_path / "i")])  # fmt: skip
    assert not (tmp_path / "t").exists() and not (tmp_path / "i").exists()
