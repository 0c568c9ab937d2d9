"""Plugins (``--plugin``): a user's controller, input or task on every entry point.

The plugin is docs/extending.md §1's "preference" controller, written into a file. Loading is
once per process and hashed; every command takes ``--plugin`` before it checks a setting;
``run.json`` (and a sweep's ``sweep.json`` and ``grid.json``) record each plugin's name, kind and
content hash; ``resume`` reloads the recorded plugins and refuses one that is missing or changed;
sweep workers, local or Ray, load the plugin from its text, so they need no file of it.

A run that uses a plugin's controller compiles the runner's fused step around it in each process
that runs it (not cached on disk); with the reactive behaviours that takes seconds, so the runs
over the plugin's controller use them. Where only the loading, the records and the refusals are
tested, the runs use the paper's controller.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import pickle
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

from cyber_rodent.plugins import (
    MODULE_PREFIX,
    Plugin,
    PluginChanged,
    PluginError,
    PluginMissing,
    PluginSource,
    identify,
    load_plugin,
    loaded_plugins,
    plugin_source,
    plugins_from_records,
)
from evolution.cli import main

#: docs/extending.md §1's controller as a plugin file: three preference genes after the paper's
#: recharge block.
PREFERENCE = '''"""A constant preference per behaviour (docs/extending.md, section 1)."""

from cyber_rodent.backend import jit_built
from evolution.controllers import ControllerSpec, GeneBlock, register_controller
from evolution.kernels import (
    choose,
    choose_reference,
    recharge_decision,
    recharge_decision_reference,
)


def preference(rules, robots, perceived, out):
    start = rules.layout[1, 0]  # where the second block ("preference") starts
    for i in range(out.weights.shape[0]):
        for o in range(3):
            out.activations[i, o] = out.weights[i, start + o]
        choose(i, perceived.behaviour, out)
        out.continue_recharge[i] = recharge_decision(i, rules, robots, out.weights[i], 0)


def preference_reference(rules, robots, perceived, out):
    start = int(rules.layout[1, 0])
    out.activations[...] = out.weights[:, start : start + 3]
    choose_reference(perceived.behaviour, out)
    recharge_decision_reference(rules, robots, out.weights, 0, out.continue_recharge)


def blocks(config, n_inputs):
    return (GeneBlock("recharge", (3,)), GeneBlock("preference", (3,)))


PREFERENCE = ControllerSpec(
    name="preference",
    description="a constant preference per behaviour",
    blocks=blocks,
    decide=jit_built(preference, inline=True),
    decide_reference=preference_reference,
)
register_controller(PREFERENCE)
'''

#: A plugin that adds an input and a task (what ``config`` lists besides controllers).
LAB = '''import dataclasses

from cyber_rodent.tasks.spec import register, task_spec
from evolution.input_kernels import ControllerInput, register_input


def pack_off_nose(i, src, arg):
    return abs(src.perceived.norm_bearing[i, arg] - 0.5) * 2.0


register_input(ControllerInput(
    name="pack_off_nose", reads="perceived.norm_bearing[battery]",
    normalisation="|norm_bearing - 0.5| * 2", low=0.0, high=1.0,
    description="how far off the nose the nearest pack is", read=pack_off_nose, arg=2,
))
register(dataclasses.replace(task_spec("forage"), name="forage_plugin"))
'''

#: Two robots, four agents, short lives (tests/test_experiments.py): a generation in seconds.
TINY = ["population_size=4", "n_robots=2", "lifetime_steps=60", "time_sharing_steps=30"]
TINY_OVERRIDES = {"population_size": 4, "n_robots": 2, "lifetime_steps": 60,
                  "time_sharing_steps": 30}  # fmt: skip
PREFERENCE_SETTING = ["--set", "evolution.controller=preference"]


def tiny_args() -> list[str]:
    return [a for item in TINY for a in ("--set", item)]


def write_plugin(path: Path, text: str = PREFERENCE) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def sha256_of(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def cli(*args: str) -> subprocess.CompletedProcess:
    """The command line in a process of its own (a fresh process loads the plugin anew)."""
    return subprocess.run(
        [sys.executable, "-m", "evolution.cli", *args],
        capture_output=True, text=True, timeout=600,
        env={**os.environ, "LP_NUM_THREADS": "1"},
    )  # fmt: skip


def error_line(capsys: pytest.CaptureFixture[str]) -> str:
    """The one line a refused command printed on stderr."""
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.fixture(autouse=True)
def registries() -> Iterator[None]:
    """Whatever a test's plugins register is removed afterwards (they run in this process)."""
    from cyber_rodent.tasks.spec import task_names, unregister
    from evolution.controllers import controller_names, unregister_controller
    from evolution.input_kernels import available_inputs, unregister_input

    def names() -> tuple[set[str], set[str], set[str]]:
        inputs = {row.name for row in available_inputs()}
        return set(controller_names()), inputs, set(task_names())

    controllers, inputs, tasks = names()
    modules = set(sys.modules)
    yield
    now = names()
    for name in now[0] - controllers:
        unregister_controller(name)
    for name in now[1] - inputs:
        unregister_input(name)
    for name in now[2] - tasks:
        unregister(name)
    for name in set(sys.modules) - modules:
        if name.startswith((MODULE_PREFIX, "plugin_test_")):
            del sys.modules[name]


# --- the loader --------------------------------------------------------------------------------
def test_a_file_loads_once_under_a_stable_name_and_is_hashed(tmp_path: Path) -> None:
    from evolution.controllers import controller_names

    path = write_plugin(tmp_path / "preference.py")
    plugin = load_plugin(str(path))
    assert plugin == Plugin(str(path.resolve()), "file", sha256_of(path))
    assert "preference" in controller_names()
    # Again, by another spelling of the same path: a no-op (a second registration would raise).
    assert load_plugin(os.path.relpath(path)) == plugin
    assert loaded_plugins().count(plugin) == 1
    # The module it runs as: named after its path and content, in sys.modules, so its functions
    # pickle by reference (numba and worker processes find them).
    name = plugin.module_name
    assert name.startswith(f"{MODULE_PREFIX}preference_") and name.endswith(plugin.sha256[:12])
    module = sys.modules[name]
    assert module.preference_reference.__module__ == name
    assert pickle.loads(pickle.dumps(module.preference_reference)) is module.preference_reference
    assert Plugin.from_record(plugin.record()) == plugin
    assert plugins_from_records([plugin.record()]) == (plugin,) and plugins_from_records(None) == ()
    # The same file with other content: refused before it runs, here and where it is expected.
    path.write_text(PREFERENCE + "\n# changed\n")
    with pytest.raises(PluginChanged, match="this process loaded other content"):
        load_plugin(str(path))
    with pytest.raises(PluginChanged, match="changed"):
        load_plugin(str(path), sha256=plugin.sha256)
    assert identify(str(path)).sha256 == sha256_of(path) != plugin.sha256


def test_a_module_is_imported_once_and_hashed_by_its_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from evolution.input_kernels import input_names_allowed

    package = tmp_path / "plugin_test_lab"
    write_plugin(package / "__init__.py", "")
    source = write_plugin(package / "inputs.py", LAB)
    monkeypatch.syspath_prepend(str(tmp_path))
    plugin = load_plugin("plugin_test_lab.inputs")
    assert plugin == Plugin("plugin_test_lab.inputs", "module", sha256_of(source))
    assert plugin.module_name == "plugin_test_lab.inputs"
    assert "pack_off_nose" in input_names_allowed()
    assert load_plugin("plugin_test_lab.inputs") == plugin  # no second registration
    assert plugin_source(plugin).text == LAB
    with pytest.raises(PluginMissing, match="no importable module"):
        load_plugin("plugin_test_lab.nothing_here")


def test_a_plugin_source_loads_the_same_code_where_the_file_is_not(tmp_path: Path) -> None:
    path = write_plugin(tmp_path / "preference.py")
    plugin = load_plugin(str(path))
    source = plugin_source(plugin)
    assert source.plugin == plugin and source.text == PREFERENCE
    with pytest.raises(PluginChanged, match="does not match its hash"):
        PluginSource(plugin.name, plugin.kind, plugin.sha256, PREFERENCE + "#")
    tampered = copy.copy(source)  # as an unpickled task would carry it: no __post_init__
    object.__setattr__(tampered, "text", PREFERENCE + "#")
    with pytest.raises(PluginChanged):
        tampered.load()
    assert source.load() == plugin  # loaded here already: a no-op

    # Another process, without the file: the same module name, the same controller.
    (tmp_path / "source.pickle").write_bytes(pickle.dumps(source))
    path.unlink()
    check = (
        "import pickle, sys\n"
        "from evolution.controllers import CONTROLLERS\n"
        "source = pickle.load(open(sys.argv[1], 'rb'))\n"
        "plugin = source.load()\n"
        "assert source.load() == plugin\n"
        "module = sys.modules[plugin.module_name]\n"
        "assert CONTROLLERS['preference'].decide_reference is module.preference_reference\n"
        "print(plugin.module_name)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", check, str(tmp_path / "source.pickle")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == plugin.module_name


def test_plugin_errors_are_value_errors() -> None:
    """A plugin's failure is the user's to fix: one line from the command line (exit 2)."""
    assert issubclass(PluginMissing, PluginError) and issubclass(PluginChanged, PluginError)
    assert issubclass(PluginError, ValueError)
    with pytest.raises(PluginError, match="neither a module name nor the path"):
        load_plugin("not a module!")
    with pytest.raises(ValueError, match="sha256"):
        Plugin("x.py", "file", "abc")


# --- the command line --------------------------------------------------------------------------
BAD_PLUGINS = {
    "missing file": ("{tmp}/nowhere/preference.py", "no such file"),
    "missing module": ("plugin_test_no_such.module", "no importable module"),
    "not python": ("{tmp}/notes.txt/", "not a .py file"),
    "raises": ("{tmp}/broken.py", "it raised ZeroDivisionError"),
}


#: Every command with every bad plugin; resume only finds and hashes a --plugin (it loads the
#: plugins its run records), so a plugin that raises is not among its cases.
BAD_CASES = [
    (command, case)
    for command in ("evolve", "sweep", "config", "resume")
    for case in sorted(BAD_PLUGINS)
    if (command, case) != ("resume", "raises")
]


@pytest.mark.parametrize("command, case", BAD_CASES)
def test_a_bad_plugin_is_one_line_and_creates_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, case: str
) -> None:
    write_plugin(tmp_path / "broken.py", "x = 1 / 0\n")
    (tmp_path / "notes.txt").mkdir()
    spec, cause = BAD_PLUGINS[case]
    spec = spec.format(tmp=tmp_path)
    out = tmp_path / "out"
    argv = {
        "evolve": ["evolve", "--out", str(out)],
        "sweep": ["sweep", "--out", str(out), "--seeds", "0", "--generations", "1"],
        "config": ["config"],
        "resume": ["resume", str(out)],
    }[command]
    before = sorted(tmp_path.rglob("*"))
    # The plugin's controller named too: the plugin is refused first, not the setting.
    settings = [] if command == "resume" else PREFERENCE_SETTING
    assert main([*argv, "--plugin", spec, *settings]) == 2
    line = error_line(capsys)
    assert line.startswith(f"cyber-rodent {command}: error: --plugin ")
    assert cause in line
    assert sorted(tmp_path.rglob("*")) == before


def test_config_lists_what_plugins_registered(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import tomllib

    preference = write_plugin(tmp_path / "preference.py")
    lab = write_plugin(tmp_path / "lab.py", LAB)
    empty = write_plugin(tmp_path / "empty.py", "")
    argv = ["config", *(a for p in (preference, lab, empty) for a in ("--plugin", str(p)))]
    assert main([*argv, *PREFERENCE_SETTING, "--set", "evolution.inputs=paper,pack_off_nose"]) == 0
    text = capsys.readouterr().out
    listing = text[text.index("# registered by plugins") :].split("\n\n")[0]
    assert f"#   controller preference  (plugin {preference})" in listing
    assert f"#   input pack_off_nose  (plugin {lab})" in listing
    assert f"#   task forage_plugin  (plugin {lab})" in listing
    assert f"#   nothing registered by {empty}" in listing
    parsed = tomllib.loads(text)  # still a valid --config file
    assert parsed["evolution"]["controller"] == "preference"
    assert parsed["evolution"]["inputs"] == "paper,pack_off_nose"
    # Without the plugin the same setting is refused, in one line naming it.
    assert main(["config", "--set", "evolution.controller=no_such_controller"]) == 2
    assert "evolution.controller" in error_line(capsys)


def test_evolve_records_its_plugins_and_resume_checks_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_plugin(tmp_path / "preference.py")
    run = tmp_path / "run"
    base = ["--generations", "1", "--no-progress", *tiny_args()]
    assert main(["evolve", "--out", str(run), "--plugin", str(path), *base]) == 0
    record = json.loads((run / "run.json").read_text())
    plugin = {"name": str(path.resolve()), "kind": "file", "sha256": sha256_of(path)}
    assert record["plugins"] == [plugin]
    plain = tmp_path / "plain"
    assert main(["evolve", "--out", str(plain), *base]) == 0
    assert "plugins" not in json.loads((plain / "run.json").read_text())  # as it always was
    capsys.readouterr()

    # resume --plugin must name the recorded plugins.
    other = write_plugin(tmp_path / "other.py", "")
    assert main(["resume", str(run), "--generations", "2", "--plugin", str(other)]) == 2
    line = error_line(capsys)
    assert "--plugin must name the plugins" in line and str(path.resolve()) in line
    # evolve --resume likewise (here: none given).
    assert main(["evolve", "--out", str(run), "--resume", *base]) == 2
    assert "records the plugins" in error_line(capsys)

    # Its file changed, or gone: refused in one line naming the plugin and saying which.
    path.write_text(PREFERENCE + "\n# changed\n")
    for args in (["resume", str(run)], ["resume", str(run), "--plugin", str(path)]):
        assert main([*args, "--generations", "2", "--no-progress"]) == 2
        line = error_line(capsys)
        assert f"plugin {path.resolve()}, which has changed" in line, line
    path.unlink()
    assert main(["resume", str(run), "--generations", "2", "--no-progress"]) == 2
    line = error_line(capsys)
    assert f"plugin {path.resolve()}, which is missing" in line, line
    assert len(pd.read_csv(run / "statistics.csv")) == 1  # nothing ran

    # Restored: resume continues, and the record keeps its plugin.
    write_plugin(path)
    assert main(["resume", str(run), "--generations", "2", "--no-progress"]) == 0
    assert len(pd.read_csv(run / "statistics.csv")) == 2
    assert json.loads((run / "run.json").read_text())["plugins"] == [plugin]


def test_sweep_workers_load_the_plugin_from_its_text(tmp_path: Path) -> None:
    """Local workers get the plugin's text, not its path: the file is gone before they start."""
    from evolution.lab.api import RunOutput
    from evolution.lab.sweep import Execution, SweepSpec, run_dir, sweep

    path = write_plugin(tmp_path / "preference.py")
    source = plugin_source(load_plugin(str(path)))
    path.unlink()
    spec = SweepSpec(("ee",), (0, 1), 1, TINY_OVERRIDES, policies="reactive", plugins=(source,))
    out = tmp_path / "sweep"
    sweep(spec, RunOutput(out), Execution(workers=2))
    for member in spec.runs:
        record = json.loads((run_dir(out, *member) / "run.json").read_text())
        assert record["plugins"] == [source.plugin.record()]


def test_a_grid_sweep_records_its_plugins_and_resumes_only_with_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_plugin(tmp_path / "preference.py")
    out = tmp_path / "grid"
    args = ["sweep", "--methods", "ee", "--seeds", "0", "--generations", "1", "--workers", "2",
            "--grid", "survival.mate_consecutive_steps=1,2", "--policies", "reactive",
            "--out", str(out), "--no-progress", *tiny_args()]  # fmt: skip
    assert main([*args, "--plugin", str(path)]) == 0
    plugin = {"name": str(path.resolve()), "kind": "file", "sha256": sha256_of(path)}
    assert json.loads((out / "sweep.json").read_text())["plugins"] == [plugin]
    assert json.loads((out / "grid.json").read_text())["plugins"] == [plugin]
    for steps in (1, 2):
        run = out / f"mate_consecutive_steps={steps}" / "ee-seed000" / "run.json"
        assert json.loads(run.read_text())["plugins"] == [plugin]
    capsys.readouterr()
    # Continued without the plugin, or with other content of it: refused before anything runs.
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert main([*args, "--resume"]) == 2
    assert "records the plugins" in error_line(capsys)
    path.write_text(PREFERENCE + "\n# changed\n")
    done = cli(*args, "--resume", "--plugin", str(path))  # a fresh process: it loads anew
    assert done.returncode == 2, done.stderr
    (line,) = done.stderr.splitlines()
    assert "records the plugins" in line and str(path.resolve()) in line
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


# --- the plugin's controller in runs (compiled in every process that runs it) ---------------
def test_evolve_with_the_plugins_controller_and_resume_it(tmp_path: Path) -> None:
    path = write_plugin(tmp_path / "preference.py")
    run = tmp_path / "run"
    args = ["--out", str(run), "--generations", "1", "--no-progress", "--policies", "reactive"]
    assert main(["evolve", "--plugin", str(path), *PREFERENCE_SETTING, *args, *tiny_args()]) == 0
    record = json.loads((run / "run.json").read_text())
    assert record["config"]["evolution"]["controller"] == "preference"
    assert record["settings"]["evolution.controller"] == "preference"
    assert record["plugins"] == [
        {"name": str(path.resolve()), "kind": "file", "sha256": sha256_of(path)}
    ]
    # A fresh process loads the plugin from the record: the checkpoint names its controller.
    done = cli("resume", str(run), "--generations", "2", "--no-progress")
    assert done.returncode == 0, done.stderr
    assert len(pd.read_csv(run / "statistics.csv")) == 2


SWEEP = ["sweep", "--methods", "ee", "--seeds", "0-1", "--generations", "1", "--no-progress",
         "--policies", "reactive", *PREFERENCE_SETTING, *tiny_args()]  # fmt: skip


@pytest.fixture(scope="module")
def one_worker_sweep(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The plugin's file and a sweep over its controller on one local worker."""
    root = tmp_path_factory.mktemp("plugins")
    path = write_plugin(root / "preference.py")
    out = root / "one"
    done = cli(*SWEEP, "--plugin", str(path), "--workers", "1", "--out", str(out))
    assert done.returncode == 0, done.stderr
    return path, out


def results(out: Path) -> dict[str, bytes]:
    """Each run's statistics and event log (dockings, recharges, deaths: what the controller
    decided), by ``<run>/<file>``."""
    found = sorted([*out.glob("*/statistics.csv"), *out.glob("*/events.csv")])
    return {f"{p.parent.name}/{p.name}": p.read_bytes() for p in found}


def test_a_sweep_over_the_plugins_controller_is_the_same_on_two_workers(
    one_worker_sweep: tuple[Path, Path],
) -> None:
    path, one = one_worker_sweep
    two = one.parent / "two"
    done = cli(*SWEEP, "--plugin", str(path), "--workers", "2", "--out", str(two))
    assert done.returncode == 0, done.stderr
    assert sorted(results(one)) == [
        f"ee-seed00{seed}/{name}" for seed in (0, 1) for name in ("events.csv", "statistics.csv")
    ]
    assert results(two) == results(one)
    for run in ("ee-seed000", "ee-seed001"):
        record = json.loads((two / run / "run.json").read_text())
        assert record["config"]["evolution"]["controller"] == "preference"
        assert record["plugins"][0]["sha256"] == sha256_of(path)


@pytest.mark.slow
def test_a_ray_sweep_over_the_plugins_controller_needs_no_file_of_it(
    one_worker_sweep: tuple[Path, Path], tmp_path: Path
) -> None:
    """Ray workers get the plugin's text: the file is gone before the sweep starts."""
    pytest.importorskip("ray")
    from evolution.lab.api import RunOutput
    from evolution.lab.sweep import Execution, SweepSpec, sweep

    original, one = one_worker_sweep
    path = write_plugin(tmp_path / "preference.py")
    source = plugin_source(load_plugin(str(path)))
    path.unlink()
    overrides = {**TINY_OVERRIDES, "evolution.controller": "preference"}
    spec = SweepSpec(("ee",), (0, 1), 1, overrides, policies="reactive", plugins=(source,))
    out = tmp_path / "ray"
    sweep(spec, RunOutput(out), Execution("ray", 2, "local"))
    assert results(out) == results(one)
    record = json.loads((out / "ee-seed000" / "run.json").read_text())
    assert record["plugins"] == [source.plugin.record()]
    assert source.sha256 == sha256_of(original)

