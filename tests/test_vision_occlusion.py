"""The randomised partial-occlusion scenes and their benchmark (a few scenes per family; the
full run is ``benchmarks/vision_occlusion.py``)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from benchmarks import vision_occlusion as bench
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.vision.hard_scenes import MAX_PENETRATION, place, valid
from cyber_rodent.vision.occlusion_scenes import (
    FAMILIES,
    MAX_SCENES,
    MIDDLE_LATERAL,
    ROW_LATERAL,
    family,
    make_scene,
    make_scenes,
    seeds,
)
from cyber_rodent.world import World, WorldConfig


def test_seed_sets_are_explicit_and_disjoint() -> None:
    tune, report = seeds("tune", MAX_SCENES), seeds("report", MAX_SCENES)
    assert tune[:3] == [1000, 1001, 1002] and report[:3] == [2000, 2001, 2002]
    assert not set(tune) & set(report)
    assert seeds("tune", 5) == tune[:5]
    with pytest.raises(ValueError, match="unknown seed set 'x'; known: tune, report"):
        seeds("x", 1)
    with pytest.raises(ValueError, match="0 to 1000 scenes"):
        seeds("report", MAX_SCENES + 1)


def test_scenes_are_valid_seeded_and_differ_between_sets() -> None:
    for fam in FAMILIES:
        world = World(fam.world_config())
        first = make_scenes(world, fam, seeds("tune", 4))
        assert first == make_scenes(world, fam, seeds("tune", 4)), fam.name
        # A scene depends on its own seed only.
        assert make_scene(world, fam, seeds("tune", 4)[2]) == first[2], fam.name
        assert not set(first) & set(make_scenes(world, fam, seeds("report", 4))), fam.name
        n_targets = 2 * fam.n_robots + fam.n_packs
        for scene in first:
            assert valid(world, scene), fam.name
            assert all(c.dist >= -MAX_PENETRATION for c in world.data.contact[: world.data.ncon])
            assert scene.designed and all(
                o == 0 and 0 <= t < n_targets for o, t in scene.designed
            ), fam.name
    with pytest.raises(ValueError, match="unknown occlusion family 'x'; known: rows"):
        family("x")
    with pytest.raises(ValueError, match="needs 4 robots and 1 packs"):
        make_scene(World(WorldConfig(n_robots=2, n_packs=2)), family("rows"), 0)


def _along_and_aside(origin, towards, point) -> tuple[float, float]:
    """``point``'s distance along the line from ``origin`` to ``towards``, and off it."""
    ux, uy = towards[0] - origin[0], towards[1] - origin[1]
    norm = math.hypot(ux, uy)
    dx, dy = point[0] - origin[0], point[1] - origin[1]
    return (dx * ux + dy * uy) / norm, (-dx * uy + dy * ux) / norm


def test_the_families_lay_out_what_they_promise() -> None:
    world = World(family("rows").world_config())
    for scene in make_scenes(world, family("rows"), seeds("tune", 20)):
        observer = scene.robots[0]
        in_row = 2 + len(scene.designed) // 2  # the robots beyond the first are designed
        along = [math.dist(observer[:2], r[:2]) for r in scene.robots[:in_row]]
        assert np.all(np.diff(along) >= 0.25 - 2 * ROW_LATERAL)
        assert along[-1] <= 3 * 1.0 + ROW_LATERAL
    world = World(family("pack_behind").world_config())
    for scene in make_scenes(world, family("pack_behind"), seeds("tune", 20)):
        for k in (1, 2):
            robot, pack = scene.robots[k][:2], scene.packs[k - 1]
            d = math.dist(scene.robots[0][:2], robot)
            behind, _ = _along_and_aside(scene.robots[0], robot, pack)
            assert 0.3 <= d <= 2.0 and behind >= d + 0.12 - 1e-9
    world = World(family("behind_robot").world_config())
    for scene in make_scenes(world, family("behind_robot"), seeds("tune", 20)):
        observer, middle, far = (r[:2] for r in scene.robots)
        assert 0.5 <= math.dist(observer, far) <= 2.0
        along, aside = _along_and_aside(observer, far, middle)
        assert 0.25 - 1e-9 <= along <= math.dist(observer, far) - 0.25 + 1e-9
        assert abs(aside) <= MIDDLE_LATERAL + 1e-9


def test_the_designed_targets_are_partly_hidden() -> None:
    """Over 30 scenes, each family's designed targets show shares strictly between 0 and 1."""
    for fam in FAMILIES:
        world = World(fam.world_config())
        geo = GeometricVision(world)
        partly = 0
        for scene in make_scenes(world, fam, seeds("tune", 30)):
            place(world, scene)
            share = geo.measure_targets().visible_share
            partly += sum(0.0 < share[o, t] < 1.0 for o, t in scene.designed)
        assert partly >= 10, fam.name


# --- the benchmark ------------------------------------------------------------------------------
def test_share_buckets() -> None:
    assert bench.share_bucket(0.5, candidate=False) == "out"
    assert bench.share_bucket(0.0, True) == "0/6"
    assert bench.share_bucket(1.0, True) == "6/6"
    assert [bench.share_bucket(k / 6, True) for k in range(1, 6)] == [
        "1/6", "2/6", "3/6", "4/6", "5/6"
    ]  # fmt: skip
    # A LED's three samples.
    assert bench.share_bucket(1 / 3, True) == "2/6" and bench.share_bucket(2 / 3, True) == "4/6"
    # Any other share: the nearest sixth, but never 0 or 6 when partly seen.
    assert bench.share_bucket(0.01, True) == "1/6" and bench.share_bucket(0.99, True) == "5/6"


def _pair(geometric_area: float, blob_area: float, share: float = 0.5) -> bench.PairRow:
    return bench.PairRow(
        family="f", seed=0, scene=0, robot=0, target=1, cls=1, distance=1.0, candidate=True,
        visible_share=share, footprint=20.0, spread=0.0, designed=False, geometric=True,
        rendered=True, geometric_area=geometric_area, blob_area=blob_area,
    )  # fmt: skip


def test_area_error() -> None:
    pairs = [_pair(3.0, 2.0), _pair(10.0, 9.0), _pair(4.0, 10.0), _pair(12.0, 10.0)]
    stats = bench.area_error(pairs)
    assert stats["n"] == 4
    assert stats["median_px"] == pytest.approx(1.5)
    assert stats["median_rel"] == pytest.approx((0.2 + 0.5) / 2)
    # Within 1 px or 20 %: all but the 4 px prediction of a 10 px blob.
    assert stats["within_1px_or_20pct"] == pytest.approx(0.75)
    assert stats["median_signed_rel"] == pytest.approx((1 / 9 + 0.2) / 2)
    assert math.isnan(bench.area_error([])["median_px"])
    # Fully visible and merged targets are not partly hidden ones.
    merged = bench.PairRow(**{**_pair(5.0, 9.0).__dict__, "spread": 0.1})
    assert bench.area_pairs([_pair(1, 1), _pair(1, 1, 1.0), merged], partly=True) == [_pair(1, 1)]


def test_the_benchmark_runs_on_a_few_scenes(tmp_path: Path, capsys) -> None:
    table, pairs = tmp_path / "occlusion.csv", tmp_path / "pairs.csv"
    argv = ["--scenes", "3", "--seeds", "report", "--csv", str(table), "--rows", str(pairs)]
    rows = bench.main(argv)
    out = capsys.readouterr().out
    assert "seed set report (2000-2002)" in out
    for title in ("| family | targets |", "| family | out | 0/6 |", "| median px |"):
        assert title in out
    names = [f.name for f in FAMILIES]
    with open(table) as fh:
        written = list(csv.DictReader(fh))
    assert len(written) == len(rows)
    assert {r["family"] for r in written} == {*names, "all"}
    assert {r["table"] for r in written} == {"targets", "inputs", "unmatched", "share", "area"}
    assert {r["seeds"] for r in written} == {"report"}
    every = [r for r in rows if r["table"] == "targets" and r["scope"] == "all"]
    every = [r for r in every if r["class"] == "all" and r["subset"] == "every pair"]
    per_family = {r["family"]: r["n"] for r in every}
    assert per_family["all"] == sum(per_family[n] for n in names) > 0
    with open(pairs) as fh:
        lines = list(csv.DictReader(fh))
    assert len(lines) == per_family["all"]
    assert {int(r["seed"]) for r in lines} == {2000, 2001, 2002}
    # The share buckets partition the pairs within range.
    near = "within 2 m"
    for name in names:
        shares = [r for r in rows if r["family"] == name and r["table"] == "share"]
        total = sum(r["n"] for r in shares if r["class"] == "all")
        within = [r for r in rows if r["family"] == name and r["table"] == "targets"]
        within = [r for r in within if r["scope"] == near and r["class"] == "all"]
        assert total == next(r["n"] for r in within if r["subset"] == "every pair")
    # Deterministic: the same scenes give the same tables.
    assert bench.main(argv[:4]) == rows
