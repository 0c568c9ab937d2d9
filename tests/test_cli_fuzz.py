"""Bad input never half-fails: exit status 2, one line on stderr, no traceback, nothing written.

Every case runs the command line in-process (``evolution.cli.main``) inside a directory tree
of prepared inputs (a plain file, an empty directory, someone's notes, a run stopped while
starting, a sweep, run directories that cannot be continued, malformed config files), and the
tree (the working directory included, where default output directories go) must be
byte-for-byte the same afterwards. A few cases also run as a real process, for the exit
status and stderr a shell sees.

The cases are listed per command (:data:`CASES`); a new command adds its own list.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from evolution.cli import main

#: Placeholders of the prepared inputs (see :func:`inputs`), written ``{name}`` in a case.
HUGE = "1000000000000000000000000000000"
MANY_VALUES = ",".join(str(v) for v in range(1, 201))

#: Bad inputs, per command: (argv, a fragment the error line must contain).
CASES: dict[str, list[tuple[list[str], str]]] = {
    "evolve": [
        (["evolve", "--method", "xyz"], "method must be one of ee, ce"),
        (["evolve", "--seed", "abc"], "--seed must be an integer"),
        (["evolve", "--seed", "-1", "--out", "{new}"], "--seed must be an integer in [0"),
        (["evolve", "--generations", "0", "--out", "{new}"], "--generations"),
        (["evolve", "--generations", "1000000000", "--out", "{new}"], "--generations"),
        (["evolve", "--generations", "1.5"], "--generations must be an integer"),
        (["evolve", "--checkpoint-every", "0", "--out", "{new}"], "--checkpoint-every"),
        (["evolve", "--keep-checkpoints", "-1", "--out", "{new}"], "--keep-checkpoints"),
        (["evolve", "--set", f"population_size={HUGE}", "--out", "{new}"], "population_size"),
        (["evolve", "--set", "population_size=100000000", "--out", "{new}"], "[1, 10000]"),
        (["evolve", "--set", "population_size=10", "--out", "{new}"], "divisible"),
        (["evolve", "--set", "population_size=many", "--out", "{new}"], "population_size"),
        (["evolve", "--set", "lifetime_steps=100000000", "--out", "{new}"], "lifetime_steps"),
        (["evolve", "--set", f"time_sharing_steps={HUGE}", "--out", "{new}"], "time_sharing"),
        (
            ["evolve", "--set", "n_robots=1000", "--set", "population_size=1000", "--out", "{new}"],
            "n_robots",
        ),
        (["evolve", "--set", "world.n_packs=500", "--out", "{new}"], "n_packs"),
        (["evolve", "--set", "mutation_probability=2", "--out", "{new}"], "mutation_probability"),
        (["evolve", "--set", "survival.mate_distance=0", "--out", "{new}"], "mate_distance"),
        (["evolve", "--set", "survival.control_dt=nan", "--out", "{new}"], "control_dt"),
        (["evolve", "--set", "max_energy=1e300", "--out", "{new}"], "max_energy"),
        (["evolve", "--set", "no_such_key=1", "--out", "{new}"], "unknown config key"),
        (["evolve", "--set", "survival.bogus=1", "--out", "{new}"], "survival.bogus"),
        (["evolve", "--set", "population_size", "--out", "{new}"], "KEY=VALUE"),
        (["evolve", "--set", "=4", "--out", "{new}"], "KEY=VALUE"),
        (["evolve", "--set", "vision=magic", "--out", "{new}"], "vision"),
        (["evolve", "--set", "camera.view_width=100000", "--out", "{new}"], "view_width"),
        (
            ["evolve", "--set", "vision=rendered", "--set", "camera.height=4096",
             "--set", "camera.view_width=1024", "--out", "{new}"],
            "buffer",
        ),  # fmt: skip
        (["evolve", "--config", "{missing}", "--out", "{new}"], "--config"),
        (["evolve", "--config", "{bad_toml}", "--out", "{new}"], "not valid TOML"),
        (["evolve", "--config", "{unknown_key_toml}", "--out", "{new}"], "unknown config key"),
        (["evolve", "--config", "{wrong_type_json}", "--out", "{new}"], "population_size"),
        (["evolve", "--config", "{empty}", "--out", "{new}"], "--config"),
        (["evolve", "--out", "{file}"], "is a file"),
        (["evolve", "--out", "{notes}"], "not empty"),
        (["evolve", "--out", "{notes}", "--force"], "refusing to delete"),
        (["evolve", "--out", "{new}", "--resume", "--force"], "exclude each other"),
        (["evolve", "--out", "{empty}", "--resume"], "holds no run"),
        (["evolve", "--out", "{started}", "--resume"], "--force"),
        (["evolve", "--out", "{started}"], "--force"),
        (["evolve", "--out", "{file}/run"], "is a file"),
        (["evolve", "--policies", "smart"], "policies must be trained or reactive or a directory"),
        (["evolve", "--bogus-flag"], "unrecognized arguments"),
        (["evolve", "stray"], "unrecognized arguments"),
        (
            ["evolve", "--set", "world.pack_reactivation_steps=-1", "--out", "{new}"],
            "world.pack_reactivation_steps must be an integer in [0, 1000000], got -1",
        ),
        (
            ["evolve", "--set", "learning.alpha_high=2", "--out", "{new}"],
            "learning.alpha_high must be a number in (0, 1], got 2.0",
        ),
        (
            ["evolve", "--set", "learning.epsilon_low=-0.1", "--out", "{new}"],
            "learning.epsilon_low must be a number in [0, 1]",
        ),
        (
            ["evolve", "--set", "learning.alpha_low=0.9", "--out", "{new}"],
            "learning.alpha_low must be <= learning.alpha_high (0.5), got 0.9",
        ),
        (
            ["evolve", "--set", "learning.inheritance=baldwinian", "--out", "{new}"],
            "learning.inheritance must be one of darwinian, lamarckian",
        ),
        (["evolve", "--set", "learning.init=random", "--out", "{new}"], "learning.init"),
        (
            ["evolve", "--set", "learning.enabled=true", "--policies", "reactive", "--out",
             "{new}"],
            "learning mode needs tile-coded behaviours",
        ),  # fmt: skip
        (["evolve", "--max-steps", "0", "--out", "{new}"], "--max-steps"),
        (
            ["evolve", "--set", "reproduction.energy_full=0", "--out", "{new}"],
            "reproduction.energy_full must be a number in (0",
        ),
        (["evolve", "--out", "{new}", "--tensorboard", "{file}"], "--tensorboard"),
        (["evolve", "--out", "{new}", "--tensorboard", "{file}/tb"], "is a file"),
    ],
    "sweep": [
        (["sweep"], "--out"),
        (["sweep", "--out", "{new}", "--max-steps", "-5"], "--max-steps"),
        (
            ["sweep", "--out", "{new}", "--grid", "learning.inheritance=darwinian,x"],
            "learning.inheritance",
        ),
        (["sweep", "--out", "{new}", "--seeds", "9-2"], "seed range"),
        (["sweep", "--out", "{new}", "--seeds", "a"], "seed range"),
        (["sweep", "--out", "{new}", "--seeds", "0-100000000000"], "more than"),
        (["sweep", "--out", "{new}", "--seeds", "1,1"], "twice"),
        (["sweep", "--out", "{new}", "--seeds", ""], "seed range"),
        (["sweep", "--out", "{new}", "--methods", "ee,xx"], "methods"),
        (["sweep", "--out", "{new}", "--methods", "ee,ee"], "methods"),
        (["sweep", "--out", "{new}", "--methods", ","], "methods"),
        (["sweep", "--out", "{new}", "--generations", "0"], "generations"),
        (["sweep", "--out", "{new}", "--generations", "10000000"], "generations"),
        (["sweep", "--out", "{new}", "--workers", "0"], "--workers"),
        (["sweep", "--out", "{new}", "--workers", "x"], "--workers"),
        (["sweep", "--out", "{new}", "--set", "population_size=10"], "divisible"),
        (["sweep", "--out", "{new}", "--set", "mutation_probability=2"], "mutation_probability"),
        (["sweep", "--out", "{new}", "--set", f"population_size={HUGE}"], "population_size"),
        (["sweep", "--out", "{new}", "--grid", "survival.reflex_max_steps"], "KEY=V1,V2"),
        (["sweep", "--out", "{new}", "--grid", "survival.reflex_max_steps=4,x"], "reflex_max"),
        (["sweep", "--out", "{new}", "--grid", "survival.reflex_max_steps=1,8"], "reflex_max"),
        (["sweep", "--out", "{new}", "--grid", "survival.reflex_max_steps=4,4"], "twice"),
        (["sweep", "--out", "{new}", "--grid", "nokey=1,2"], "unknown config key"),
        (["sweep", "--out", "{new}", "--grid", "camera.min_blob_area=1,2"], "grid axis"),
        (
            ["sweep", "--out", "{new}", "--grid", "survival.mate_distance=0.3,0.4",
             "--grid", "survival.mate_distance=0.5"],
            "already a grid axis",
        ),  # fmt: skip
        (
            ["sweep", "--out", "{new}", "--seeds", "0-99",
             "--grid", f"survival.mate_consecutive_steps={MANY_VALUES}"],
            "at most",
        ),  # fmt: skip
        (["sweep", "--out", "{new}", "--seeds", "0-1", "--ray", "127.0.0.1:1"], "Ray"),
        (["sweep", "--out", "{new}", "--seeds", "0-1", "--ray", "auto"], "Ray"),
        (["sweep", "--out", "{new}", "--ray", "not an address"], "Ray address"),
        (["sweep", "--out", "{file}"], "is a file"),
        (["sweep", "--out", "{notes}"], "not empty"),
        (["sweep", "--out", "{notes}", "--force"], "refusing to delete"),
        (["sweep", "--out", "{empty}", "--resume"], "no sweep"),
        (["sweep", "--out", "{new}", "--policies", "x"], "policies must be trained or reactive"),
        (["sweep", "--out", "{new}", "--config", "{bad_toml}"], "not valid TOML"),
        (["sweep", "--out", "{new}", "--tensorboard", "{file}"], "--tensorboard"),
        (["sweep", "--out", "{new}", "--tensorboard", "{file}/tb"], "is a file"),
    ],
    "resume": [
        (["resume"], "required"),
        (["resume", "{missing}"], "no such run directory"),
        (["resume", "{file}"], "is a file"),
        (["resume", "{empty}"], "not a run directory"),
        (["resume", "{notes}"], "not a run directory"),
        (["resume", "{sweep}"], "sweep --resume"),
        (["resume", "{started}"], "--force"),
        (["resume", "{alien_run}"], "not installed"),
        (["resume", "{list_run}"], "--force"),
        (["resume", "{empty_record_run}"], "malformed"),
        (["resume", "{alien_run}", "--generations", "0"], "--generations"),
        (["resume", "{alien_run}", "--generations", "x"], "--generations"),
        (["resume", "{alien_run}", "--tensorboard", "{file}/tb"], "--tensorboard"),
    ],
    "plot": [
        (["plot"], "required"),
        (["plot", "{missing}"], "is not a run or sweep directory"),
        (["plot", "{file}"], "is a file"),
        (["plot", "{empty}"], "no statistics.csv"),
        (["plot", "{notes}"], "no statistics.csv"),
        (["plot", "{empty}", "--out", "{file}"], "is a file"),
        (["plot", "{bad_grid}"], "grid.json: not a grid record"),
    ],
    "render": [
        (["render"], "--out"),
        (["render", "--out", "{root}/video.mp4"], "run directory"),
        (["render", "{empty}", "--out", "{root}/video.mp4", "--frames", "0"], "--frames"),
        (["render", "{empty}", "--out", "{root}/video.mp4", "--frames", "abc"], "--frames"),
        (["render", "{empty}", "--out", "{root}/video.mp4", "--fps", "0"], "fps"),
        (["render", "{empty}", "--out", "{root}/video.avi"], ".mp4"),
        (["render", "{empty}", "--out", "{missing}/video.mp4"], "does not exist"),
        (["render", "{empty}", "--out", "{root}/video.mp4"], "checkpoint"),
        (["render", "--checkpoint", "{not_a_checkpoint}", "--out", "{root}/v.mp4"], "checkpoint"),
        (["render", "{missing}", "--out", "{root}/video.mp4"], "{missing}"),
        (
            ["render", "{empty}", "--checkpoint", "{not_a_checkpoint}", "--out", "{root}/v.mp4"],
            "one of them",
        ),
    ],
    "transfer": [
        (["transfer"], "required"),
        (["transfer", "--from", "{missing}", "--out", "{new}"], "--from"),
        (["transfer", "--from", "{file}", "--out", "{new}"], "is a file"),
        (["transfer", "--from", "{empty}", "--out", "{new}"], "not a run directory"),
        (["transfer", "--from", "{alien_run}", "--out", "{new}"], "no checkpoint of generation"),
        (["transfer", "--from", "{alien_run}", "--out", "{file}"], "is a file"),
        (["transfer", "--from", "{alien_run}", "--out", "{new}", "--top", "0"], "--top"),
        (["transfer", "--from", "{alien_run}", "--out", "{new}", "--robots", "0"], "--robots"),
        (["transfer", "--from", "{alien_run}", "--out", "{new}", "--robots", "1000"], "--robots"),
        (
            ["transfer", "--from", "{alien_run}", "--out", "{new}", "--agents-per-robot", "0"],
            "--agents-per-robot",
        ),
        (
            ["transfer", "--from", "{alien_run}", "--out", "{new}", "--agents-per-robot", HUGE],
            "--agents-per-robot",
        ),
        (["transfer", "--from", "{alien_run}", "--out", "{new}", "--generations", "0"], "gener"),
        (["transfer", "--from", "{alien_run}", "--out", "{new}", "--generation", "-1"], "gener"),
        (["transfer", "--from", "{alien_run}", "--out", "{new}", "--seed", "-5"], "--seed"),
        (["transfer", "--from", "{alien_run}", "--out", "{new}", "--profile", "mars"],
         "--profile must be one of sim, hardware or a profile file"),
    ],
    "view": [
        (["view"], "one of"),
        (["view", "--task", "nope"], "--task"),
        (["view", "{missing}"], "{missing}"),
        (["view", "{file}"], "{file}"),
        (["view", "{empty}"], "run.json"),
        (["view", "--checkpoint", "{not_a_checkpoint}"], "checkpoint"),
        (["view", "--checkpoint", "{missing}"], "{missing}"),
        (["view", "--task", "forage", "--seconds", "-1"], "--seconds"),
        (["view", "--task", "forage", "--seconds", "abc"], "--seconds"),
        (["view", "--task", "forage", "--speed", "0"], "--speed"),
        (["view", "--task", "forage", "--seed", "-3"], "--seed"),
        (["view", "--task", "forage", "{empty}"], "one of"),
        (["view", "--task", "forage", "--screenshot", "{root}/shot.png"], "--seconds"),
        (
            ["view", "--task", "forage", "--screenshot", "{missing}/s.png", "--seconds", "1"],
            "{missing}",
        ),
    ],
    "deploy": [
        (["deploy"], "required"),
        (["deploy", "--from", "{missing}", "--out", "{new}"], "--from"),
        (["deploy", "--from", "{empty}", "--out", "{new}"], "not a run directory"),
        (["deploy", "--from", "{alien_run}", "--out", "{new}", "--top", "0"], "--top"),
        (["deploy", "--from", "{alien_run}", "--out", "{notes}"], "--out"),
    ],
    "export": [
        (["export"], "required"),
        (["export", "--out", "{new}", "--values", "{missing}"], "--values"),
        (["export", "--out", "{new}", "--values", "{empty}"], "mate.npz"),
        (["export", "--out", "{file}"], "--out"),
    ],
}

#: Cases also run as a real process (command, index in its list).
SUBPROCESS_CASES = [
    ("evolve", 1), ("evolve", 8), ("sweep", 24), ("resume", 5), ("plot", 1), ("view", 1),
    ("deploy", 3),
]  # fmt: skip


def inputs(root: Path) -> dict[str, str]:
    """Prepare the inputs under ``root``; their paths by placeholder name."""
    paths = {name: root / name for name in (
        "empty", "notes", "started", "sweep", "alien_run", "list_run", "empty_record_run",
        "bad_grid",
    )}  # fmt: skip
    for path in paths.values():
        path.mkdir()
    (paths["notes"] / "notes.txt").write_text("mine")
    command = ["cyber-rodent", "evolve", "--out", str(paths["started"])]
    (paths["started"] / "versions.json").write_text(json.dumps({"command": command}))
    (paths["started"] / "run.json").write_text('{"config": {"method": "e')  # cut short
    sweep = ["cyber-rodent", "sweep", "--seeds", "0-1", "--out", str(paths["sweep"])]
    (paths["sweep"] / "sweep.json").write_text(json.dumps({"command": sweep}))
    record = {"policies": "not-installed", "seed": 0, "target_generations": 5, "config": {}}
    (paths["alien_run"] / "run.json").write_text(json.dumps(record))
    (paths["list_run"] / "run.json").write_text("[]")
    (paths["empty_record_run"] / "run.json").write_text("{}")
    (paths["bad_grid"] / "grid.json").write_text('{"grid": [["survival.mate_distance"')
    files = {
        "file": "a plain file",
        "bad_toml.toml": "population_size = = 3",
        "unknown_key_toml.toml": "[survival]\nno_such_rule = 1\n",
        "wrong_type_json.json": '{"population_size": "many"}',
        "not_a_checkpoint.ckpt": "not a checkpoint",
    }
    for name, text in files.items():
        (root / name).write_text(text)
        paths[name.partition(".")[0]] = root / name
    paths["missing"] = root / "missing"
    paths["new"] = root / "new"
    paths["root"] = root
    return {name: str(path) for name, path in paths.items()}


def tree(root: Path) -> dict[str, str]:
    """Every path under ``root`` with a digest of its content ("dir" for a directory)."""
    found = {}
    for path in sorted(root.rglob("*")):
        rel = str(path.relative_to(root))
        found[rel] = "dir" if path.is_dir() else hashlib.sha256(path.read_bytes()).hexdigest()
    return found


ALL_CASES = [(command, i) for command, cases in CASES.items() for i in range(len(cases))]


@pytest.fixture(scope="module")
def prepared(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    root = tmp_path_factory.mktemp("fuzz")
    (root / "cwd").mkdir()  # where default output directories (runs/...) would appear
    return inputs(root)


@pytest.fixture()
def no_ray_cluster(monkeypatch: pytest.MonkeyPatch) -> None:
    # --ray auto resolves RAY_ADDRESS first: point it nowhere, whatever runs on this machine.
    monkeypatch.setenv("RAY_ADDRESS", "127.0.0.1:1")


def _argv(command: str, index: int, paths: dict[str, str]) -> tuple[list[str], str]:
    argv, fragment = CASES[command][index]
    return [a.format(**paths) for a in argv], fragment.format(**paths)


def test_enough_distinct_bad_inputs() -> None:
    distinct = {tuple(argv) for cases in CASES.values() for argv, _ in cases}
    assert len(distinct) == len(ALL_CASES)
    assert {"evolve", "sweep", "resume", "plot", "render", "transfer", "view"} <= set(CASES)
    print(f"{len(ALL_CASES)} bad inputs across {', '.join(CASES)}")
    assert len(ALL_CASES) >= 60


@pytest.mark.parametrize("command, index", ALL_CASES, ids=[f"{c}-{i}" for c, i in ALL_CASES])
@pytest.mark.usefixtures("no_ray_cluster")
def test_bad_input_is_one_line_and_writes_nothing(
    command: str,
    index: int,
    prepared: dict[str, str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    root = Path(prepared["root"])
    monkeypatch.chdir(root / "cwd")
    argv, fragment = _argv(command, index, prepared)
    before = tree(root)
    try:
        status = main(argv)
    except SystemExit as exit_:  # the parser must not exit on its own
        status = exit_.code if isinstance(exit_.code, int) else 1
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert status == 2, err
    assert len(lines) == 1 and lines[0].strip(), err
    assert lines[0].startswith(f"cyber-rodent {command}: error: "), lines[0]
    assert fragment in lines[0], lines[0]
    assert "Traceback" not in err
    assert tree(root) == before


@pytest.mark.parametrize("command, index", SUBPROCESS_CASES)
@pytest.mark.usefixtures("no_ray_cluster")
def test_bad_input_as_a_process(command: str, index: int, prepared: dict[str, str]) -> None:
    root = Path(prepared["root"])
    argv, fragment = _argv(command, index, prepared)
    before = tree(root)
    result = subprocess.run(
        [sys.executable, "-m", "evolution.cli", *argv],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=root / "cwd",
        env={**os.environ, "RAY_ADDRESS": "127.0.0.1:1"},
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and f"cyber-rodent {command}: error: " in lines[0], result.stderr
    assert fragment in lines[0]
    assert tree(root) == before
