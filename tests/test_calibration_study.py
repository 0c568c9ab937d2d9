"""The calibration study refuses a study it could not run before any sweep starts, and
publishing new sweeps keeps the studies already published."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from benchmarks import calibration_study
from benchmarks.calibration_study import STUDIES, Study, check_studies, read_published


def test_every_study_of_both_rounds_is_a_valid_configuration() -> None:
    check_studies(STUDIES)


def test_a_pack_gap_the_field_cannot_hold_is_refused_with_the_study_named() -> None:
    # 4 robots and 5 packs fit the 2.3 m field at a 0.55 m gap, not at 0.6 m (WorldConfig).
    check_studies([Study("fits", "pack spacing", ("world.pack_gap=0.55",))])
    wide = Study("wide", "pack spacing", ("world.pack_gap=0.45,0.6",))
    with pytest.raises(ValueError, match=r"study 'wide'.*pack_gap=0\.6"):
        check_studies([wide])


def test_a_first_round_study_is_checked_under_the_first_defaults() -> None:
    # reflex_min_steps is 4 in the first defaults: a maximum of 3 is below it there, not today.
    short = ("survival.reflex_max_steps=3",)
    check_studies([Study("today", "reflex", short)])
    with pytest.raises(ValueError, match="study 'first'"):
        check_studies([Study("first", "reflex", short, round=1)])


def test_run_refuses_a_bad_study_before_creating_anything(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = Study("wide", "pack spacing", ("world.pack_gap=0.9",))
    monkeypatch.setattr(calibration_study, "STUDIES", (bad,))
    out = tmp_path / "calibration"
    with pytest.raises(SystemExit) as stop:
        calibration_study.main(["--run", "--out", str(out), "--only", "wide"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "study 'wide'" in err[0] and "pack_gap=0.9" in err[0]
    assert not out.exists()


PUBLISHED = Path(__file__).resolve().parents[1] / "results" / "calibration.csv"


def _fake_sweeps(
    monkeypatch: pytest.MonkeyPatch, out: Path, studies: dict[str, tuple[str, list[float]]]
) -> None:
    """Finished round-2 sweeps of ``studies`` (name: key and values) under ``out``, every
    quantity 99, without running them: the merge with the published table is under test."""
    for name in studies:
        (out / "final" / name).mkdir(parents=True)

    def compare(loaded: object, window: int) -> pd.DataFrame:
        del loaded, window
        study = current.pop()
        key, values = studies[study]
        return pd.DataFrame(
            {"cell": f"{key}={v}", key: v, "method": m, "runs": 2, "generations": "20-29",
             "batteries": 99.0, "batteries_std": 0.0, "matings": 99.0, "matings_std": 0.0,
             "completed": 99.0, "completed_std": 0.0}  # fmt: skip
            for v in values
            for m in ("ee", "ce")
        )

    current: list[str] = []

    def load(root: Path) -> dict[str, object]:
        current.append(root.name)
        return {}

    monkeypatch.setattr(calibration_study, "read_grid", lambda root: None)
    monkeypatch.setattr(calibration_study, "load_sweep", load)
    monkeypatch.setattr(calibration_study, "compare_cells", compare)


def test_publishing_with_no_sweeps_writes_the_published_table_back_unchanged(
    tmp_path: Path,
) -> None:
    table = calibration_study.collect(tmp_path, 10, published=read_published(PUBLISHED))
    written = tmp_path / "calibration.csv"
    table.to_csv(written, index=False, float_format="%.4g")
    assert written.read_text() == PUBLISHED.read_text()


def test_a_new_study_joins_the_published_rows_with_its_reference_from_the_baseline(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _fake_sweeps(monkeypatch, tmp_path, {"pack_gap": ("world.pack_gap", [0.45, 0.55])})
    published = read_published(PUBLISHED)
    assert published is not None
    # the table as it was before the study ran
    published = published[published["study"] != "pack_gap"].reset_index(drop=True)
    table = calibration_study.collect(tmp_path, 10, published=published)
    gap = table[table["study"] == "pack_gap"]
    assert sorted(gap["value"]) == [0.3, 0.3, 0.45, 0.45, 0.55, 0.55]
    fresh = gap[gap["value"] != 0.3]
    assert (fresh["batteries"] == 99.0).all() and not fresh["default"].any()
    # the reference value's rows are the round's baseline, marked as the default
    reference = gap[gap["value"] == 0.3].set_index("method")
    baseline = published[(published["round"] == 2) & (published["study"] == "baseline")]
    assert reference["default"].all()
    assert dict(reference["batteries"]) == dict(baseline.set_index("method")["batteries"])
    # every published row is still there, in its place
    rest = table[table["study"] != "pack_gap"].reset_index(drop=True)
    pd.testing.assert_frame_equal(rest, published, check_dtype=False)


def test_a_study_run_again_replaces_its_published_rows(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _fake_sweeps(monkeypatch, tmp_path, {"mate_distance": ("survival.mate_distance", [0.25])})
    published = read_published(PUBLISHED)
    table = calibration_study.collect(tmp_path, 10, published=published)
    mine = table[(table["round"] == 2) & (table["study"] == "mate_distance")]
    # 0.5 was published but is not in the new sweep; 0.35 is the default, from the baseline
    assert sorted(mine["value"]) == [0.25, 0.25, 0.35, 0.35]
    assert (mine[mine["value"] == 0.25]["batteries"] == 99.0).all()
    assert (mine[mine["value"] == 0.35]["batteries"] < 99.0).all()
    assert len(table) == len(published) - 2
