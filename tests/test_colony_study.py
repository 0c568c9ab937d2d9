"""The colony study (benchmarks/colony_study.py): its cells, its run order, resuming, the
mating table read from an event log, and the analysis of published tables."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from benchmarks import colony_study as study
from evolution.agent import Origin
from evolution.lab.grid import Cell
from evolution.lab.sweep import STEPS_PER_LIFE, SweepRun, SweepSpec, run_dir

#: Two and four robots, eight agents, short lives: a run of two generations takes a second.
TINY_ARGS = ["--sizes", "2,4", "--ce-sizes", "4", "--population", "8", "--seeds", "0",
             "--generations", "2", "--set", "evolution.lifetime_steps=40",
             "--set", "evolution.time_sharing_steps=10", "--workers", "1",
             "--no-estimate"]  # fmt: skip


# --- the cells and the order of the runs --------------------------------------------------------
@pytest.mark.parametrize(
    ("n", "field", "packs", "per_robot"),
    [(4, 2.3, 5, 25), (10, 3.636619, 13, 10), (25, 5.75, 31, 4), (50, 8.131728, 63, 2),
     (100, 11.5, 125, 1)],
)  # fmt: skip
def test_each_size_is_the_papers_density_with_100_agents(
    n: int, field: float, packs: int, per_robot: int
) -> None:
    settings = study.cell_settings(n)
    # 2.3 m x sqrt(N / 4); 5 N / 4 packs rounded half up (12.5 -> 13, 31.25 -> 31, 62.5 -> 63)
    assert settings["world.field_size"] == pytest.approx(field, abs=1e-6)
    assert settings["world.n_packs"] == packs
    assert settings["evolution.n_robots"] == n
    assert settings["evolution.population_size"] // n == per_robot
    assert settings["evolution.population_size"] == 100
    # One agent per robot: no time sharing, its one slot is its whole 400-step life (Table 1);
    # otherwise Table 1's 100-step slots.
    if per_robot == 1:
        assert settings["evolution.time_sharing_steps"] == 400
    else:
        assert "evolution.time_sharing_steps" not in settings


def test_one_agent_per_robot_keeps_a_shortened_life_in_one_slot() -> None:
    spec = study.study_spec(overrides={"evolution.lifetime_steps": 40})
    assert spec.settings_of("n100")["evolution.time_sharing_steps"] == 40
    assert "evolution.time_sharing_steps" not in spec.settings_of("n050")


def test_every_cell_validates_and_ce_runs_at_4_and_100_only() -> None:
    spec = study.study_spec()
    spec.check()  # builds every cell's config for each of its methods
    assert [(c.name, spec.methods_of(c)) for c in spec.cells] == [
        ("n004", ("ee", "ce")), ("n010", ("ee",)), ("n025", ("ee",)), ("n050", ("ee",)),
        ("n100", ("ee", "ce")),
    ]  # fmt: skip
    assert spec.generations == 60 and spec.seeds == (0, 1, 2, 3, 4)


def test_runs_go_seed_by_seed_across_every_cell() -> None:
    runs = study.study_spec().runs
    assert len(runs) == 35
    first_seed = [("ee", "n004"), ("ce", "n004"), ("ee", "n010"), ("ee", "n025"),
                  ("ee", "n050"), ("ee", "n100"), ("ce", "n100")]  # fmt: skip
    for seed in range(5):
        assert [(m.method, m.cell) for m in runs[7 * seed : 7 * seed + 7]] == first_seed
        assert {m.seed for m in runs[7 * seed : 7 * seed + 7]} == {seed}


def test_a_sweep_spec_takes_an_explicit_cell_list_with_its_own_methods() -> None:
    cells = (Cell("a", {"evolution.n_robots": 2}, ("ee",)), Cell("b", {"evolution.n_robots": 4}))
    spec = SweepSpec(("ee", "ce"), (0, 1), 2, cell_list=cells)
    assert spec.runs == [SweepRun("ee", 0, "a"), SweepRun("ee", 1, "a"), SweepRun("ee", 0, "b"),
                         SweepRun("ce", 0, "b"), SweepRun("ee", 1, "b"),
                         SweepRun("ce", 1, "b")]  # fmt: skip
    chosen = SweepSpec(("ee", "ce"), (0, 1), 2, cell_list=cells, order="seed",
                       members=(SweepRun("ce", 1, "b"), SweepRun("ee", 0, "b")))  # fmt: skip
    assert chosen.runs == [SweepRun("ee", 0, "b"), SweepRun("ce", 1, "b")]
    assert chosen.settings_of("b") == {"evolution.n_robots": 4}
    with pytest.raises(ValueError, match="a grid or a cell list"):
        SweepSpec(("ee",), (0,), 2, grid=(("evolution.n_robots", (2,)),), cell_list=cells[:1])
    with pytest.raises(ValueError, match="must not repeat"):
        SweepSpec(("ee",), (0,), 2, cell_list=(Cell("a", {}), Cell("a", {})))
    with pytest.raises(ValueError, match="methods of the sweep"):
        SweepSpec(("ee",), (0,), 2, cell_list=(Cell("a", {}, ("ce",)),))
    with pytest.raises(ValueError, match="directory name"):
        SweepSpec(("ee",), (0,), 2, cell_list=(Cell("a/b", {}),))
    with pytest.raises(ValueError, match="members must be runs"):
        SweepSpec(("ee",), (0,), 2, cell_list=cells, members=(SweepRun("ce", 0, "a"),))
    with pytest.raises(ValueError, match="order"):
        SweepSpec(("ee",), (0,), 2, order="random")


def test_bad_settings_exit_2_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "runs"
    for args in (["--sizes", "3", "--ce-sizes", ""], ["--set", "world.n_packs=3"],
                 ["--set", "survival.mate_distance=99"], ["--seeds", "0-x"], ["--workers", "0"],
                 ["--ce-sizes", "10,100", "--sizes", "4,100"]):  # fmt: skip
        assert study.main(["--run", "--out", str(out), *args]) == 2
        error = capsys.readouterr().err
        assert error.startswith("colony_study: error: ") and error.count("\n") == 1, error
    assert not out.exists()


def test_projected_hours_scale_the_measured_step_cost() -> None:
    spec = study.study_spec(sizes=(4, 100), ce_sizes=(100,), seeds=(0,))
    costs = {"n004": {"step_s": 0.001, "build_s": 36.0}, "n100": {"step_s": 0.03, "build_s": 0}}
    hours = study.projected_hours(spec, spec.runs, costs)
    # 60 generations x 25 agents per robot x 400 steps x 1.2 steps per life, 1 ms a step
    assert hours[SweepRun("ee", 0, "n004")] == pytest.approx(
        (60 * 25 * 400 * STEPS_PER_LIFE["ee"] * 0.001 + 36) / 3600
    )
    assert hours[SweepRun("ce", 0, "n100")] == pytest.approx(
        60 * 1 * 400 * STEPS_PER_LIFE["ce"] * 0.03 / 3600
    )


# --- resuming ------------------------------------------------------------------------------------
def test_the_study_publishes_each_run_and_a_rerun_skips_finished_ones(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out, published = tmp_path / "runs", tmp_path / "results"
    paths = ["--out", str(out), "--published", str(published),
             "--figure", str(tmp_path / "figure.png")]  # fmt: skip
    # Only the sweep's callback publishes here, as each run finishes.
    monkeypatch.setattr(study, "publish_finished", lambda *args: [])
    assert study.main(["--run", *paths, *TINY_ARGS]) == 0
    members = [SweepRun("ee", 0, "n002"), SweepRun("ee", 0, "n004"), SweepRun("ce", 0, "n004")]
    for member in members:
        target = run_dir(published, *member)
        for name in ("statistics.csv", "statistics_per_robot.csv", "run.json", "matings.csv"):
            assert (target / name).is_file(), (member, name)
        assert not (target / "events.csv").exists() and not (target / "checkpoints").exists()
    assert (published / "summary.csv").is_file() and (tmp_path / "figure.png").is_file()
    monkeypatch.undo()

    swept: list[SweepSpec] = []
    monkeypatch.setattr(study, "sweep", lambda spec, *args, **kwargs: swept.append(spec))
    assert study.main(["--run", *paths, *TINY_ARGS]) == 0
    assert swept == []  # every run finished: nothing to run
    # A run stopped before its end has no event log yet: it alone runs again (from its
    # checkpoints, which the sweep resumes).
    (run_dir(out, *members[1]) / "events.csv").unlink()
    assert study.main(["--run", *paths, *TINY_ARGS]) == 0
    assert [spec.runs for spec in swept] == [[members[1]]]
    # Another plan in the same directory is refused.
    assert study.main(["--run", *paths, *TINY_ARGS, "--generations", "3"]) == 2


# --- the mating table from an event log ---------------------------------------------------------
#: A hand-made EE log: 2 robots x 2 slots, lives of 4 steps in slots of 2 (see the test).
CONFIG: dict[str, Any] = {"method": "ee", "evolution": {
    "n_robots": 2, "population_size": 4, "lifetime_steps": 4, "time_sharing_steps": 2,
    "fitness_time_unit": 100.0}}  # fmt: skip
EVENTS = [
    (1, 0, "dock", 0, 0, 3),
    (1, 0, "recharge_end", 0, 0, 1),
    (2, 0, "mate", 0, 0, 1), (2, 1, "mate", 0, 0, 0),
    (3, 1, "death", 1, 0, 1), (3, 1, "birth", 1, 0, int(Origin.RANDOM)),
    (5, 0, "mate", 0, 0, 1), (5, 1, "mate", 0, 0, 0), (5, 1, "birth", 0, 1, int(Origin.OFFSPRING)),
    (7, 0, "birth", 1, 1, int(Origin.RANDOM)),
    (8, 0, "birth", 0, 1, int(Origin.OFFSPRING)),
]  # fmt: skip


def events_frame(rows: list[tuple[int, int, str, int, int, int]] = EVENTS) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=["step", "robot", "kind", "slot", "generation", "value"])


def test_the_time_sharing_replays_from_the_log() -> None:
    # Robot 0: slot 0 steps 1-2 (mates at 2), slot 1 steps 3-4, slot 0 step 5 (mates at its age
    # 3), slot 1 steps 6-7 (a full life at 7), slot 0 step 8 (a full life at 8).
    # Robot 1: slot 0 steps 1-2, slot 1 step 3 (dies at age 1), slot 0 steps 4-5 (mates and
    # ends its life at 5).
    ages = study.replay_ages(events_frame(), CONFIG)
    assert ages.tolist() == [1, -1, 2, 2, 1, -1, 3, 4, -1, -1, -1]
    wrong = list(EVENTS)
    wrong[4] = (3, 1, "death", 1, 0, 2)  # a death at an age the replay does not reach
    with pytest.raises(ValueError, match="do not replay"):
        study.replay_ages(events_frame(wrong), CONFIG)


def test_the_mating_table_counts_partners_and_parents_by_hand() -> None:
    table = study.mating_table(events_frame(), CONFIG).set_index("generation")
    row = table.loc[0]
    # generation 0's four initial agents ended (robot 1's replacement in slot 1 lives on)
    assert (row["lives"], row["deaths"], row["full_lives"]) == (4, 1, 3)
    assert (row["mated"], row["matings"], row["completed"], row["positive_fitness"]) == (2, 4, 2, 1)
    assert row["partners_per_life"] == 0.5 and row["partners_per_mated_life"] == 1.0
    assert row["matings_per_mated_life"] == 2.0 and row["repeat_share"] == 0.5
    # each completed agent's fittest (here its only) partner is the other: 2 parents, 2 each
    assert (row["offspring"], row["parents"], row["parents_effective"]) == (2, 2, 2.0)
    assert list(table.index) == [0]  # generation 1's agents have not ended

    # Counted as the statistics do, generation 0 closing when 2 of the 4 slots passed it: robot
    # 1's slot 0 at step 5, robot 0's slot 1 at step 7; robot 0's slot 0 ends later.
    config = {**CONFIG, "evolution": {**CONFIG["evolution"], "ee_close_quorum": 0.5}}
    closed = study.mating_table(events_frame(), config, {0: 7}).set_index("generation").loc[0]
    assert (closed["lives"], closed["deaths"], closed["completed"]) == (3, 1, 1)
    assert (closed["offspring"], closed["parents"], closed["parents_effective"]) == (1, 2, 2.0)
    with pytest.raises(ValueError, match="closed at step 6, 2 slots passed it at step 7"):
        study.mating_table(events_frame(), config, {0: 6})


def test_a_row_closes_in_the_middle_of_its_step() -> None:
    # Two robots with one slot each end a mated life at step 2, robot 0 first: with a quorum of
    # one slot robot 0's full life closes generation 0, and robot 1's is late.
    config: dict[str, Any] = {"method": "ee", "evolution": {
        "n_robots": 2, "population_size": 2, "lifetime_steps": 2, "time_sharing_steps": 2,
        "fitness_time_unit": 100.0, "ee_close_quorum": 0.5}}  # fmt: skip
    rows = [(1, 0, "mate", 0, 0, 1), (1, 1, "mate", 0, 0, 0),
            (2, 0, "birth", 0, 1, int(Origin.OFFSPRING)),
            (2, 1, "birth", 0, 1, int(Origin.OFFSPRING))]  # fmt: skip
    row = study.mating_table(events_frame(rows), config, {0: 2}).set_index("generation").loc[0]
    assert (row["lives"], row["completed"], row["offspring"], row["parents"]) == (1, 1, 1, 2)
    # with a quorum of both slots robot 1's full life closes it: both count
    config["evolution"]["ee_close_quorum"] = 1.0
    row = study.mating_table(events_frame(rows), config, {0: 2}).set_index("generation").loc[0]
    assert (row["lives"], row["completed"], row["offspring"], row["parents"]) == (2, 2, 2, 2)


#: Runs the mating table must agree with: (settings, seed, generations). The first has rows
#: that close in the middle of a step (a later robot's full life at that step is late); the
#: second, short-lived agents with little energy, has deaths and another close quorum (9 of 10).
AGREEING_RUNS = [
    ({"evolution.n_robots": 3, "evolution.population_size": 12, "evolution.lifetime_steps": 60,
      "evolution.time_sharing_steps": 15}, 1, 4),
    ({"evolution.n_robots": 5, "evolution.population_size": 10, "evolution.lifetime_steps": 40,
      "evolution.time_sharing_steps": 10, "evolution.initial_energy": 38}, 2, 2),
]  # fmt: skip


@pytest.mark.parametrize(("settings", "seed", "generations"), AGREEING_RUNS)
def test_the_mating_table_agrees_with_the_scheduler_of_a_run(
    monkeypatch: pytest.MonkeyPatch, settings: dict[str, Any], seed: int, generations: int
) -> None:
    from evolution.lab.api import make_config
    from evolution.runner import EvolutionRunner, default_policies
    from evolution.scheduler import EmbodiedEvolution

    fittest: dict[tuple[int, int, int], float] = {}  # (step, robot, slot) -> partner fitness
    original = EmbodiedEvolution._on_full_life

    def on_full_life(self: EmbodiedEvolution, robot: int, slot: int) -> None:
        partner = self.slots[robot][slot].fittest_partner()
        if partner is not None:
            fittest[(self.steps, robot, slot)] = partner.fitness
        original(self, robot, slot)

    monkeypatch.setattr(EmbodiedEvolution, "_on_full_life", on_full_life)
    config = make_config("ee", **settings)
    with EvolutionRunner(config, seed, default_policies()) as runner:
        statistics = runner.run(generations)
        events = runner.events.to_frame()
    record: dict[str, Any] = json.loads(json.dumps(dataclasses.asdict(config), default=repr))
    closed_at = dict(zip(statistics["generation"], statistics["closed_at_step"], strict=True))
    table = study.mating_table(events, record, closed_at).set_index("generation")
    stats = statistics.set_index("generation")
    for ours, theirs in (("completed", "completed"), ("full_lives", "full_lifetimes"),
                         ("deaths", "deaths"), ("offspring", "reproductions")):  # fmt: skip
        assert table[ours].tolist() == stats[theirs].astype(int).tolist(), ours
    assert fittest and table["parents"].sum() > 0

    # the replayed fitness of each completed agent's fittest partner is the scheduler's
    ages = study.replay_ages(events, record)
    kinds = events["kind"].astype(str).to_numpy()
    k = settings["evolution.population_size"] // settings["evolution.n_robots"]
    life = study.life_ids(events, k)
    docks = pd.Series((kinds == "dock").astype(int)).groupby(life).cumsum().to_numpy()
    fitness_at = {(int(s), int(r)): docks[i] / (ages[i] / 100.0)
                  for i, (s, r) in enumerate(zip(events["step"], events["robot"], strict=True))
                  if kinds[i] == "mate"}  # fmt: skip
    matings = events[kinds == "mate"].assign(life=life[kinds == "mate"])
    for (step, robot, slot), expected in fittest.items():
        own = matings[(matings["robot"] == robot) & (matings["slot"] == slot)
                      & (matings["step"] <= step)]  # fmt: skip
        last = own[own["life"] == own["life"].iloc[-1]]
        best = max(fitness_at[(int(s), int(p))] for s, p in zip(last["step"], last["value"],
                                                                  strict=True))  # fmt: skip
        assert best == pytest.approx(expected), (step, robot, slot)


# --- the analysis of published tables ------------------------------------------------------------
def test_reach_generation_uses_a_trailing_mean_of_five_generations() -> None:
    table = pd.DataFrame({"generation": range(10),
                          "batteries_mean": [0, 10, 20, 20, 20, 20, 20, 20, 20, 20]})
    # trailing means 0, 5, 10, 12.5, 14, then (10 + 4 x 20) / 5 = 18 = 0.9 x 20 at generation 5
    assert study.reach_generation(table, 20.0) == 5
    table.loc[1, "batteries_mean"] = math.nan  # skipped: generation 4's mean is (0 + 60) / 4
    assert study.reach_generation(table, 20.0) == 5
    assert study.reach_generation(table, 30.0) is None
    assert study.reach_generation(table, math.nan) is None


def publish_synthetic(root: Path, n: int, method: str, seed: int, batteries: float,
                      matings: float, partners: float = 1.5) -> None:  # fmt: skip
    """A published run of 60 generations: batteries rise to ``batteries`` at generation 10."""
    run = run_dir(root, method, seed, study.cell_name(n))
    run.mkdir(parents=True)
    generations = np.arange(60)
    statistics = pd.DataFrame({
        "generation": generations,
        "batteries_mean": np.where(generations < 10, 0.0, batteries),
        "matings_mean": matings, "completed": 50 + seed, "full_lifetimes": 90,
        "deaths": 10 - seed, "random_share": 0.1 * seed,
        "closed_at_step": 1000 * (generations + 1),
    })  # fmt: skip
    statistics.to_csv(run / "statistics.csv", index=False)
    pd.DataFrame({"generation": generations, "partners_per_mated_life": partners,
                  "parents": 80.0, "parents_effective": 70.0}).to_csv(run / "matings.csv",
                                                                        index=False)  # fmt: skip
    config = {"method": method, "evolution": {"n_robots": n, "population_size": 100},
              "survival": {"control_dt": 0.2}}  # fmt: skip
    (run / "run.json").write_text(json.dumps({"config": config, "seed": seed}))


def test_the_analysis_of_published_runs_by_hand(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = tmp_path / "results"
    for seed in range(3):
        publish_synthetic(root, 4, "ee", seed, 10.0 + seed, 3.0)
        publish_synthetic(root, 100, "ee", seed, 20.0 + seed, 2.0, partners=1.0 + seed)
        publish_synthetic(root, 100, "ce", seed, 30.0 + seed, 1.0)
    publish_synthetic(root, 4, "ce", 0, 5.0, 4.0)  # a cell with one finished seed
    figure = tmp_path / "figure.png"
    assert study.main(["--out", str(tmp_path / "absent"), "--published", str(root),
                       "--figure", str(figure)]) == 0  # fmt: skip
    assert figure.stat().st_size > 0
    summary = pd.read_csv(root / "summary.csv").set_index(["n_robots", "method"])
    assert summary.loc[(4, "ce"), "runs"] == 1 and summary.loc[(4, "ee"), "runs"] == 3
    assert summary.loc[(4, "ee"), "batteries"] == 11.0
    assert summary.loc[(4, "ee"), "batteries_std"] == 1.0
    assert summary.loc[(100, "ee"), "partners_per_mated_life"] == 2.0
    assert summary.loc[(4, "ee"), "deaths"] == 9.0  # 10, 9, 8
    assert summary.loc[(4, "ee"), "random_share"] == pytest.approx(0.1)  # 0, 0.1, 0.2
    runs = pd.read_csv(root / "runs.csv").set_index(["n_robots", "method", "seed"])
    # batteries jump to their final level at generation 10; the trailing mean of 5 reaches
    # 90 % of it at generation 14 (4 of 5 generations: 80 %; 5 of 5: 100 %)
    assert (runs["reach_generation"] == 14).all()
    assert (runs["first_level"] == 0).all()  # generations 0-4 are all 0
    # the paper colony's level is its cell's (N = 4, same method): EE 11, 90 % of it 9.9; CE 5
    # (one run), 4.5. A trailing mean of 5 over a jump from 0 to b at generation 10 is
    # b (g - 9) / 5 at generation g: EE N=4 (10-12) reaches 9.9 at 14, EE N=100 (20-22) at 12
    # (3/5 x 20 = 12), CE N=4 (5) 4.5 at 14, CE N=100 (30-32) at 10 (30/5 = 6)
    paper = runs.sort_index()
    assert (paper.loc[(4, "ee"), "paper_level"] == 11.0).all()
    assert (paper.loc[(100, "ce"), "paper_level"] == 5.0).all()
    expected = {(4, "ee"): 14, (100, "ee"): 12, (4, "ce"): 14, (100, "ce"): 10}
    for cell, generation in expected.items():
        assert (paper.loc[cell, "reach_paper_generation"] == generation).all(), cell
    assert (runs["reached_paper"] == 1).all()
    # generation 14 closed at world step 15,000: x 4 robots x 0.2 s = 3.33 robot-hours
    hours = runs["reach_robot_hours"]
    assert hours[(4, "ee", 0)] == pytest.approx(15_000 * 4 * 0.2 / 3600, rel=1e-5)
    assert hours[(100, "ee", 0)] == pytest.approx(15_000 * 100 * 0.2 / 3600, rel=1e-5)
    per_generation = runs.loc[(4, "ee", 0), "robot_hours_per_generation"]
    assert per_generation == pytest.approx(1000 * 4 * 0.2 / 3600, rel=1e-5)
    tests = pd.read_csv(root / "tests.csv")
    mann_whitney = tests[tests["test"].str.startswith("mann-whitney")].set_index(["quantity", "a"])
    # EE N=4 (10, 11, 12) below every EE N=100 run (20, 21, 22): U = 0, exact p = 2 / C(6, 3)
    batteries = mann_whitney.loc[("batteries", "EE N=4")]
    assert batteries["statistic"] == 0 and batteries["p_value"] == pytest.approx(0.1)
    assert batteries["test"] == "mann-whitney exact" and batteries["n_b"] == 3
    # EE against CE at N=100: CE higher in every pair
    versus = mann_whitney.loc[("batteries", "EE N=100")]
    assert versus["b"] == "CE N=100" and versus["statistic"] == 0
    # one CE run at N=4: the test has n 1/3
    assert mann_whitney.loc[("batteries", "CE N=4"), "n_a"] == 1
    printed = capsys.readouterr().out
    assert "| 4 | 25 | CE | 1 |" in printed and "| 100 | 1 | EE | 3 |" in printed


def test_the_tests_compare_the_study_sizes_even_before_their_runs_exist() -> None:
    """With N = 100 not published yet, N = 4 is never tested against itself or another N."""
    per_run = pd.DataFrame({
        "method": ["ee", "ee", "ee", "ce"], "n_robots": [4, 4, 10, 4], "seed": [0, 1, 0, 0],
        **{q: [1.0, 2.0, 3.0, 4.0] for q in ("batteries", "matings", "completed", "deaths",
            "reach_generation", "reach_robot_hours", "reach_paper_generation",
            "reach_paper_robot_hours", "partners_per_mated_life", "parents",
            "parents_effective")},
    })  # fmt: skip
    tests = study.test_table(per_run)
    pairs = tests[tests["test"].str.startswith("mann-whitney")]
    assert set(pairs["b"]) <= {"EE N=100", "CE N=100", "CE N=4"}
    assert (pairs.loc[pairs["b"].str.endswith("N=100"), "n_b"] == 0).all()


def test_the_trend_over_n_is_a_permutation_test_not_the_t_approximation() -> None:
    """Three runs in perfect order: 1 of the 6 orderings is as high (and 1 as low), p = 1/3;
    scipy's t approximation would say p = 0."""
    rho, p, kind = study.trend_test(np.array([4.0, 10.0, 25.0]), np.array([3.0, 2.0, 1.0]))
    assert (rho, kind) == (-1.0, "exact") and p == pytest.approx(1 / 3)
    # four in order: 1 of 24 orderings each way, p = 2/24
    assert study.trend_test(np.arange(4.0), np.arange(4.0))[1] == pytest.approx(1 / 12)
    # ties in N take their mean rank: x ranks 1.5, 1.5, 3.5, 3.5 against y ranks 1..4 gives
    # rho = 4 / sqrt(4 x 5); the high pair {3, 4} is 1 of the 6 pairs (4 orderings each) that
    # can face the high N, so p = 2 x 4/24
    rho, p, kind = study.trend_test(np.array([4.0, 4.0, 100.0, 100.0]), np.arange(1.0, 5.0))
    assert rho == pytest.approx(4 / np.sqrt(20)) and p == pytest.approx(1 / 3)
    # 25 runs: the orderings are drawn, with a fixed seed
    x = np.repeat([4.0, 10.0, 25.0, 50.0, 100.0], 5)
    y = np.arange(25.0) % 7
    first, second = study.trend_test(x, y), study.trend_test(x, y)
    assert first == second and first[2] == "permutation"
    assert study.trend_test(np.full(3, 4.0), np.arange(3.0))[2] == "none"


# --- where the robots are -------------------------------------------------------------------------
def test_the_wall_band_share_of_the_field_by_hand() -> None:
    # The paper's 2.3 m field: centres reach 1.15 - 0.14 = 1.01 m either side of the middle;
    # the inner square keeping 0.5 m from the walls has half side 0.65 m.
    assert study.wall_share(1.15, 0.5, 0.14) == pytest.approx(1 - (0.65 / 1.01) ** 2)
    # 11.5 m (N = 100): 1 - (5.25 / 5.61)^2.
    assert study.wall_share(5.75, 0.5, 0.14) == pytest.approx(1 - (5.25 / 5.61) ** 2)
    assert study.wall_share(0.4, 0.5, 0.14) == 1.0  # every reachable point is at a wall
    xy = np.array([[0.0, 0.0], [0.66, 0.0], [0.64, -0.64], [-1.0, 0.2], [0.1, -0.651]])
    assert study.near_wall(xy, 1.15, 0.5).tolist() == [False, True, False, True, True]


def test_the_walls_replay_the_last_generation_of_each_run(tmp_path: Path) -> None:
    out = tmp_path / "runs"
    paths = ["--out", str(out), "--published", str(tmp_path / "results"),
             "--figure", str(tmp_path / "figure.png")]  # fmt: skip
    tiny = [a for a in TINY_ARGS if a not in ("--ce-sizes", "4")]
    tiny[tiny.index("--sizes") + 1] = "4"
    assert study.main(["--run", *paths, *tiny, "--ce-sizes", "", "--walls"]) == 0
    table = pd.read_csv(tmp_path / "results" / study.WALLS_FILE)
    assert table[["cell", "method", "seed", "generation"]].values.tolist() == [["n004", "ee", 0, 1]]
    row = table.iloc[0]
    assert row["field_at_wall"] == pytest.approx(study.wall_share(1.15))
    assert 0 <= row["robots_at_wall"] <= 1 and 0 <= row["packs_at_wall"] <= 1
    assert row["robot_samples"] % 4 == 0 and row["robot_samples"] > 0
    # robots running a random genome and the others split the samples
    random = row["random_genomes"]
    parts = [(random, row["random_at_wall"]), (1 - random, row["others_at_wall"])]
    assert sum(w * share for w, share in parts if w > 0) == pytest.approx(row["robots_at_wall"])
    assert row["active_robots"] == 1.0  # an EE robot always runs an agent
    # A replay that closes the generation elsewhere is refused.
    statistics = run_dir(out, "ee", 0, "n004") / "statistics.csv"
    table = pd.read_csv(statistics)
    table.loc[table.index[-1], "closed_at_step"] += 1
    table.to_csv(statistics, index=False)
    with pytest.raises(study.StudyError, match="the replay closed generation 1"):
        study.sample_walls(run_dir(out, "ee", 0, "n004"))


def test_a_run_that_never_reaches_the_paper_level_is_censored_above_every_other() -> None:
    per_run = pd.DataFrame({
        "method": ["ee"] * 6, "n_robots": [4, 4, 4, 100, 100, 100], "seed": [0, 1, 2] * 2,
        "reach_paper_generation": [10.0, 12.0, 14.0, math.nan, 30.0, math.nan],
    })  # fmt: skip
    for quantity in study.QUANTITIES:  # the other tests' quantities, unused here
        if quantity not in per_run:
            per_run[quantity] = 1.0
    tests = study.test_table(per_run).set_index(["quantity", "a"])
    row = tests.loc[("reach_paper_generation", "EE N=4")]
    # every N=4 run reached it sooner than every N=100 run: U = 0 whichever way the two
    # censored runs rank among themselves; the tie makes it the asymptotic test
    assert row["statistic"] == 0 and row["n_b"] == 3 and row["never_b"] == 2
    assert row["mean_b"] == 30.0 and row["never_a"] == 0  # the mean of those that reached it
    assert row["test"] == "mann-whitney asymptotic"
    trend = tests.loc[("reach_paper_generation", "EE, every N")]
    assert trend["n_a"] == 6 and trend["statistic"] > 0
