"""Agreement of the geometric and the rendered vision providers on partly hidden targets.

Each family of :mod:`cyber_rodent.vision.occlusion_scenes` (robots in a row, packs behind
robots, a far robot behind a middle one) is generated ``--scenes`` times from the seed set
``--seeds`` (``tune``: seeds 1000 on, for tuning rules; ``report``: seeds 2000 on, disjoint,
for reporting them). Both providers observe every scene;
:func:`cyber_rodent.vision.agreement.compare_scene` matches the rendered blobs to the true
targets by class, bearing, distance and area. Every robot is an observer. Per family it reports:

* **targets**: the share of (observer, candidate target) pairs on which both providers agree
  (seen or not), within ``--within`` m (default 2) and over all, and the disagreements each way;
* **inputs**: the share of (robot, class) nearest-target readings, the controller's inputs,
  that agree (both see nothing, or both see one at distances within 10 %), for robots with a
  target of the class within range, and over all;
* **by visible share**: target agreement within range by the share of the target's occlusion
  samples the geometric provider sees, in sixths (a LED's 1/3 and 2/3 are 2/6 and 4/6; any
  other share is rounded to the nearest sixth, 1/6 to 5/6 when partly seen); ``out``: not a
  candidate at all (out of range, too small, a face turned away; unlit LEDs are no targets);
* **area error**: on targets both providers see, matched to a rendered blob, |geometric
  expected area − blob area| in pixels and relative to the blob area (median, 95th
  percentile), its bias (the median signed relative error) and the share within ±1 px or
  20 %, for partly hidden targets (share < 1) and, for reference, fully visible ones; targets
  whose blob swallowed touching targets of their colour (``blob_spread > 0``) are left out, as
  their blob holds other targets' pixels.

Rendered blobs that match no target (within range) are counted apart: the matcher could pair
them with none. The tables are printed as Markdown; ``--csv`` writes them (long form) and
``--rows`` every (observer, target) pair of every scene, so that two runs can be compared pair
by pair. The measurements read only the providers' public outputs
(:meth:`~cyber_rodent.vision.geometric.GeometricVision.measure_targets`, the rendered frame).

    .venv/bin/python -m benchmarks.vision_occlusion --seeds report --csv /tmp/occlusion.csv
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from cyber_rodent.vision import CLASS_NAMES, N_CLASSES, CameraConfig, kernels
from cyber_rodent.vision.agreement import NearestComparison, compare_scene
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.vision.hard_scenes import Family, place
from cyber_rodent.vision.occlusion_scenes import FAMILIES, SEED_BASES, make_scene, seeds
from cyber_rodent.vision.rendered import RenderedVision
from cyber_rodent.world import World

#: One line of a table (or of its CSV): column name to value.
Row = dict[str, Any]
#: The visible-share buckets, in table order (see the module docstring).
BUCKETS = ("out", "0/6", "1/6", "2/6", "3/6", "4/6", "5/6", "6/6")
#: An area prediction within this many pixels or this relative error of the blob's is good.
AREA_GOOD_PX = 1.0
AREA_GOOD_REL = 0.2


@dataclass(frozen=True)
class PairRow:
    """One (observer, candidate target) pair of one scene, as both providers saw it.

    Attributes:
        family, seed, scene: where it comes from (scene: index within the run).
        robot, target, cls: observer, target index (as in ``GeometricVision``), class.
        distance: m, true horizontal distance.
        candidate, visible_share: the geometric provider's (see ``TargetMeasurements``).
        footprint: px, the target's whole projected footprint (``width_px * height_px``).
        spread: rad, ``blob_spread`` (> 0: its blob swallowed touching targets).
        designed: whether the family built the scene around this pair.
        geometric, rendered: whether each provider detected it.
        geometric_area: px, the geometric provider's expected visible area.
        blob_area: px, the matched rendered blob's area (0 if none).
        traced_area: px, the target's pixels counted one ray per pixel centre
            (``kernels.traced_area``), for every partly hidden candidate (0 for the others):
            the pixel model's own accuracy, whether or not the provider's rule traced it.
    """

    family: str
    seed: int
    scene: int
    robot: int
    target: int
    cls: int
    distance: float
    candidate: bool
    visible_share: float
    footprint: float
    spread: float
    designed: bool
    geometric: bool
    rendered: bool
    geometric_area: float
    blob_area: float
    traced_area: float = 0.0

    @property
    def bucket(self) -> str:
        return share_bucket(self.visible_share, self.candidate)


def share_bucket(share: float, candidate: bool) -> str:
    """The :data:`BUCKETS` entry of a visible share (``out`` for a non-candidate)."""
    if not candidate:
        return "out"
    if share <= 0.0:
        return "0/6"
    if share >= 1.0:
        return "6/6"
    return f"{min(5, max(1, round(6 * share)))}/6"


@dataclass
class FamilyResult:
    """Everything one family's scenes gave."""

    family: Family
    pairs: list[PairRow] = field(default_factory=list)
    nearest: list[NearestComparison] = field(default_factory=list)
    #: m, the distance of every rendered blob that matched no target.
    unmatched: list[float] = field(default_factory=list)
    seconds: float = 0.0


def run_family(family: Family, scene_seeds: Sequence[int], config: CameraConfig) -> FamilyResult:
    """Generate one scene of ``family`` per seed and compare both providers on each."""
    world = World(family.world_config())
    geo = GeometricVision(world, config)
    result = FamilyResult(family)
    t0 = time.perf_counter()
    with RenderedVision(world, config) as ren:
        for s, seed in enumerate(scene_seeds):
            scene = make_scene(world, family, seed)
            place(world, scene)
            comparison = compare_scene(geo, ren)
            meas = comparison.measurements
            designed = set(scene.designed)
            partly = meas.candidate & (meas.visible_share > 0.0) & (meas.visible_share < 1.0)
            robots, targets = np.nonzero(partly)
            pixels = np.zeros(len(robots))
            kernels.traced_area(geo.scene, robots, targets, pixels)
            traced = np.zeros_like(meas.area)
            traced[robots, targets] = pixels
            for r in comparison.targets:
                i, t = r.robot, r.target
                result.pairs.append(
                    PairRow(
                        family=family.name, seed=seed, scene=s, robot=i, target=t, cls=r.cls,
                        distance=r.distance, candidate=bool(meas.candidate[i, t]),
                        visible_share=float(meas.visible_share[i, t]),
                        footprint=float(meas.width_px[i, t] * meas.height_px[i, t]),
                        spread=float(meas.blob_spread[i, t]), designed=(i, t) in designed,
                        geometric=r.geometric, rendered=r.rendered,
                        geometric_area=r.geometric_area, blob_area=r.blob_area,
                        traced_area=float(traced[i, t]),
                    )
                )  # fmt: skip
            result.nearest += comparison.nearest
            result.unmatched += [b.distance for b in comparison.unmatched]
    result.seconds = time.perf_counter() - t0
    return result


# --- statistics --------------------------------------------------------------------------------
def agreement(pairs: Sequence[PairRow]) -> Row:
    """Pairs, the share that agree, and the disagreements each way."""
    return {
        "n": len(pairs),
        "agree": sum(p.geometric == p.rendered for p in pairs) / len(pairs) if pairs else math.nan,
        "geometric_only": sum(p.geometric and not p.rendered for p in pairs),
        "rendered_only": sum(p.rendered and not p.geometric for p in pairs),
    }


def input_agreement(inputs: Sequence[NearestComparison]) -> Row:
    """Readings, the share that agree, and the visibility disagreements each way."""
    return {
        "n": len(inputs),
        "agree": sum(n.agree for n in inputs) / len(inputs) if inputs else math.nan,
        "geometric_only": sum(n.geometric and not n.rendered for n in inputs),
        "rendered_only": sum(n.rendered and not n.geometric for n in inputs),
    }


def area_pairs(pairs: Sequence[PairRow], partly: bool) -> list[PairRow]:
    """Pairs both providers see, matched to a blob, no merge; partly hidden or fully visible."""
    return [
        p
        for p in pairs
        if p.geometric and p.rendered and p.spread == 0.0 and (p.visible_share < 1.0) == partly
    ]


def area_error(pairs: Sequence[PairRow], pixel_model: bool = False) -> Row:
    """|geometric area − blob area| in px and relative to the blob (median, p95), the median of
    the signed relative error (> 0: the geometric provider expects more pixels), and the share
    within :data:`AREA_GOOD_PX` or :data:`AREA_GOOD_REL`. With ``pixel_model``, of the traced
    area (``PairRow.traced_area``) instead of the provider's."""
    signed = np.array(
        [(p.traced_area if pixel_model else p.geometric_area) - p.blob_area for p in pairs]
    )
    gap = np.abs(signed)
    blob = np.maximum([p.blob_area for p in pairs], 1.0) if len(gap) else gap
    rel = gap / blob

    def stat(a: np.ndarray, q: float) -> float:
        return float(np.percentile(a, q)) if len(a) else math.nan

    good = (gap <= AREA_GOOD_PX) | (rel <= AREA_GOOD_REL)
    return {
        "n": len(gap),
        "median_px": stat(gap, 50),
        "p95_px": stat(gap, 95),
        "median_rel": stat(rel, 50),
        "p95_rel": stat(rel, 95),
        "median_signed_rel": stat(signed / blob, 50),
        "within_1px_or_20pct": float(good.mean()) if len(gap) else math.nan,
    }


def _class_name(cls: int) -> str:
    return CLASS_NAMES[cls] if cls >= 0 else "all"


def summary(results: Sequence[FamilyResult], within: float, name: str | None = None) -> list[Row]:
    """The figures of one family's results (or of several together, called ``name``), long
    form: one dict per (table, scope, class, subset)."""
    out: list[Row] = []
    name = name or results[0].family.name
    pairs = [p for r in results for p in r.pairs]
    nearest = [n for r in results for n in r.nearest]
    unmatched = [d for r in results for d in r.unmatched]

    def add(table: str, scope: str, cls: int, subset: str, stats: Row) -> None:
        out.append({"family": name, "table": table, "scope": scope, "class": _class_name(cls),
                    "subset": subset, **stats})  # fmt: skip

    scopes = {f"within {within:g} m": within, "all": math.inf}
    for scope, reach in scopes.items():
        near = [p for p in pairs if p.distance <= reach]
        for cls in [-1, *range(N_CLASSES)]:
            sel = [p for p in near if cls < 0 or p.cls == cls]
            add("targets", scope, cls, "every pair", agreement(sel))
            add("targets", scope, cls, "designed", agreement([p for p in sel if p.designed]))
        inputs = [n for n in nearest if n.closest <= reach]
        for cls in [-1, *range(N_CLASSES)]:
            sel_in = [n for n in inputs if cls < 0 or n.cls == cls]
            add("inputs", scope, cls, "nearest", input_agreement(sel_in))
        blobs = sum(d <= reach for d in unmatched)
        add("unmatched", scope, -1, "rendered blobs", {"n": blobs})
    near = [p for p in pairs if p.distance <= within]
    scope = f"within {within:g} m"
    for cls in [-1, *range(N_CLASSES)]:
        for bucket in BUCKETS:
            sel = [p for p in near if p.bucket == bucket and (cls < 0 or p.cls == cls)]
            add("share", scope, cls, bucket, agreement(sel))
    for cls in [-1, *range(N_CLASSES)]:
        for subset, partly in (("partly hidden", True), ("fully visible", False)):
            sel = [p for p in area_pairs(pairs, partly) if cls < 0 or p.cls == cls]
            add("area", "all", cls, subset, area_error(sel))
            if partly:
                add("area", "all", cls, "partly hidden, pixel model", area_error(sel, True))
    return out


def _find(rows: list[Row], **key: str) -> Row:
    for r in rows:
        if all(r[k] == v for k, v in key.items()):
            return r
    raise KeyError(key)


# --- output ------------------------------------------------------------------------------------
def _pct(x: float) -> str:
    return "-" if math.isnan(x) else f"{100 * x:.1f} %"


def _num(x: float, digits: int = 1) -> str:
    return "-" if math.isnan(x) else f"{x:.{digits}f}"


def markdown(rows: list[Row], families: list[str], within: float) -> str:
    """The three tables (per family, by visible share, area error) as Markdown."""
    near = f"within {within:g} m"
    lines = [
        f"Per family (targets and inputs {near}; 'all': any distance)",
        "",
        "| family | targets | agree | geo only | ren only | designed | agree | all: agree "
        "| inputs | agree | LED | face | pack | all: agree | unmatched blobs |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for f in families:
        t = _find(rows, family=f, table="targets", scope=near, subset="every pair")
        d = _find(rows, family=f, table="targets", scope=near, subset="designed")
        a = _find(rows, family=f, table="targets", scope="all", subset="every pair")
        inp = {
            c: _find(rows, family=f, table="inputs", scope=near, **{"class": c})
            for c in ("all", *CLASS_NAMES)
        }
        ia = _find(rows, family=f, table="inputs", scope="all", **{"class": "all"})
        u = _find(rows, family=f, table="unmatched", scope=near)
        lines.append(
            f"| {f} | {t['n']} | {_pct(t['agree'])} | {t['geometric_only']} | "
            f"{t['rendered_only']} | {d['n']} | {_pct(d['agree'])} | {_pct(a['agree'])} | "
            f"{inp['all']['n']} | {_pct(inp['all']['agree'])} | "
            + " | ".join(_pct(inp[c]["agree"]) for c in CLASS_NAMES)
            + f" | {_pct(ia['agree'])} | {u['n']} |"
        )
    lines += [
        "",
        f"Targets {near} by visible share (agreement, pairs)",
        "",
        "| family | " + " | ".join(BUCKETS) + " |",
        "|---|" + "---:|" * len(BUCKETS),
    ]
    for f in families:
        cells = []
        for b in BUCKETS:
            r = _find(rows, family=f, table="share", subset=b, **{"class": "all"})
            cells.append(f"{_pct(r['agree'])} ({r['n']})" if r["n"] else "-")
        lines.append(f"| {f} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Area error, both see it, matched blob, merges left out (|geometric - blob|)",
        "",
        "| family | targets | n | median px | p95 px | median rel | p95 rel | bias "
        "| ≤ 1 px or 20 % |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for f in families:
        for subset in ("partly hidden", "partly hidden, pixel model", "fully visible"):
            r = _find(rows, family=f, table="area", subset=subset, **{"class": "all"})
            lines.append(
                f"| {f} | {subset} | {r['n']} | {_num(r['median_px'])} | {_num(r['p95_px'])} | "
                f"{_pct(r['median_rel'])} | {_pct(r['p95_rel'])} | "
                f"{_pct(r['median_signed_rel'])} | {_pct(r['within_1px_or_20pct'])} |"
            )
    return "\n".join(lines)


def _rounded(value: object) -> object:
    return round(value, 4) if isinstance(value, float) else value


def write_csv(path: Path, rows: list[Row]) -> None:
    """The summary rows, long form (every row's keys; missing ones empty)."""
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        for r in rows:
            writer.writerow({k: _rounded(r.get(k, "")) for k in keys})


def write_pairs(path: Path, pairs: list[PairRow]) -> None:
    """Every (observer, target) pair of every scene."""
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow([f.name for f in fields(PairRow)])
        for p in pairs:
            writer.writerow([_rounded(v) for v in asdict(p).values()])


def main(argv: Sequence[str] | None = None) -> list[Row]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=200, help="scenes per family (default 200)")
    ap.add_argument(
        "--seeds", choices=sorted(SEED_BASES), default="tune",
        help="seed set: tune (seeds 1000 on) or report (2000 on); default tune",
    )  # fmt: skip
    ap.add_argument("--within", type=float, default=2.0, help="m, the near range (default 2)")
    ap.add_argument(
        "--families", default=",".join(f.name for f in FAMILIES), help="comma-separated names"
    )
    ap.add_argument(
        "--trace-below", default=None,
        help="camera.trace_below as LED,FACE,PACK px (0,0,0: the samples' estimate alone, the "
        "model before pixel tracing); default the camera's",
    )  # fmt: skip
    ap.add_argument("--csv", type=Path, default=None, help="write the tables here (long form)")
    ap.add_argument("--rows", type=Path, default=None, help="write every pair here")
    args = ap.parse_args(argv)
    names = args.families.split(",")
    unknown = set(names) - {f.name for f in FAMILIES}
    if unknown:
        ap.error(f"unknown families: {', '.join(sorted(unknown))}")
    chosen = [f for f in FAMILIES if f.name in names]
    scene_seeds = seeds(args.seeds, args.scenes)
    config = CameraConfig()
    if args.trace_below is not None:
        try:
            trace = tuple(int(v) for v in args.trace_below.split(","))
            config = CameraConfig(trace_below=trace)  # type: ignore[arg-type]
        except ValueError as e:
            ap.error(f"--trace-below: {e}")
    print(
        f"{args.scenes} scenes per family, seed set {args.seeds} "
        f"({scene_seeds[0] if scene_seeds else '-'}-{scene_seeds[-1] if scene_seeds else '-'});"
        f" camera {config.n_views} x {config.view_width} x {config.height} px,"
        f" trace_below {config.trace_below}",
        flush=True,
    )
    results = []
    for family in chosen:
        results.append(run_family(family, scene_seeds, config))
        print(f"  {family.name}: {results[-1].seconds:.1f} s", flush=True)
    rows: list[Row] = []
    for result in results:
        rows += summary([result], args.within)
    if len(results) > 1:
        rows += summary(results, args.within, name="all")
    rows = [{"seeds": args.seeds, **r} for r in rows]
    names = [r["family"] for r in rows if r["table"] == "unmatched" and r["scope"] == "all"]
    print()
    print(markdown(rows, names, args.within))
    if args.csv is not None:
        write_csv(args.csv, rows)
        print(f"\ntables in {args.csv}")
    if args.rows is not None:
        write_pairs(args.rows, [p for r in results for p in r.pairs])
        print(f"pairs in {args.rows}")
    return rows


if __name__ == "__main__":
    main()
