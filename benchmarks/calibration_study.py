"""The calibration study of the paper's unknowns: run it, then tabulate and draw it.

The paper fixes Tables 1 and 2 but leaves open the quantities that set how often a robot can
capture a battery or mate: the control step's length, the post-recharge reflex, the IR
exchange's duration, the mating geometry, the pack layout, what counts as a capture, and
whether energy decays while docked. Each study below is one ``cyber-rodent sweep`` over a grid
of one setting (its reference value is the round's ``baseline`` sweep, run once), for EE and
CE, on the calibration seeds 100 and up: a choice is never tuned on a seed the results then
report (seeds 0-19).

The study ran in two rounds. The first varied the unknowns that set the rates most around the
first defaults (:data:`FIRST_DEFAULTS`, a 0.1 s step) and tried the combinations that became
today's defaults; the second varies every unknown, one at a time, around today's defaults. A
first-round sweep runs with the code of the first defaults (``--code``, a checkout of it), a
second-round one with a checkout of today's defaults (the published round ran with the commit
``results/fig6_published_contacts`` records).

Each run contributes its mean over its last ``--window`` generations; the table gives, per
study, value and method, the mean and standard deviation over seeds (:mod:`evolution.lab.grid`).
Publishing reads the table already published and keeps the rows of every study with no
finished sweep under ``--out``: run directories are not kept, so the studies can be run a few at
a time, on different machines.

    .venv/bin/python -m benchmarks.calibration_study --run --round 2   # the sweeps (hours)
    .venv/bin/python -m benchmarks.calibration_study                   # tables and figures
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from evolution.lab.cells import compare_cells, load_cells
from evolution.lab.grid import Cell, cells, read_grid
from evolution.lab.sweep import load_sweep, parse_seeds
from evolution.runner.config import RunConfig
from evolution.runner.settings import apply, parse_grid, parse_set, settings

#: The paper's headline numbers per 400-step life (Fig. 6): EE at generation 120, CE after
#: it converged.
PAPER = {"ee": {"batteries": 22.0, "matings": 3.5}, "ce": {"batteries": 25.0, "matings": 2.0}}
#: Seeds used to calibrate (never reported as results) and the generations of each run.
SEEDS = "100-101"
GENERATIONS = 30


#: The first round's reference: the defaults before the study (every other setting as today's).
FIRST_DEFAULTS: dict[str, Any] = {
    "survival.control_dt": 0.1,
    "survival.reflex_min_steps": 4,
    "survival.reflex_max_steps": 8,
    "survival.mate_reflex": False,
    "survival.mate_consecutive_steps": 1,
}
#: Where each round's sweeps go, under ``--out``.
ROUND_DIRS = {1: ".", 2: "final"}


@dataclass(frozen=True)
class Study:
    """One unknown: a sweep over a grid of one setting (or the defaults for a baseline).

    A combination (``sets``, and ``behaviours`` trained under the combination's control step)
    is compared with the paper, not with the baseline: it changes more than one setting.
    """

    name: str
    title: str
    grid: tuple[str, ...] = ()
    methods: str = "ee,ce"
    sets: tuple[str, ...] = ()
    behaviours: str | None = None
    round: int = 2

    @property
    def single(self) -> bool:
        """Does the study vary one setting around its round's defaults?"""
        return not self.sets and bool(self.grid)

    def directory(self, out: Path) -> Path:
        """The study's sweep directory."""
        return (out / ROUND_DIRS[self.round] / self.name).resolve()


#: Behaviours trained under a 0.2 s control step, for the first round's combinations:
#: ``cyber-rodent train-behaviours --set survival.control_dt=0.2 --seed 0 --out DIR`` with the
#: first defaults' code.
BEHAVIOURS_DT02 = "behaviours_dt0.2"
_DT02 = ("survival.control_dt=0.2",)


STUDIES = (
    # first round: around FIRST_DEFAULTS, then the combinations that became today's defaults
    Study("baseline", "the first defaults", round=1),
    Study("ir_exchange", "IR exchange duration", ("survival.mate_consecutive_steps=2,3",),
          round=1),  # fmt: skip
    Study("mate_reflex", "reflex after mating", ("survival.mate_reflex=true",), round=1),
    Study("control_step", "control step length", ("survival.control_dt=0.15,0.2",), round=1),
    Study(
        "candidate",
        "0.2 s step, retrained behaviours, reflex after mating",
        ("survival.mate_reflex=true",),
        sets=_DT02,
        behaviours=BEHAVIOURS_DT02,
        round=1,
    ),
    Study(
        "candidate2",
        "the same, reflex 2-4 steps (86-172° at 0.2 s)",
        ("survival.mate_consecutive_steps=1,2",),
        sets=(*_DT02, "survival.mate_reflex=true", "survival.reflex_min_steps=2",
              "survival.reflex_max_steps=4"),  # fmt: skip
        behaviours=BEHAVIOURS_DT02,
        round=1,
    ),
    # second round: every other unknown, one at a time, around today's defaults
    Study("baseline", "today's defaults"),
    Study("mate_distance", "mating distance", ("survival.mate_distance=0.25,0.5",)),
    Study("mate_angle", "mating angle", ("survival.mate_angle_deg=10,25",)),
    Study("reflex_length", "reflex length (max steps)", ("survival.reflex_max_steps=3,6",)),
    Study("reflex_speed", "reflex speed", ("survival.reflex_wheel_speed=0.15,0.6",)),
    Study("capture_rule", "what counts as a capture", ("survival.capture_rule=recharge",)),
    # 0.55 m is the widest gap at which 4 robots and 5 packs still fit the field (WorldConfig)
    Study("pack_gap", "pack spacing", ("world.pack_gap=0.45,0.55",)),
    Study("decay_docked", "decay while docked", ("survival.decay_while_recharging=true",)),
    Study("ce_tournament", "CE tournament size", ("genetic.tournament_size=4,8",), "ce"),
    Study(
        "ce_dead_fitness",
        "CE fitness of agents that died",
        ("evolution.ce_fitness_requires_survival=false",),
        "ce",
    ),
)


def reference(round_: int) -> dict[str, Any]:
    """The default of every setting in a round: today's, or :data:`FIRST_DEFAULTS` over them."""
    values = {key: field.default for key, field in settings().items()}
    if round_ == 1:
        values.update(FIRST_DEFAULTS)
    return values


def sweep_command(study: Study, out: Path) -> list[str]:
    """The ``cyber-rodent sweep`` command line of one study."""
    command = [
        "cyber-rodent", "sweep", "--methods", study.methods, "--seeds", SEEDS,
        "--generations", str(GENERATIONS), "--workers", "2", "--out", str(study.directory(out)),
    ]  # fmt: skip
    for axis in study.grid:
        command += ["--grid", axis]
    for setting in study.sets:
        command += ["--set", setting]
    return command


def check_studies(studies: Sequence[Study]) -> None:
    """Refuse, before any sweep starts, a study whose cells are not valid configurations.

    Each cell of each method is resolved from its round's defaults, the study's ``sets`` and the
    cell's grid values, so a value the world cannot hold (packs that do not fit, say) stops the
    whole study up front rather than hours in.

    Raises:
        ValueError: one line naming the study and the value its configuration refuses.
    """
    for study in studies:
        first = FIRST_DEFAULTS if study.round == 1 else {}
        try:
            sets = parse_set(list(study.sets))
            grid_cells: tuple[Cell | None, ...] = cells(parse_grid(list(study.grid))) or (None,)
            for method in study.methods.split(","):
                for cell in grid_cells:
                    values = {**first, **sets, **(cell.settings if cell else {})}
                    apply(RunConfig(method=method), values)
        except ValueError as error:
            raise ValueError(f"study {study.name!r}: {error}") from None


def run_studies(studies: Sequence[Study], out: Path, code: Path) -> None:
    """Run (or resume) every study's sweep, one after the other, with the package in ``code``
    (training the behaviours a combination needs first); every study is checked first."""
    check_studies(studies)
    cli = [sys.executable, "-m", "evolution.cli"]
    for study in studies:
        env = dict(os.environ)
        if study.behaviours is not None:
            values = (out.parent / study.behaviours).resolve()
            if not (values / "mate.npz").exists():
                train = ["train-behaviours", "--set", _DT02[0], "--seed", "0", "--out", str(values)]
                print("cyber-rodent", " ".join(train), flush=True)
                subprocess.run([*cli, *train, "--no-progress"], check=True, cwd=code)
            env["CYBER_RODENT_BEHAVIOUR_VALUES"] = str(values)
        command = sweep_command(study, out)
        if (study.directory(out) / "sweep.json").exists():
            command.append("--resume")
        print(" ".join(command), flush=True)
        subprocess.run([*cli, *command[1:], "--no-progress"], check=True, env=env, cwd=code)


#: Two matings of one robot pair this close (control steps) are a chain: the next agents of two
#: robots left nose to nose by an exchange mate at once.
CHAIN_STEPS = 3


def event_rates(run: Path, window: int) -> dict[str, float]:
    """What sets a run's rates, from its event log, over its last ``window`` generations.

    ``recharge_steps``: median recharge steps per docking (the steps between the docking and the
    recharge's end, less the stopping step when the controller stopped it); ``zero_recharge``:
    share of dockings with none; ``redock_gap``: median steps from a robot's undocking to its
    next docking (the reflex, then the re-approach); ``chained_matings``: share of a pair's
    matings within :data:`CHAIN_STEPS` steps of its previous one.
    """
    events = pd.read_csv(run / "events.csv")
    last = int(events["generation"].max())
    late = events[events["generation"] > last - window]
    steps, gaps = [], []
    for _, mine in late[late["kind"].isin(("dock", "recharge_end"))].groupby("robot"):
        kinds, times, reasons = mine["kind"].tolist(), mine["step"].tolist(), mine["value"]
        for k in range(1, len(kinds)):
            if kinds[k - 1] == "dock" and kinds[k] == "recharge_end":
                steps.append(times[k] - times[k - 1] - int(reasons.iloc[k] == 1))
            if kinds[k - 1] == "recharge_end" and kinds[k] == "dock":
                gaps.append(times[k] - times[k - 1])
    matings = late[(late["kind"] == "mate") & (late["robot"] < late["value"])]
    gap = matings.groupby(["robot", "value"])["step"].diff()
    return {
        "recharge_steps": float(np.median(steps)) if steps else math.nan,
        "zero_recharge": float(np.mean(np.array(steps) == 0)) if steps else math.nan,
        "redock_gap": float(np.median(gaps)) if gaps else math.nan,
        "chained_matings": float((gap <= CHAIN_STEPS).mean()) if len(gap) else math.nan,
    }


def _cells_of(root: Path) -> list[str]:
    grid = read_grid(root)
    return ["defaults"] if grid is None else [c.name for c in cells(grid)]


def _rates(out: Path, window: int) -> pd.DataFrame:
    """:func:`event_rates` averaged over seeds, per round, study, cell and method."""
    rows = []
    for study in STUDIES:
        root = study.directory(out)
        if not root.is_dir():
            continue
        for name in _cells_of(root):
            base = root if name == "defaults" else root / name
            for run in sorted(base.glob("*-seed*")):
                if (run / "events.csv").exists():
                    method = run.name.partition("-")[0]
                    rates = event_rates(run, window)
                    rows.append({"round": study.round, "study": study.name, "cell": name,
                                 "method": method, **rates})  # fmt: skip
    keys = ["round", "study", "cell", "method"]
    if not rows:
        return pd.DataFrame(columns=keys)
    return pd.DataFrame(rows).groupby(keys, as_index=False).mean()


def _parse_value(text: object) -> object:
    """A published ``value`` cell as the sweep wrote it (``1`` an int, ``2.0`` a float, ``True``
    a bool, else the text), so a row kept from the published table is written back unchanged."""
    if not isinstance(text, str):
        return text
    if text in ("True", "False"):
        return text == "True"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def read_published(table: Path) -> pd.DataFrame | None:
    """The published table, or None where there is none yet."""
    if not table.exists():
        return None
    published = pd.read_csv(table, dtype={"value": str, "generations": str})
    published["value"] = published["value"].map(_parse_value)
    return published


def collect(
    out: Path, window: int, partial: bool = False, published: pd.DataFrame | None = None
) -> pd.DataFrame:
    """One row per round, study, value and method (a round's baseline rows, and again under
    each of its single studies' keys); only cells whose runs all reached the last generation,
    unless ``partial``.

    A study with no finished sweep under ``out`` keeps its rows from ``published`` (the table
    as last written), so the studies can be run and published on different machines, a few at
    a time, without losing the runs already published.
    """
    frames = []
    for study in STUDIES:
        root = study.directory(out)
        if not root.is_dir():
            continue
        loaded: dict[str, tuple[Mapping[str, Any], dict[str, list[pd.DataFrame]]]]
        if read_grid(root) is None:
            loaded = {"defaults": ({}, load_sweep(root))}
        else:
            loaded = load_cells(root)
        table = compare_cells(loaded, window)
        if len(table) and not partial:
            last = table["generations"].str.endswith(f"-{GENERATIONS - 1}")
            table = table[last & (table["runs"] == len(parse_seeds(SEEDS)))]
        if table.empty:
            continue
        table.insert(0, "study", study.name)
        table.insert(0, "round", study.round)
        frames.append(table)
    pieces = []
    if frames:
        rows = pd.concat(frames, ignore_index=True)
        rows = rows.merge(_rates(out, window), on=["round", "study", "cell", "method"], how="left")
        keys = [c for c in rows.columns if "." in c]
        rows["key"] = rows[keys].notna().idxmax(axis=1).where(rows[keys].notna().any(axis=1))
        rows["value"] = [
            row[row["key"]] if isinstance(row["key"], str) else math.nan
            for _, row in rows.iterrows()
        ]
        pieces.append(rows.drop(columns=[*keys, "cell"]))
    if published is not None:
        fresh = {
            (r, s) for piece in pieces for r, s in zip(piece["round"], piece["study"], strict=True)
        }
        pairs = zip(published["round"], published["study"], strict=True)
        kept = published[[pair not in fresh for pair in pairs]]
        # a single study's reference rows are copies of its round's baseline: derived again below
        kept = kept[(kept["study"] == "baseline") | ~kept["default"].astype(bool)]
        pieces.append(kept.drop(columns="default"))
    if not pieces:
        raise SystemExit(f"no finished calibration sweeps under {out}")
    rows = pd.concat(pieces, ignore_index=True)
    expanded = [rows]
    for study in STUDIES:  # a round's defaults are each of its single studies' reference value
        in_round = rows[rows["round"] == study.round]
        if not study.single or not (in_round["study"] == study.name).any():
            continue
        key = study.grid[0].partition("=")[0]
        base = in_round[
            (in_round["study"] == "baseline") & in_round["method"].isin(study.methods.split(","))
        ].copy()
        base["study"], base["key"], base["value"] = study.name, key, reference(study.round)[key]
        expanded.append(base)
    table = pd.concat(expanded, ignore_index=True)
    single = {(s.round, s.name) for s in STUDIES if s.single}
    table["default"] = [
        study == "baseline" or ((r, study) in single and reference(r)[k] == v)
        for r, study, k, v in zip(
            table["round"], table["study"], table["key"], table["value"], strict=True
        )
    ]
    order = {(s.round, s.name): i for i, s in enumerate(STUDIES)}
    table["_order"] = [order[(r, n)] for r, n in zip(table["round"], table["study"], strict=True)]
    table["_value"] = table["value"].map(lambda v: float(v) if not isinstance(v, str) else 0.0)
    table = table.sort_values(["_order", "_value", "method"]).drop(columns=["_order", "_value"])
    columns = ["round", "study", "key", "value", "default", "method", "runs", "generations"]
    return table[columns + [c for c in table.columns if c not in columns]]


def _label(value: object) -> str:
    """A grid value as a tick label (3.0 → "3")."""
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)


def plot(table: pd.DataFrame, round_: int, out_base: Path) -> list[Path]:
    """One column per study of a round: batteries, matings and completed agents against the
    value."""
    from evolution.lab.figures import METHOD_STYLE, save_figure, styled_pyplot

    plt = styled_pyplot()
    table = table[table["round"] == round_]
    studies = [
        s for s in STUDIES
        if s.round == round_ and s.name != "baseline" and (table["study"] == s.name).any()
    ]  # fmt: skip
    if not studies:
        return []
    rows = [("batteries", "batteries per life"), ("matings", "matings per life"),
            ("completed", "agents completing")]  # fmt: skip
    fig, axes = plt.subplots(
        len(rows), len(studies), figsize=(2.3 * len(studies) + 1, 7.5), squeeze=False,
        sharey="row",
    )  # fmt: skip
    for col, study in enumerate(studies):
        part = table[table["study"] == study.name]
        values = list(dict.fromkeys(part["value"]))
        x = np.arange(len(values))
        for r, (column, label) in enumerate(rows):
            ax = axes[r][col]
            for offset, method in ((-0.1, "ee"), (0.1, "ce")):
                m = part[part["method"] == method].set_index("value").reindex(values)
                if m[column].isna().all():
                    continue
                colour = METHOD_STYLE[method][1]
                ax.errorbar(x + offset, m[column], yerr=m[f"{column}_std"], fmt="o",
                            color=colour, capsize=3, label=method.upper())  # fmt: skip
                if column in ("batteries", "matings"):
                    ax.axhline(PAPER[method][column], color=colour, ls=":", lw=1)
            defaults = part.drop_duplicates("value").set_index("value").reindex(values)["default"]
            marks = ["*" if d else "" for d in defaults]
            labels = [_label(v) + m for v, m in zip(values, marks, strict=True)]
            ax.set_xticks(x, labels, fontsize=8)
            ax.set_xlim(-0.5, len(values) - 0.5)
            ax.grid(axis="y", alpha=0.3)
            if col == 0:
                ax.set_ylabel(label)
            if r == 0:
                ax.set_title("\n".join(textwrap.wrap(study.title, 26)), fontsize=9)
        axes[-1][col].set_xlabel(study.grid[0].partition("=")[0].partition(".")[2], fontsize=8)
    axes[0][0].legend(frameon=False, fontsize=8)
    window = table["generations"].iloc[0]
    around = "the first defaults" if round_ == 1 else "today's defaults"
    fig.suptitle(
        f"Calibration around {around} (seeds {SEEDS}, mean ± std over seeds of each run's mean "
        f"over generations {window}; * the round's default; dotted: the paper's EE and CE)",
        fontsize=10,
    )
    fig.tight_layout()
    return save_figure(fig, out_base)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("runs/calibration"))
    parser.add_argument("--run", action="store_true", help="run (or resume) the sweeps first")
    parser.add_argument("--round", type=int, choices=(1, 2), default=2, help="the round to run")
    parser.add_argument("--only", default=None, help="comma list of the round's studies to run")
    parser.add_argument(
        "--code", type=Path, default=Path("."),
        help="checkout whose package runs the sweeps (round 1: the first defaults' commit)",
    )  # fmt: skip
    parser.add_argument("--window", type=int, default=10, help="final generations per run")
    parser.add_argument(
        "--partial", action="store_true", help="also cells whose runs are still going"
    )
    parser.add_argument(
        "--table", type=Path, default=Path("results/calibration.csv"),
        help="the published table: studies with no sweep under --out keep their rows from it",
    )  # fmt: skip
    parser.add_argument(
        "--figure", type=Path, default=Path("docs/images/calibration"),
        help="figure base name of round 2; round 1's adds _first",
    )  # fmt: skip
    args = parser.parse_args(argv)
    if args.run:
        mine = [s for s in STUDIES if s.round == args.round]
        chosen = args.only.split(",") if args.only else [s.name for s in mine]
        try:
            run_studies([s for s in mine if s.name in chosen], args.out, args.code.resolve())
        except ValueError as error:
            parser.exit(2, f"{parser.prog}: error: {error}\n")
    table = collect(args.out, args.window, args.partial, read_published(args.table))
    args.table.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.table, index=False, float_format="%.4g")
    paths = []
    for round_ in sorted(set(table["round"])):
        base = args.figure.with_name(args.figure.name + ("_first" if round_ == 1 else ""))
        paths += plot(table, round_, base)
    with pd.option_context("display.width", 200, "display.max_rows", 200):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    print("wrote", args.table, *paths)


if __name__ == "__main__":
    main()
