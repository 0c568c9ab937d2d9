"""Checkpoints: atomic writes, verified loads, bit-identical resume of a scheduler."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from evolution.checkpoint import (
    FORMAT_VERSION,
    MAGIC,
    CheckpointError,
    config_fingerprint,
    load_checkpoint,
    read_header,
    remove_stale_temporaries,
    save_checkpoint,
)
from evolution.config import EvolutionConfig, GeneticConfig
from evolution.scheduler import NO_PARTNER, EmbodiedEvolution, TimeSharingScheduler


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


def _rows(scheduler: TimeSharingScheduler) -> list[tuple]:
    """Rows with NaN made comparable."""
    return [
        tuple("nan" if isinstance(v, float) and math.isnan(v) else v for v in row.values())
        for row in scheduler.stats.to_records()
    ]


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
        path, {"scheduler": first, "events": events}, kind="ee", fingerprint=fingerprint
    )
    del first, events
    state = load_checkpoint(path, kind="ee", fingerprint=fingerprint)
    resumed, events = state["scheduler"], state["events"]
    for _ in range(10_000 - 4_321):
        events.step(resumed)

    assert len(uninterrupted.stats.rows) >= 2
    assert _rows(resumed) == _rows(uninterrupted)
    assert resumed.population() == uninterrupted.population()
    assert [len(s) for s in resumed.spare_lists] == [len(s) for s in uninterrupted.spare_lists]
    np.testing.assert_array_equal(resumed.active_weights, uninterrupted.active_weights)


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
    with pytest.raises(CheckpointError, match=match):
        load_checkpoint(path, **kwargs)
    assert path.read_bytes() == before  # a failed load loses no data


def test_round_trip_and_header(tmp_path: Path) -> None:
    path = _good(tmp_path)
    np.testing.assert_array_equal(load_checkpoint(path)["x"], np.arange(1000))
    header = read_header(path)
    assert header["format_version"] == FORMAT_VERSION
    assert (header["kind"], header["fingerprint"]) == ("ee", "abc")
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


def test_incompatible_checkpoints_are_rejected_clearly(tmp_path: Path) -> None:
    path = _good(tmp_path)
    _expect_rejected(path, "kind 'ee' does not match", kind="ce")
    _expect_rejected(path, "fingerprint mismatch", fingerprint="xyz")
    data = path.read_bytes()
    size = int.from_bytes(data[len(MAGIC) : len(MAGIC) + 4], "big")
    start = len(MAGIC) + 4
    header = json.loads(data[start : start + size])
    header["format_version"] = FORMAT_VERSION + 1
    raw = json.dumps(header).encode()
    path.write_bytes(MAGIC + len(raw).to_bytes(4, "big") + raw + data[start + size :])
    _expect_rejected(path, "format_version")


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
    return [p for p in directory.iterdir() if p.name.endswith(".tmp-ckpt")]


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
