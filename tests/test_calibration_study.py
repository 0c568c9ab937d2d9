"""The calibration study refuses a study it could not run before any sweep starts."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import calibration_study
from benchmarks.calibration_study import STUDIES, Study, check_studies


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
