"""Action values on disk (version + SHA-256) and the greedy policy built on them."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from behaviours.action_values import (
    FORMAT_VERSION,
    ActionValues,
    CorruptActionValuesError,
    IncompatibleActionValuesError,
)
from behaviours.greedy_policy import GreedyPolicy
from behaviours.tile_coding import TileCoder, TileCoderConfig

CODER = TileCoderConfig(resolution=(8, 4), n_tilings=4, table_size=256, wrap=(True, False), seed=3)
NAMES = ("forward", "left", "right")


@pytest.fixture
def values() -> ActionValues:
    weights = np.random.default_rng(0).normal(size=(3, 256))
    return ActionValues(CODER, weights, NAMES, {"behaviour": "forage", "episodes": 12})


def test_round_trip_is_exact(values, tmp_path):
    path = values.save(tmp_path / "forage.npz")
    loaded = ActionValues.load(path)
    assert loaded.weights.tobytes() == values.weights.tobytes()
    assert loaded.coder_config == CODER
    assert loaded.action_names == NAMES
    assert loaded.metadata == {"behaviour": "forage", "episodes": 12}
    assert loaded.checksum == values.checksum
    assert not (tmp_path / "forage.npz.tmp").exists()


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="action values file not found"):
        ActionValues.load(tmp_path / "nope.npz")


def test_flipped_byte_is_detected(values, tmp_path):
    path = values.save(tmp_path / "v.npz")
    raw = bytearray(path.read_bytes())
    raw[len(raw) // 2] ^= 0xFF  # inside the weights payload
    path.write_bytes(bytes(raw))
    with pytest.raises(CorruptActionValuesError, match=str(path.name)):
        ActionValues.load(path)


def test_edited_weights_fail_the_checksum(values, tmp_path):
    """A well-formed archive whose weights were changed after saving (zip CRCs are fine)."""
    path = values.save(tmp_path / "v.npz")
    with np.load(path) as data:
        header, digest = data["header"], data["sha256"]
        weights = data["weights"].copy()
    weights[1, 7] += 1e-12
    np.savez(path, weights=weights, header=header, sha256=digest)
    with pytest.raises(CorruptActionValuesError, match="checksum"):
        ActionValues.load(path)


def test_truncated_and_foreign_files_are_corrupt(values, tmp_path):
    path = values.save(tmp_path / "v.npz")
    path.write_bytes(path.read_bytes()[:200])
    with pytest.raises(CorruptActionValuesError):
        ActionValues.load(path)
    path.write_bytes(b"definitely not numpy")
    with pytest.raises(CorruptActionValuesError):
        ActionValues.load(path)
    np.savez(path, something=np.zeros(3))
    with pytest.raises(CorruptActionValuesError, match="missing entries"):
        ActionValues.load(path)
    with open(path, "wb") as fh:
        np.save(fh, np.zeros(3))  # a bare .npy, not an archive
    with pytest.raises(CorruptActionValuesError, match="not an .npz"):
        ActionValues.load(path)


def _rewrite_header(path, edit) -> None:
    """Re-save with an edited header and a *valid* checksum (an intact but different file)."""
    from behaviours.action_values import values_checksum

    with np.load(path) as data:
        weights = data["weights"].copy()
        header = json.loads(str(data["header"][()]))
    edit(header)
    text = json.dumps(header, sort_keys=True, separators=(",", ":"))
    checksum = np.array(values_checksum(text, weights))
    np.savez(path, weights=weights, header=np.array(text), sha256=checksum)


def test_other_format_version_is_incompatible(values, tmp_path):
    path = values.save(tmp_path / "v.npz")
    _rewrite_header(path, lambda h: h.update(format_version=FORMAT_VERSION + 1))
    with pytest.raises(IncompatibleActionValuesError, match="format_version"):
        ActionValues.load(path)


def test_other_hash_version_is_incompatible(values, tmp_path):
    path = values.save(tmp_path / "v.npz")
    _rewrite_header(path, lambda h: h["coder"].update(hash_version=0))
    with pytest.raises(IncompatibleActionValuesError, match="hash_version"):
        ActionValues.load(path)


def test_expectations_are_checked(values, tmp_path):
    path = values.save(tmp_path / "v.npz")
    other = TileCoderConfig(resolution=(8, 4), n_tilings=4, table_size=256, seed=4)
    with pytest.raises(IncompatibleActionValuesError, match="coder"):
        ActionValues.load(path, expect_coder=other)
    with pytest.raises(IncompatibleActionValuesError, match="n_actions"):
        ActionValues.load(path, expect_n_actions=5)
    assert ActionValues.load(path, expect_coder=CODER, expect_n_actions=3).n_actions == 3


def test_bad_construction_names_the_field(tmp_path):
    with pytest.raises(ValueError, match="weights"):
        ActionValues(CODER, np.zeros((3, 100)))
    with pytest.raises(ValueError, match="weights"):
        ActionValues(CODER, np.full((3, 256), np.nan))
    with pytest.raises(ValueError, match="action_names"):
        ActionValues(CODER, np.zeros((3, 256)), ("a", "b"))
    with pytest.raises(ValueError, match="metadata"):
        ActionValues(CODER, np.zeros((3, 256)), metadata={"rng": object()})
    with pytest.raises(ValueError, match="path"):
        ActionValues(CODER, np.zeros((3, 256))).save(tmp_path / "v.pickle")


def test_checksum_is_stable_across_processes(values, tmp_path):
    path = values.save(tmp_path / "v.npz")
    script = (
        "import sys; from behaviours.action_values import ActionValues; "
        "print(ActionValues.load(sys.argv[1]).checksum)"
    )
    out = subprocess.run(
        [sys.executable, "-c", script, str(path)], capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == values.checksum


# -- greedy policy --------------------------------------------------------------------------------


def test_greedy_policy_takes_the_argmax_of_the_tile_sum(values):
    policy = GreedyPolicy(values)
    coder = TileCoder(CODER)
    x = np.random.default_rng(1).random((500, 2))
    idx = coder.indices(x)
    q_by_hand = np.stack([values.weights[:, row].sum(axis=1) for row in idx])
    assert np.allclose(policy.q_values(x), q_by_hand, rtol=0, atol=1e-12)
    assert np.array_equal(policy.act(x), q_by_hand.argmax(axis=1))
    assert int(policy.act(x[3])) == int(q_by_hand[3].argmax())


def test_greedy_ties_go_to_the_lowest_action():
    policy = GreedyPolicy(ActionValues(CODER, np.zeros((3, 256))))
    assert not policy.act(np.random.default_rng(0).random((50, 2))).any()
    weights = np.zeros((3, 256))
    weights[1:] = 1.0  # actions 1 and 2 tie everywhere
    assert set(GreedyPolicy(ActionValues(CODER, weights)).act(np.full((5, 2), 0.5))) == {1}


def test_greedy_policy_from_file(values, tmp_path):
    path = values.save(tmp_path / "v.npz")
    policy = GreedyPolicy.from_file(path, expect_n_actions=3)
    x = np.random.default_rng(2).random((100, 2))
    assert np.array_equal(policy.act(x), GreedyPolicy(values).act(x))
    assert policy.action_names == NAMES
