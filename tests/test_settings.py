"""Settings by dotted key: --set, --config, --grid and the `config` command's TOML."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pandas as pd
import pytest

from cyber_rodent.survival import SurvivalConfig
from cyber_rodent.world import WorldConfig
from evolution.config import (
    CtrnnConfig,
    EvolutionConfig,
    GeneticConfig,
    LearningConfig,
    ReproductionConfig,
)
from evolution.lab.api import make_config
from evolution.lab.cells import compare_cells, run_final_means
from evolution.lab.grid import Cell, cells
from evolution.runner import RunConfig
from evolution.runner.settings import (
    FLAT_KEYS,
    SHARED_KEYS,
    apply,
    canonical_key,
    changed,
    load_config_file,
    merge,
    parse_grid,
    parse_set,
    settings,
    to_toml,
)


def test_every_field_of_every_section_is_a_key() -> None:
    keys = settings()
    sections = {
        "evolution": EvolutionConfig,
        "genetic": GeneticConfig,
        "survival": SurvivalConfig,
        "world": WorldConfig,
        "learning": LearningConfig,
        "reproduction": ReproductionConfig,
        "ctrnn": CtrnnConfig,
    }
    for prefix, cls in sections.items():
        default = cls()
        for f in dataclasses.fields(cls):
            if not dataclasses.is_dataclass(getattr(default, f.name)):  # nested: own sections
                assert f"{prefix}.{f.name}" in keys
    for key in ("camera.height", "camera.noise.dropout", "camera.led.hue_low", "vision"):
        assert key in keys
    # Each setting carries its meaning, allowed range and source.
    mate = keys["survival.mate_distance"]
    assert mate.kind is float and mate.default == 0.35
    assert mate.allowed.startswith("number in (0,") and "IR port-to-port" in mate.meaning
    assert keys["evolution.lifetime_steps"].source == "paper Table 1"
    assert keys["evolution.lifetime_steps"].unit == "control steps"


def test_flat_keys_of_earlier_versions_name_dotted_keys() -> None:
    assert FLAT_KEYS["population_size"] == "evolution.population_size"
    assert FLAT_KEYS["crossover_probability"] == "genetic.crossover_probability"
    assert FLAT_KEYS["n_packs"] == "world.n_packs"
    assert canonical_key("vision") == "vision"
    assert canonical_key(" survival.mate_distance ") == "survival.mate_distance"


def test_unknown_keys_name_the_closest_valid_keys() -> None:
    with pytest.raises(ValueError, match=r"unknown config key 'survival.mate_distnce'; "
                       r"closest: survival.mate_distance"):  # fmt: skip
        canonical_key("survival.mate_distnce")
    # A known field name in the wrong section points at the right one.
    with pytest.raises(ValueError, match=r"closest: .*survival.mate_distance"):
        canonical_key("world.mate_distance")
    with pytest.raises(ValueError, match=r"key 'survival.bogus'.*cyber-rodent config"):
        canonical_key("survival.bogus")


def test_set_parses_each_type_and_names_the_range_on_bad_text() -> None:
    values = parse_set([
        "survival.mate_distance=0.4", "survival.mate_consecutive_steps=3",
        "survival.decay_while_recharging=yes", "vision=rendered", "camera.min_blob_area=1,2,2",
        "population_size=20",
    ])  # fmt: skip
    assert values == {
        "survival.mate_distance": 0.4,
        "survival.mate_consecutive_steps": 3,
        "survival.decay_while_recharging": True,
        "vision": "rendered",
        "camera.min_blob_area": (1, 2, 2),
        "evolution.population_size": 20,
    }
    assert parse_set(["survival.mate_distance=0.4", "survival.mate_distance=0.3"]) == {
        "survival.mate_distance": 0.3  # a later --set wins
    }
    with pytest.raises(ValueError, match=r"survival.mate_consecutive_steps must be an integer "
                       r"in \[1, 1000000\], got '2.5'"):  # fmt: skip
        parse_set(["survival.mate_consecutive_steps=2.5"])
    with pytest.raises(ValueError, match="survival.decay_while_recharging must be true or false"):
        parse_set(["survival.decay_while_recharging=maybe"])
    with pytest.raises(ValueError, match=r"survival.mate_distance must be a number .* got 'inf'"):
        parse_set(["survival.mate_distance=inf"])
    with pytest.raises(ValueError, match="use KEY=VALUE"):
        parse_set(["survival.mate_distance"])


def test_apply_changes_exactly_the_named_fields() -> None:
    base = RunConfig()
    config = apply(base, {
        "survival.mate_distance": 0.4, "genetic.mutation_probability": 0.2,
        "evolution.lifetime_steps": 300, "world.n_packs": 3, "camera.noise.dropout": 0.1,
        "vision": "rendered",
    })  # fmt: skip
    assert config.survival.mate_distance == 0.4
    assert config.evolution.genetics.mutation_probability == 0.2
    assert config.evolution.lifetime_steps == 300 and config.world.n_packs == 3
    assert config.camera.noise.dropout == 0.1 and config.vision == "rendered"
    assert config.camera.height == base.camera.height  # untouched fields keep their values
    assert changed(config) == {
        "vision": "rendered",
        "evolution.lifetime_steps": 300,
        "genetic.mutation_probability": 0.2,
        "survival.mate_distance": 0.4,
        "world.n_packs": 3,
        "camera.noise.dropout": 0.1,
    }
    assert changed(base) == {}


def test_shared_numbers_are_one_setting() -> None:
    for alias, key in SHARED_KEYS.items():
        assert canonical_key(alias) == alias and canonical_key(key) == key
    config = make_config("ee", **{"survival.max_energy": 300.0})
    assert config.evolution.max_energy == config.survival.max_energy == 300.0
    config = make_config("ee", **{"world.n_robots": 2, "evolution.population_size": 10})
    assert config.evolution.n_robots == config.world.n_robots == 2
    assert merge({"survival.max_energy": 300.0}) == {"evolution.max_energy": 300.0}


def test_errors_name_the_dotted_key() -> None:
    cases = {
        "survival.mate_distance": (9.0, r"survival.mate_distance must be a number in \(0, "),
        "survival.reflex_max_steps": (1, r"survival.reflex_max_steps must be an integer in \[2,"),
        "genetic.crossover_probability": (2.0, r"genetic.crossover_probability must be a number"),
        "genetic.tournament_size": (500, r"genetic.tournament_size must be an integer in \[1, 1"),
        "evolution.population_size": (10, r"evolution.population_size \(10\) must be divisible"),
        "camera.noise.dropout": (2.0, r"camera.noise.dropout must be a number in \[0, 1\]"),
    }
    for key, (value, message) in cases.items():
        with pytest.raises(ValueError, match=message):
            make_config("ee", **{key: value})


def test_config_toml_is_a_valid_config_file_that_reproduces_the_config(tmp_path: Path) -> None:
    config = make_config("ce", **{"survival.mate_distance": 0.4, "camera.noise.dropout": 0.05})
    text = to_toml(config, method="ce")
    assert "[survival]" in text and "[camera.noise]" in text and "mate_distance = 0.4" in text
    # Every key is commented with its allowed values and its source.
    lifetime = (
        "# integer in [1, 1000000] · unit: control steps · source: paper Table 1\nlifetime_steps"
    )
    assert lifetime in text
    assert "source: paper Table 1 · same number as survival.max_energy\nmax_energy = 200.0" in text
    path = tmp_path / "config.toml"
    path.write_text(text)
    loaded = load_config_file(path)
    assert apply(RunConfig(method="ce"), loaded) == config


def test_config_files_take_sections_dotted_and_flat_keys(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(
        'population_size = 20\n"world.n_packs" = 3\n[survival]\nmate_distance = 1\n'
        "[camera.noise]\ndropout = 0.5\n"
    )
    assert load_config_file(path) == {
        "evolution.population_size": 20,
        "world.n_packs": 3,
        "survival.mate_distance": 1.0,  # a TOML integer is a valid number
        "camera.noise.dropout": 0.5,
    }
    json_path = tmp_path / "c.json"
    json_path.write_text(json.dumps({"survival": {"mate_consecutive_steps": 2}}))
    assert load_config_file(json_path) == {"survival.mate_consecutive_steps": 2}
    bad = {
        "[survival]\nbogus = 1\n": "unknown config key 'survival.bogus'",
        "[survival]\nmate_consecutive_steps = 1.5\n": "survival.mate_consecutive_steps must be",
        "[survival]\nmax_energy = 300.0\n[evolution]\nmax_energy = 200.0\n": "contradicts",
        "[survival\n": "not valid TOML",
    }
    for text, message in bad.items():
        path.write_text(text)
        with pytest.raises(ValueError, match=message):
            load_config_file(path)


def test_grid_parsing_and_cells() -> None:
    grid = parse_grid(["survival.reflex_max_steps=4,8,16", "survival.mate_consecutive_steps=1,3"])
    assert grid == (
        ("survival.reflex_max_steps", (4, 8, 16)),
        ("survival.mate_consecutive_steps", (1, 3)),
    )
    found = cells(grid)
    assert len(found) == 6
    assert found[0] == Cell(
        "reflex_max_steps=4,mate_consecutive_steps=1",
        {"survival.reflex_max_steps": 4, "survival.mate_consecutive_steps": 1},
    )
    assert found[-1].name == "reflex_max_steps=16,mate_consecutive_steps=3"
    # Two axes with one field name are told apart by their full keys.
    same = cells((("evolution.initial_energy", (100.0,)), ("camera.noise.dropout", (0.1,))))
    assert same[0].name == "initial_energy=100.0,dropout=0.1"
    for bad, message in {
        "survival.reflex_max_steps": "use KEY=V1,V2",
        "survival.reflex_max_steps=": "use KEY=V1,V2",
        "survival.reflex_max_steps=4,,8": "use KEY=V1,V2",
        "survival.reflex_max_steps=4,4": "a value appears twice",
        "survival.reflex_max_steps=4,x": "survival.reflex_max_steps must be an integer",
        "camera.min_blob_area=1": "cannot be a grid axis",
        "survival.nope=1": "unknown config key",
    }.items():
        with pytest.raises(ValueError, match=message):
            parse_grid([bad])
    with pytest.raises(ValueError, match="already a grid axis"):
        parse_grid(["survival.mate_distance=0.3", "survival.mate_distance=0.4"])


def _table(batteries: list[float], matings: list[float], completed: list[int]) -> pd.DataFrame:
    return pd.DataFrame({
        "generation": range(len(batteries)), "batteries_mean": batteries,
        "matings_mean": matings, "completed": completed,
    })  # fmt: skip


def test_cell_comparison_by_hand() -> None:
    # Window 2: each run's mean over its last two generations, NaN rows skipped.
    a = _table([1.0, 4.0, 6.0], [1.0, 1.0, 3.0], [5, 6, 8])  # means 5, 2, 7
    b = _table([0.0, math.nan, 8.0], [0.0, 2.0, 2.0], [1, 2, 4])  # means 8, 2, 3
    assert run_final_means(b, "batteries_mean", 2) == 8.0
    loaded = {"x=1": ({"survival.x": 1}, {"ee": [a, b], "ce": [a]})}
    table = compare_cells(loaded, window=2).set_index("method")
    assert table.loc["ee", "batteries"] == 6.5
    assert math.isclose(table.loc["ee", "batteries_std"], math.sqrt(4.5))  # ddof = 1
    assert table.loc["ee", "matings"] == 2.0 and table.loc["ee", "matings_std"] == 0.0
    assert table.loc["ee", "completed"] == 5.0 and table.loc["ee", "runs"] == 2
    assert table.loc["ee", "generations"] == "1-2" and table.loc["ee", "survival.x"] == 1
    assert table.loc["ce", "batteries"] == 5.0 and math.isnan(table.loc["ce", "batteries_std"])


def test_the_field_size_is_a_key_and_the_camera_range_follows_it() -> None:
    setting = settings()["world.field_size"]
    assert (setting.default, setting.unit, setting.allowed) == (2.3, "m", "number in [0.5, 50]")
    # A 4.6 m field: the camera sees to its diagonal, 4.6 m x sqrt(2) = 6.5054 m.
    wide = apply(RunConfig(), {"world.field_size": 4.6})
    assert wide.world.field_size == 4.6
    assert wide.camera.max_range == pytest.approx(6.5054, abs=1e-4)
    assert RunConfig(world=WorldConfig(field_size=4.6)).camera == wide.camera
    assert changed(wide) == {"world.field_size": 4.6, "camera.max_range": wide.camera.max_range}
    # A range set by hand is kept, in whichever order the two keys come.
    for values in (
        {"world.field_size": 4.6, "camera.max_range": 5.0},
        {"camera.max_range": 5.0, "world.field_size": 4.6},
    ):
        assert apply(RunConfig(), values).camera.max_range == 5.0
    assert "field_size = 4.6" in to_toml(wide)
    with pytest.raises(ValueError, match=r"world.field_size must be a number in \[0.5, 50\]"):
        apply(RunConfig(), {"world.field_size": 0.2})


def test_a_colony_and_its_field_grow_in_one_set_of_settings() -> None:
    """``evolution.n_robots`` and the world's field change together: 100 robots do not fit the
    paper's 2.3 m field, but do fit the 11.5 m field set beside them."""
    from evolution.runner import RunConfig
    from evolution.runner.settings import apply

    config = apply(
        RunConfig(),
        {"evolution.n_robots": 100, "evolution.population_size": 100,
         "world.field_size": 11.5, "world.n_packs": 125},
    )  # fmt: skip
    assert (config.evolution.n_robots, config.world.n_robots) == (100, 100)
    assert (config.world.field_size, config.world.n_packs) == (11.5, 125)
    with pytest.raises(ValueError, match="n_robots"):
        apply(RunConfig(), {"evolution.n_robots": 100, "evolution.population_size": 100})
