"""Checkpoints: plain versioned state, atomic writes, verified loads that never run code,
exact round trips of every state, bit-identical resume."""

from __future__ import annotations

import hashlib
import json
import math
import os
import pickle
import re
import signal
import struct
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from behaviours import BehaviourPolicies
from cyber_rodent.atomic import TEMP_MARK, remove_stale_temporaries
from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.world import WorldConfig
from evolution.agent import GenomePool, MatingRecord, Origin, VirtualAgent, genomes_from_array
from evolution.checkpoint import (
    ARRAY_DTYPES,
    FORMAT_VERSION,
    MAGIC,
    CheckpointError,
    config_fingerprint,
    load_checkpoint,
    read_header,
    save_checkpoint,
)
from evolution.cli import main as cli_main
from evolution.config import EvolutionConfig, GeneticConfig
from evolution.genome import Genome
from evolution.runner import EventLog, EvolutionRunner, policy_identity
from evolution.runner.world_state import (
    DERIVED_FIELDS,
    INTEGRATION,
    load_physics_state,
    physics_state,
)
from evolution.scheduler import (
    NO_PARTNER,
    CentralisedEvolution,
    EmbodiedEvolution,
    LifeRecord,
    TimeSharingScheduler,
)
from evolution.stats import StatisticsRecorder

REACTIVE = BehaviourPolicies.reactive()


class _Events:
    """Seeded random events (captures, deaths from the energy arithmetic, matings)."""

    def __init__(self, n: int, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.energy = np.zeros(n)
        self.partner = np.full(n, NO_PARTNER)

    def step(self, scheduler: TimeSharingScheduler) -> None:
        switched = scheduler.switched
        self.energy[switched] = scheduler.active_energy[switched]
        n = len(self.energy)
        captured = self.rng.random(n) < 0.02
        self.energy += np.where(captured, 60.0, -1.0)
        np.minimum(self.energy, 200.0, out=self.energy)
        died = self.energy <= 0.0
        self.energy[died] = 0.0
        self.partner[:] = NO_PARTNER
        if self.rng.random() < 0.03:
            a, b = self.rng.choice(n, size=2, replace=False)
            self.partner[a], self.partner[b] = b, a
        scheduler.on_step(self.energy, died, captured, self.partner)

    def state(self) -> dict[str, Any]:
        return {"rng": self.rng.bit_generator.state, "energy": self.energy.copy()}

    def load_state(self, state: dict[str, Any]) -> None:
        self.rng.bit_generator.state = state["rng"]
        np.copyto(self.energy, state["energy"])


def _rows(scheduler: TimeSharingScheduler) -> list[tuple]:
    """Rows with NaN made comparable."""
    return [
        tuple("nan" if isinstance(v, float) and math.isnan(v) else v for v in row.values())
        for row in scheduler.stats.to_records()
    ]


def _same(a: Any, b: Any, where: str = "state") -> None:
    """Nested plain states equal exactly: same types, floats bit for bit, arrays by dtype too."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), where
        for key in a:
            _same(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list | tuple):
        assert isinstance(b, list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape, where
        assert a.tobytes() == b.tobytes(), where
    elif isinstance(a, float):
        assert type(b) is float and struct.pack("<d", a) == struct.pack("<d", b), where
    else:
        assert type(a) is type(b) and a == b, where


def _through_file(tmp_path: Path, state: Any, name: str = "state.ckpt") -> Any:
    path = tmp_path / name
    save_checkpoint(path, state, kind="test", fingerprint="f")
    return load_checkpoint(path, kind="test", fingerprint="f")


# --- resume ---------------------------------------------------------------------------------
def test_resume_from_a_checkpoint_is_bit_identical(tmp_path: Path) -> None:
    cfg = EvolutionConfig(population_size=20, n_robots=4)
    fingerprint = config_fingerprint(cfg)

    uninterrupted = EmbodiedEvolution(cfg, np.random.default_rng(21))
    events = _Events(4, seed=22)
    for _ in range(10_000):
        events.step(uninterrupted)

    first = EmbodiedEvolution(cfg, np.random.default_rng(21))
    events = _Events(4, seed=22)
    for _ in range(4_321):
        events.step(first)
    path = tmp_path / "run.ckpt"
    save_checkpoint(
        path, {"scheduler": first.state(), "events": events.state()}, kind="ee",
        fingerprint=fingerprint,
    )  # fmt: skip
    del first, events
    state = load_checkpoint(path, kind="ee", fingerprint=fingerprint)
    resumed = EmbodiedEvolution(cfg, np.random.default_rng(999))  # its state is overwritten
    resumed.load_state(state["scheduler"])
    events = _Events(4, seed=999)
    events.load_state(state["events"])
    for _ in range(10_000 - 4_321):
        events.step(resumed)

    assert len(uninterrupted.stats.rows) >= 2
    assert _rows(resumed) == _rows(uninterrupted)
    assert resumed.population() == uninterrupted.population()
    assert [len(s) for s in resumed.spare_lists] == [len(s) for s in uninterrupted.spare_lists]
    np.testing.assert_array_equal(resumed.active_weights, uninterrupted.active_weights)
    _same(resumed.state(), uninterrupted.state())


@pytest.mark.parametrize("method", [EmbodiedEvolution, CentralisedEvolution])
def test_scheduler_state_round_trips_and_continues_identically(tmp_path, method) -> None:
    cfg = EvolutionConfig(population_size=12, n_robots=4, lifetime_steps=60, time_sharing_steps=20)
    a = method(cfg, np.random.default_rng(3))
    events = _Events(4, seed=4)
    for _ in range(1_500):
        events.step(a)
    saved = a.state()
    assert saved["genomes"].shape[1] == 39
    b = method(cfg, np.random.default_rng(77))
    b.load_state(_through_file(tmp_path, saved))
    _same(b.state(), saved)
    # Genomes shared by the run (a slot and its partner records, ...) are shared again.
    assert len({id(g) for g in b.population()}) == len({id(g) for g in a.population()})
    twin = _Events(4, seed=0)
    twin.load_state(events.state())
    for _ in range(1_500):
        events.step(a)
        twin.step(b)
    assert len(a.stats.rows) >= 2
    _same(b.state(), a.state())
    # A state of the other method, or of another population, does not fit.
    other = CentralisedEvolution if method is EmbodiedEvolution else EmbodiedEvolution
    with pytest.raises((KeyError, ValueError)):
        other(cfg, np.random.default_rng(0)).load_state(saved)
    bigger = EvolutionConfig(population_size=16, n_robots=4)
    with pytest.raises(ValueError):
        method(bigger, np.random.default_rng(0)).load_state(saved)


def test_agent_records_round_trip_with_shared_genomes(tmp_path) -> None:
    rng = np.random.default_rng(0)
    mine, partner = Genome.random(rng), Genome.random(rng)
    agent = VirtualAgent(
        mine, 73.25, generation=4, origin=Origin.SPARE, age=120, batteries=3, matings=2,
        partners=[MatingRecord(partner, 2.5), MatingRecord(partner, 1 / 3)], dead=True,
    )  # fmt: skip
    life = LifeRecord(4, 1, 2, mine, 3, 2, 0.1 + 0.2)
    pool = GenomePool()
    state = {"agent": agent.state(pool), "life": life.state(pool), "genomes": pool.array()}
    assert state["genomes"].shape == (2, 39)  # each genome once
    loaded = _through_file(tmp_path, state)
    genomes = genomes_from_array(loaded["genomes"])
    again = VirtualAgent.from_state(loaded["agent"], genomes)
    assert again == agent
    assert again.partners[0].genome is again.partners[1].genome
    assert LifeRecord.from_state(loaded["life"], genomes) == life
    assert LifeRecord.from_state(loaded["life"], genomes).genome is again.genome
    bad = dict(loaded["agent"], genome=-1)
    with pytest.raises(ValueError, match="out of range"):
        VirtualAgent.from_state(bad, genomes)


def test_statistics_and_event_log_round_trip(tmp_path) -> None:
    stats = StatisticsRecorder()
    stats.accept_late = True
    stats.record_full_life(0, 3, 1, robot=1)
    stats.record_full_life(0, 2, 0, robot=0)
    stats.record_death(0)
    stats.record_birth(0, Origin.RANDOM)
    stats.record_reproduction(0, crossover=True)
    stats.close(0, 4)
    stats.close(1, 0)  # nothing happened: NaN means
    stats.record_death(0)  # late
    stats.record_full_life(2, 5, 2, robot=3)
    stats.record_birth(2, Origin.OFFSPRING)
    log = EventLog(capacity=2)
    for i in range(5):
        log.append(i, i % 4, 2, 1, 0, -i)
    loaded = _through_file(tmp_path, {"stats": stats.state(), "events": log.state()})
    again = StatisticsRecorder()
    again.load_state(loaded["stats"])
    _same(again.state(), stats.state())
    assert math.isnan(again.rows[1].batteries_mean) and again.late == 1
    for recorder in (stats, again):
        recorder.record_full_life(2, 1, 1, robot=0)
        recorder.close(2, 7)
    assert again.to_records()[2] == stats.to_records()[2]
    assert again.robot_records() == stats.robot_records()
    events = EventLog()
    events.load_state(loaded["events"])
    np.testing.assert_array_equal(events.array, log.array)
    events.append(9, 0, 1, 0, 0, 0)
    assert len(events) == 6
    with pytest.raises(ValueError, match="int64"):
        events.load_state({"rows": np.zeros((2, 6), dtype=np.float64)})


# --- the container --------------------------------------------------------------------------
def test_plain_state_round_trips_exactly(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    big_endian = np.arange(6, dtype=">f8").reshape(2, 3)
    state = {
        "floats": [0.1, -0.0, 5e-324, 1.7976931348623157e308, math.pi, *rng.random(50).tolist()],
        "non_finite": [math.nan, math.inf, -math.inf],
        "ints": [0, -1, 2**130 + 7, -(2**70)],
        "pcg64": np.random.default_rng(5).bit_generator.state,
        "flags": [True, False, None],
        "text": "Ünïcode ✓",
        "nested": {"a": [[], {}], "b": {"c": [1, [2, [3.5]]]}},
        "arrays": {code: (rng.random((3, 2)) * 100).astype(code) for code in ARRAY_DTYPES},
        "empty": np.zeros((0, 3)),
        "scalar": np.array(2.5),
        "view": np.arange(20.0)[::3],
        "fortran": np.asfortranarray(rng.random((4, 5))),
    }
    loaded = _through_file(tmp_path, {**state, "big_endian": big_endian})
    np.testing.assert_array_equal(loaded.pop("big_endian"), big_endian)
    expected = dict(state, view=np.ascontiguousarray(state["view"]))
    expected["fortran"] = np.ascontiguousarray(state["fortran"])
    assert [math.isnan(x) for x in loaded["non_finite"]] == [True, False, False]
    loaded["non_finite"] = expected["non_finite"] = [1.0, math.inf, -math.inf]
    _same(expected, loaded)
    assert all(a.flags.writeable for a in loaded["arrays"].values())
    rebuilt = np.random.default_rng(0)
    rebuilt.bit_generator.state = loaded["pcg64"]
    assert rebuilt.random() == np.random.default_rng(5).random()
    # numpy scalars are written as the Python numbers they are; tuples come back as lists
    assert _through_file(tmp_path, [np.float64(0.1), np.int64(3), np.bool_(True), (1, 2)]) == [
        0.1, 3, True, [1, 2],
    ]  # fmt: skip


@pytest.mark.parametrize(
    "state",
    [
        {"genome": Genome(np.zeros(39))},
        {"set": {1, 2}},
        {1: "integer key"},
        {"objects": np.array([object()], dtype=object)},
        {"complex": np.zeros(2, dtype=complex)},
        {"text": np.array(["a"])},
        {"__array__": "looks like a reference"},
    ],
)
def test_what_is_not_plain_state_is_refused_and_nothing_written(tmp_path, state) -> None:
    with pytest.raises(TypeError):
        save_checkpoint(tmp_path / "x.ckpt", state, kind="k", fingerprint="f")
    assert list(tmp_path.iterdir()) == []


def test_fingerprint_is_stable_and_sensitive() -> None:
    a = config_fingerprint(EvolutionConfig())
    assert a == config_fingerprint(EvolutionConfig())
    assert a != config_fingerprint(
        EvolutionConfig(genetics=GeneticConfig(mutation_probability=0.2))
    )
    # Stable across processes and Python runs (no salted hash()).
    code = "from evolution.checkpoint import config_fingerprint as f; from evolution.config import "
    code += "EvolutionConfig as E; print(f(E()))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == a


def _good(tmp_path: Path) -> Path:
    path = tmp_path / "good.ckpt"
    save_checkpoint(path, {"x": np.arange(1000)}, kind="ee", fingerprint="abc")
    return path


def _expect_rejected(path: Path, match: str, **kwargs) -> None:
    before = path.read_bytes()
    with pytest.raises(CheckpointError, match=match) as info:
        load_checkpoint(path, **kwargs)
    assert "\n" not in str(info.value)  # one line
    assert path.read_bytes() == before  # a failed load loses no data


def test_round_trip_and_header(tmp_path: Path) -> None:
    path = _good(tmp_path)
    np.testing.assert_array_equal(load_checkpoint(path)["x"], np.arange(1000))
    header = read_header(path)
    assert header["format_version"] == FORMAT_VERSION
    assert (header["kind"], header["fingerprint"]) == ("ee", "abc")
    assert header["mujoco_version"] == mujoco.__version__
    assert isinstance(header["code_version"], str)
    assert list(tmp_path.iterdir()) == [path]  # no temporary left behind


def test_corrupt_checkpoints_are_rejected_clearly(tmp_path: Path) -> None:
    path = _good(tmp_path)
    data = bytearray(path.read_bytes())
    data[-10] ^= 0xFF
    path.write_bytes(bytes(data))
    _expect_rejected(path, "SHA-256")

    path = _good(tmp_path)
    path.write_bytes(path.read_bytes()[:-100])
    _expect_rejected(path, "truncated")

    path.write_bytes(MAGIC[:5])
    _expect_rejected(path, "bad magic")

    path.write_bytes(b"")
    _expect_rejected(path, "bad magic")

    path.write_bytes(MAGIC + (50).to_bytes(4, "big") + b"{not json")
    _expect_rejected(path, "truncated")

    raw = b"[1, 2]"
    path.write_bytes(MAGIC + len(raw).to_bytes(4, "big") + raw)
    _expect_rejected(path, "corrupt checkpoint header")

    with pytest.raises(CheckpointError, match="not found"):
        load_checkpoint(tmp_path / "missing.ckpt")


def _split(path: Path) -> tuple[dict[str, Any], bytes]:
    data = path.read_bytes()
    size = int.from_bytes(data[len(MAGIC) : len(MAGIC) + 4], "big")
    start = len(MAGIC) + 4
    return json.loads(data[start : start + size]), data[start + size :]


def _write(path: Path, header: dict[str, Any], payload: bytes) -> Path:
    """A file with ``payload`` behind a header whose lengths and SHA-256 are *right*."""
    header = dict(header, payload_bytes=len(payload), sha256=hashlib.sha256(payload).hexdigest())
    raw = json.dumps(header).encode()
    path.write_bytes(MAGIC + len(raw).to_bytes(4, "big") + raw + payload)
    return path


def test_incompatible_checkpoints_are_rejected_clearly(tmp_path: Path) -> None:
    path = _good(tmp_path)
    _expect_rejected(path, "kind 'ee' does not match", kind="ce")
    _expect_rejected(path, "fingerprint mismatch", fingerprint="xyz")
    header, payload = _split(path)
    _write(path, dict(header, format_version=FORMAT_VERSION + 1), payload)
    _expect_rejected(path, f"checkpoint format {FORMAT_VERSION + 1} is not read by this version")
    with pytest.raises(CheckpointError, match="is not read by this version"):
        read_header(path)


class _Payload:
    """Unpickling this object creates ``marker`` (what a malicious checkpoint could do)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[Any, ...]:
        return (open, (str(self.marker), "w"))


def _malicious_pickle(marker: Path) -> bytes:
    payload = pickle.dumps({"scheduler": _Payload(marker)})
    probe = marker.with_name(marker.name + ".probe")
    pickle.loads(pickle.dumps(_Payload(probe))).close()  # the payload is live: it runs code
    assert probe.exists()
    probe.unlink()
    return payload


def _old_header(kind: str = "evolution-run-ee") -> dict[str, Any]:
    """A header as the first (pickle) format wrote it."""
    return {"format_version": 1, "kind": kind, "fingerprint": "0" * 64}


def _new_header(payload: bytes, kind: str = "evolution-run-ee") -> dict[str, Any]:
    return {
        "format_version": FORMAT_VERSION, "kind": kind, "fingerprint": "0" * 64,
        "code_version": "0.1.0", "mujoco_version": mujoco.__version__,
        "document_bytes": len(payload),
    }  # fmt: skip


def test_a_checkpoint_of_the_pickle_format_gets_one_line(tmp_path: Path) -> None:
    marker = tmp_path / "marker"
    path = _write(tmp_path / "gen_00003.ckpt", _old_header(), _malicious_pickle(marker))
    message = f"{path}: checkpoint format 1 (pickled objects) is no longer read; this version "
    message += f"reads format {FORMAT_VERSION} — re-run, or resume with cyber-rodent 0.1.0"
    _expect_rejected(path, re.escape(message))
    with pytest.raises(CheckpointError, match=re.escape(message)):
        EvolutionRunner.from_checkpoint(path, REACTIVE)
    assert not marker.exists()


def test_a_pickle_behind_a_valid_header_is_never_unpickled(tmp_path: Path) -> None:
    marker = tmp_path / "marker"
    payload = _malicious_pickle(marker)
    path = _write(tmp_path / "gen_00001.ckpt", _new_header(payload), payload)
    _expect_rejected(path, "malformed checkpoint: the payload is a pickle, which is never loaded")
    with pytest.raises(CheckpointError, match="the payload is a pickle"):
        EvolutionRunner.from_checkpoint(path, REACTIVE)
    assert not marker.exists()


def _document(path: Path, document: Any, blocks: bytes = b"") -> Path:
    text = json.dumps(document).encode()
    return _write(path, _new_header(text, kind="k"), text + blocks)


def _one(dtype: str, shape: list[int]) -> dict[str, Any]:
    """A document whose state is one array ``x`` of ``dtype`` and ``shape`` at offset 0."""
    return {
        "state": {"__array__": "x"},
        "arrays": {"x": {"dtype": dtype, "shape": shape, "offset": 0}},
    }


@pytest.mark.parametrize(
    ("document", "blocks", "match"),
    [
        ({"state": {"__array__": "x"}, "arrays": {}}, b"", "missing array 'x'"),
        (_one("|O", [1]), bytes(8), "dtype '|O' is not allowed"),
        (_one("<c16", [1]), bytes(16), "dtype '<c16' is not allowed"),
        (_one(">f8", [1]), bytes(8), "dtype '>f8' is not allowed"),
        (_one("<f8", [4]), bytes(8), "outside the payload"),
        (_one("<f8", [-1]), bytes(8), "malformed shape"),
        (_one("|b1", [2]), b"\x01\x07", "bool values"),
        (
            dict(_one("<i8", [1]), state=[{"__array__": "x"}, {"__array__": "x"}]),
            bytes(8), "referred to twice",
        ),
        ({"state": {"__float__": "pi"}, "arrays": {}}, b"", "unknown float tag"),
        ({"state": {"__array__": "x", "y": 1}, "arrays": {}}, b"", "malformed reference"),
        ({"state": 1}, b"", "expected 'state' and 'arrays'"),
    ],
)  # fmt: skip
def test_malformed_documents_are_refused(tmp_path, document, blocks, match) -> None:
    _expect_rejected(_document(tmp_path / "x.ckpt", document, blocks), match)


def test_bare_non_finite_numbers_in_the_document_are_refused(tmp_path) -> None:
    text = b'{"state": NaN, "arrays": {}}'
    path = _write(tmp_path / "x.ckpt", _new_header(text, kind="k"), text)
    _expect_rejected(path, "bare NaN")


def _fake_run_dir(root: Path, payload: bytes, header: dict[str, Any]) -> Path:
    """A run directory whose only checkpoint is a crafted file."""
    run = root / "run"
    (run / "checkpoints").mkdir(parents=True)
    record = {
        "config": {}, "seed": 0, "policies": policy_identity(REACTIVE), "target_generations": 3,
    }  # fmt: skip
    (run / "run.json").write_text(json.dumps(record))
    _write(run / "checkpoints" / "gen_00001.ckpt", header, payload)
    return run


@pytest.mark.parametrize("layout", ["pickle format", "valid new header"])
def test_resume_render_and_transfer_refuse_a_malicious_checkpoint(
    tmp_path, capsys, layout
) -> None:
    marker = tmp_path / "marker"
    payload = _malicious_pickle(marker)
    header = _old_header() if layout == "pickle format" else _new_header(payload)
    run = _fake_run_dir(tmp_path, payload, header)
    checkpoint = run / "checkpoints" / "gen_00001.ckpt"
    commands = [
        ["resume", str(run), "--no-progress"],
        ["render", "--checkpoint", str(checkpoint), "--out", str(tmp_path / "v.mp4"),
         "--no-progress"],
        ["transfer", "--from", str(run), "--generation", "1", "--out", str(tmp_path / "t"),
         "--no-progress"],
    ]  # fmt: skip
    for argv in commands:
        assert cli_main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(f"cyber-rodent {argv[0]}: error: "), err
        assert str(checkpoint) in err, err
        assert not marker.exists()
    assert not (tmp_path / "v.mp4").exists() and not (tmp_path / "t").exists()


# --- physics --------------------------------------------------------------------------------
def _mjdata_pointers() -> list[str]:
    header = Path(mujoco.__file__).parent / "include" / "mujoco" / "mjxmacro.h"
    if not header.is_file():
        pytest.skip("MuJoCo's headers are not installed")
    text = header.read_text()
    block = text[text.index("#define MJDATA_POINTERS") : text.index("#define MJDATA_ARENA")]
    return re.findall(r"\bX(?:NV)?\s*\(\s*\w+\s*,\s*(\w+)\s*,", block)


def test_derived_fields_are_every_fixed_size_array_outside_the_integration_state() -> None:
    integration = {
        "qpos", "qvel", "act", "history", "qacc_warmstart", "plugin_state", "ctrl",
        "qfrc_applied", "xfrc_applied", "eq_active", "mocap_pos", "mocap_quat", "userdata",
    }  # fmt: skip
    pointers = set(_mjdata_pointers())
    assert integration <= pointers
    assert set(DERIVED_FIELDS) == pointers - integration - {"plugin", "plugin_data"}
    assert len(DERIVED_FIELDS) == len(set(DERIVED_FIELDS))


def _moving_world(seed: int) -> SurvivalWorld:
    return SurvivalWorld(WorldConfig(n_robots=3, n_packs=2), rng=np.random.default_rng(seed))


def _drive(survival: SurvivalWorld, steps: int, start: int) -> None:
    n = survival.n_robots
    for k in range(start, start + steps):
        wheels = np.column_stack([np.full(n, 0.2), np.full(n, 0.1 + 0.05 * (k % 3))])
        survival.step(wheels, np.zeros(n, bool), np.zeros(n, bool), np.ones(n, bool))


def test_physics_state_restores_what_the_next_step_reads(tmp_path) -> None:
    a = _moving_world(0)
    _drive(a, 30, 0)
    saved = _through_file(tmp_path, {"physics": physics_state(a.world), "world": a.state()})
    b = _moving_world(1)  # another placement: everything must come from the state
    load_physics_state(b.world, saved["physics"])
    b.load_state(saved["world"])
    da, db = a.world.data, b.world.data
    for name in DERIVED_FIELDS:
        assert getattr(da, name).tobytes() == getattr(db, name).tobytes(), name
    for name in ("body_pos", "eq_data", "geom_rgba"):
        np.testing.assert_array_equal(getattr(a.world.model, name), getattr(b.world.model, name))
    _drive(a, 30, 30)
    _drive(b, 30, 30)
    assert da.qpos.tobytes() == db.qpos.tobytes() and da.time == db.time
    assert da.sensordata.tobytes() == db.sensordata.tobytes()
    _same(a.state(), b.state())


def test_the_derived_arrays_are_needed(tmp_path) -> None:
    """Why they are saved: the last substep's forward pass ran before its integration, so
    recomputing at the restored integration state gives other poses and sensor values."""
    a = _moving_world(0)
    _drive(a, 30, 0)
    m, d = a.world.model, a.world.data
    integration = np.empty(mujoco.mj_stateSize(m, INTEGRATION))
    mujoco.mj_getState(m, d, integration, INTEGRATION)
    site_xpos = d.site_xpos.copy()
    mujoco.mj_setState(m, d, integration, INTEGRATION)
    mujoco.mj_forward(m, d)
    assert d.site_xpos.tobytes() != site_xpos.tobytes()


def test_physics_state_of_another_world_or_mujoco_is_refused() -> None:
    a = _moving_world(0)
    state = physics_state(a.world)
    other = SurvivalWorld(WorldConfig(n_robots=4, n_packs=2), rng=np.random.default_rng(0))
    with pytest.raises(ValueError):
        load_physics_state(other.world, state)
    with pytest.raises(ValueError, match="MuJoCo 0.0.1"):
        load_physics_state(a.world, dict(state, mujoco_version="0.0.1"))


# --- atomic writes --------------------------------------------------------------------------
_WRITER = textwrap.dedent(
    """
    import sys
    import numpy as np
    from evolution.checkpoint import save_checkpoint
    path = sys.argv[1]
    big = np.random.default_rng(0).random(4_000_000)  # 32 MB: each write takes a while
    count = 0
    while True:
        save_checkpoint(path, {"count": count, "big": big}, kind="ee", fingerprint="f")
        count += 1
        print(count, flush=True)
    """
)


def _temporaries(directory: Path) -> list[Path]:
    return [p for p in directory.iterdir() if TEMP_MARK in p.name]


def test_killing_the_writer_mid_write_leaves_the_last_good_checkpoint(tmp_path: Path) -> None:
    path = tmp_path / "run.ckpt"
    writer = subprocess.Popen(
        [sys.executable, "-c", _WRITER, str(path)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert writer.stdout is not None
        writer.stdout.readline()  # the first checkpoint is complete
        # Freeze the writer while its temporary file exists (i.e. mid-write), then kill it.
        # Freezing first makes "mid-write" certain rather than a race.
        mid_write = False
        for _ in range(100):
            while not _temporaries(tmp_path):
                assert writer.poll() is None, "the writer exited"
                time.sleep(0.001)
            os.kill(writer.pid, signal.SIGSTOP)
            if _temporaries(tmp_path):
                mid_write = True
                break
            os.kill(writer.pid, signal.SIGCONT)
        os.kill(writer.pid, signal.SIGKILL)
    finally:
        writer.kill()
        writer.wait()
    assert mid_write
    state = load_checkpoint(path, kind="ee", fingerprint="f")
    assert state["count"] >= 0
    assert state["big"].shape == (4_000_000,)
    stale = remove_stale_temporaries(tmp_path)
    assert len(stale) == 1
    assert list(tmp_path.iterdir()) == [path]


def test_default_fingerprint_is_the_earlier_versions() -> None:
    """Fields added since (the controller, the field's size, the mating threshold, ...) are left
    out of the fingerprint at the value that reproduces the earlier behaviour, so checkpoints of
    earlier versions still resume: the paper's run of seed 0 with the vision of before traced
    pixels (``camera.trace_below`` off) and with the teeth that touched robots
    (``world.contacts`` published) has the fingerprint it had before them. Today's default
    traces them and has teeth that touch no robot, which changes what robots see and do, so
    its runs must not resume those checkpoints, nor those of the published model."""
    import dataclasses

    from behaviours import BehaviourPolicies
    from cyber_rodent.vision import CameraConfig
    from cyber_rodent.world import WorldConfig
    from evolution.runner import RunConfig, policy_identity, run_fingerprint

    policies = policy_identity(BehaviourPolicies.load_default())
    published = dataclasses.replace(RunConfig(), world=WorldConfig(contacts="published"))
    before = dataclasses.replace(published, camera=CameraConfig(trace_below=(0, 0, 0)))
    earlier = "05171b5b2de9bc1c2a48c04bddf4cea827e72dec848368c0199181d1a33def13"
    assert run_fingerprint(before, 0, policies, None) == earlier
    today = run_fingerprint(RunConfig(), 0, policies, None)
    assert today not in (earlier, run_fingerprint(published, 0, policies, None))


def test_a_record_without_a_later_field_is_read_as_it_ran() -> None:
    """A run.json or checkpoint written before a field existed means the behaviour before it:
    the published model's records lack ``world.contacts`` and ran with teeth that touch
    robots; those written before ``camera.trace_below`` ran without tracing."""
    import dataclasses

    from evolution.runner import RunConfig, run_config_from_record

    record = dataclasses.asdict(RunConfig())
    assert run_config_from_record(record) == RunConfig()  # today's record reads as written
    del record["world"]["contacts"]
    del record["camera"]["trace_below"]
    old = run_config_from_record(record)
    assert old.world.contacts == "published"
    assert old.camera.trace_below == (0, 0, 0)
    assert "contacts" not in record["world"]  # the record itself is left alone
