"""``docs/extending.md`` runs: every Python block of the page, in order, and its colony
command; and the survival rule it adds, on a hand-computed pair of robots."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.world import WorldConfig

PAGE = Path(__file__).resolve().parents[1] / "docs" / "extending.md"


def _blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", PAGE.read_text(), flags=re.S)


def test_the_page_has_its_examples() -> None:
    text = PAGE.read_text()
    for heading in ("## 1. Another controller", "## 2. Another controller input",
                    "## 3. Another survival rule", "## 4. A bigger colony"):  # fmt: skip
        assert heading in text
    assert len(_blocks("python")) >= 3


@pytest.mark.parametrize("index", range(len(_blocks("python"))))
def test_every_python_block_runs(index: int) -> None:
    exec(compile(_blocks("python")[index], f"{PAGE.name}[{index}]", "exec"), {})


def test_the_colony_command_runs(tmp_path: Path) -> None:
    """Example 4's command, made short: the same settings with 2 agents per robot and short
    lives, so one generation takes seconds."""
    from evolution.cli import main

    (command,) = _blocks("bash")
    args = command.split()[1:]
    assert args[0] == "evolve" and "evolution.n_robots=16" in args
    assert "world.field_size=4.6" in args and "world.n_packs=20" in args
    out = tmp_path / "colony16"
    args[args.index("--out") + 1] = str(out)
    args[args.index("evolution.population_size=400")] = "evolution.population_size=32"
    short = ["--set", "evolution.lifetime_steps=40", "--set", "evolution.time_sharing_steps=20"]
    assert main([*args, *short]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["config"]["evolution"]["n_robots"] == 16
    assert record["config"]["world"]["field_size"] == 4.6
    assert record["config"]["world"]["n_packs"] == 20
    assert (out / "statistics.csv").read_text().count("\n") >= 2


# --- the survival rule of example 3, by hand ---------------------------------------------------
PORT_FORWARD, PORT_RIGHT = 0.111, 0.02  # IR port offsets (assets/mjcf/cyber_rodent.xml)


def _facing_pair(config: SurvivalConfig, backend: str) -> SurvivalWorld:
    """Two robots facing each other with their IR ports 0.3 m apart (they mate when both
    signal Mate on 2 consecutive steps)."""
    sw = SurvivalWorld(WorldConfig(n_robots=2, n_packs=0), config, backend=backend)
    gap = math.sqrt(0.3**2 - (2 * PORT_RIGHT) ** 2) + 2 * PORT_FORWARD
    sw.world.set_robot_pose(0, -gap / 2, 0.0, 0.0)
    sw.world.set_robot_pose(1, gap / 2, 0.0, math.pi)
    mujoco.mj_forward(sw.world.model, sw.world.data)
    return sw


def _matings(sw: SurvivalWorld, energy: tuple[float, float], steps: int) -> list:
    sw.energy[:] = energy
    yes, wheels = np.ones(2, dtype=bool), np.zeros((2, 2))
    found = []
    for k in range(steps):
        found += [(k, pair) for pair in sw.step(wheels, yes, yes, yes).matings()]
    return found


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_mating_only_above_the_energy_threshold(backend: str) -> None:
    """Threshold 100, one energy unit lost per step, the energy at the start of a step counts:
    a robot starting at 102 signals with 102 and 101 and mates on the second step; one starting
    at 101 signals with 101, then has 100 (not above 100) and never completes the exchange."""
    config = SurvivalConfig(mate_min_energy=100.0)
    assert config.mate_consecutive_steps == 2
    assert _matings(_facing_pair(config, backend), (150.0, 102.0), 2) == [(1, (0, 1))]
    assert _matings(_facing_pair(config, backend), (150.0, 101.0), 5) == []
    # the paper's rule (threshold 0): the same pair mates at 101
    paper = _facing_pair(SurvivalConfig(), backend)
    assert _matings(paper, (150.0, 101.0), 2) == [(1, (0, 1))]


def test_the_threshold_is_a_validated_setting() -> None:
    assert SurvivalConfig().mate_min_energy == 0.0  # the paper's rule
    with pytest.raises(ValueError, match=r"mate_min_energy.*200"):
        SurvivalConfig(mate_min_energy=250.0)
    with pytest.raises(ValueError, match="mate_min_energy"):
        SurvivalConfig(mate_min_energy=-1.0)
