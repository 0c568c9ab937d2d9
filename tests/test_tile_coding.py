"""Hashed tile coder: hand-computed tiles, hash reference, reproducibility, generalisation."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from behaviours.tile_coding import TileCoder, TileCoderConfig, mix32

# -- an independent reference of the hash, in plain Python integers --------------------------


def _lowbias32(x: int) -> int:
    """Wellons' lowbias32 written the obvious way (no 16-bit split), as the reference."""
    x &= 0xFFFFFFFF
    x ^= x >> 16
    x = (x * 0x7FEB352D) & 0xFFFFFFFF
    x ^= x >> 15
    x = (x * 0x846CA68B) & 0xFFFFFFFF
    x ^= x >> 16
    return x


def _reference_index(seed: int, tiling: int, coords: tuple[int, ...], table_size: int) -> int:
    h = _lowbias32(_lowbias32(seed) ^ tiling)
    for c in coords:
        h = _lowbias32(h ^ c)
    return h % table_size


def test_mix32_matches_plain_integer_reference():
    rng = np.random.default_rng(0)
    x = rng.integers(0, 2**32, size=2000, dtype=np.int64)
    x[:4] = [0, 1, 2**32 - 1, 0x80000000]
    ours = mix32(x)
    assert ours.dtype == np.int64
    assert [int(v) for v in ours] == [_lowbias32(int(v)) for v in x]
    assert (ours >= 0).all() and (ours < 2**32).all()
    assert _lowbias32(0) == 0  # the mixer fixes 0; the seed/tiling steps keep that harmless
    assert len(set(ours.tolist())) == len(set(x.tolist()))  # a bijection: no collisions


# -- tile coordinates, computed by hand ------------------------------------------------------


def test_one_dimension_two_tilings_by_hand():
    # resolution 2, 2 tilings: tiling 0 has edges at 0, .5, 1; tiling 1 is shifted by 1/2 of a
    # tile (1/4), edges at -.25, .25, .75. floor(x * 2 * 2) = q; tile = (q + t) // 2.
    coder = TileCoder(TileCoderConfig(resolution=(2,), n_tilings=2))
    cases = {0.0: [0, 0], 0.3: [0, 1], 0.74: [1, 1], 0.76: [1, 2], 1.0: [2, 2]}
    for x, tiles in cases.items():
        assert coder.coordinates(np.array([x]))[:, 0].tolist() == tiles, x


def test_wrap_maps_one_onto_zero_by_hand():
    coder = TileCoder(TileCoderConfig(resolution=(2,), n_tilings=2, wrap=(True,)))
    cases = {0.0: [0, 0], 0.3: [0, 1], 0.76: [1, 0], 1.0: [0, 0]}
    for x, tiles in cases.items():
        assert coder.coordinates(np.array([x]))[:, 0].tolist() == tiles, x


def test_two_dimensions_asymmetric_offsets_by_hand():
    # resolution (4, 4), 4 tilings: offsets t * (1, 3) mod 4 = (0,0), (1,3), (2,2), (3,1)
    # in quarters of a tile. x = (0.1, 0.1) -> q = floor(0.1 * 16) = 1 on both axes.
    coder = TileCoder(TileCoderConfig(resolution=(4, 4), n_tilings=4))
    assert coder.offsets.tolist() == [[0, 0], [1, 3], [2, 2], [3, 1]]
    coords = coder.coordinates(np.array([0.1, 0.1]))
    assert coords.tolist() == [[0, 0], [0, 1], [0, 0], [1, 0]]


def test_hashed_indices_match_reference_by_hand():
    config = TileCoderConfig(resolution=(4, 4), n_tilings=4, table_size=97, seed=12345)
    coder = TileCoder(config)
    expected = [
        _reference_index(12345, t, c, 97)
        for t, c in enumerate([(0, 0), (0, 1), (0, 0), (1, 0)])  # from the test above
    ]
    assert coder.indices(np.array([0.1, 0.1])).tolist() == expected
    assert coder.hashed_indices(np.array([0.1, 0.1])).tolist() == expected


def test_lookup_table_path_equals_on_the_fly_hash():
    rng = np.random.default_rng(3)
    for config in (
        TileCoderConfig(resolution=(10, 5), n_tilings=8, table_size=4096, wrap=(True, False)),
        TileCoderConfig(resolution=(3, 7, 2), n_tilings=4, table_size=101, seed=9),
        TileCoderConfig(resolution=(6,), n_tilings=16, table_size=64, wrap=(True,)),
    ):
        coder = TileCoder(config)
        x = rng.random((5000, config.n_dims))
        x[:3] = [[0.0] * config.n_dims, [1.0] * config.n_dims, [0.5] * config.n_dims]
        idx = coder.indices(x)
        assert idx.shape == (5000, config.n_tilings) and idx.dtype == np.int64
        assert np.array_equal(idx, coder.hashed_indices(x))
        assert idx.min() >= 0 and idx.max() < config.table_size


def test_large_coordinate_space_hashes_on_the_fly():
    config = TileCoderConfig(resolution=(1000, 1000), n_tilings=8, table_size=1 << 20)
    coder = TileCoder(config)
    assert coder._lookup is None
    x = np.random.default_rng(0).random((100, 2))
    expected = [
        [_reference_index(0, t, tuple(c), 1 << 20) for t, c in enumerate(state_coords)]
        for state_coords in coder.coordinates(x).tolist()
    ]
    assert coder.indices(x).tolist() == expected


def test_single_state_and_batch_agree():
    coder = TileCoder(TileCoderConfig(resolution=(8, 8)))
    x = np.array([[0.2, 0.9], [0.7, 0.1]])
    batch = coder.indices(x)
    assert np.array_equal(coder.indices(x[1]), batch[1])


# -- generalisation ---------------------------------------------------------------------------


def _shared_tiles(coder: TileCoder, a: list[float], b: list[float]) -> int:
    ca, cb = coder.coordinates(np.array(a)), coder.coordinates(np.array(b))
    return int((ca == cb).all(axis=1).sum())


def test_nearby_states_share_tiles_distant_ones_do_not():
    coder = TileCoder(TileCoderConfig(resolution=(4, 4), n_tilings=8))
    # 0.01 is 1/25 of a tile: at most one tile boundary per axis per tiling is crossed.
    assert _shared_tiles(coder, [0.40, 0.40], [0.41, 0.41]) >= 6
    assert _shared_tiles(coder, [0.10, 0.10], [0.60, 0.10]) == 0  # two tile widths apart


def test_wrap_shares_tiles_across_the_seam_only_when_asked():
    wrap = TileCoder(TileCoderConfig(resolution=(8, 4), n_tilings=8, wrap=(True, False)))
    flat = TileCoder(TileCoderConfig(resolution=(8, 4), n_tilings=8))
    assert _shared_tiles(wrap, [0.999, 0.5], [0.001, 0.5]) >= 6
    assert _shared_tiles(flat, [0.999, 0.5], [0.001, 0.5]) == 0
    assert np.array_equal(wrap.indices(np.array([0.0, 0.3])), wrap.indices(np.array([1.0, 0.3])))


def test_seed_changes_the_layout():
    x = np.random.default_rng(1).random((50, 2))
    a = TileCoder(TileCoderConfig(resolution=(8, 8), seed=1)).indices(x)
    b = TileCoder(TileCoderConfig(resolution=(8, 8), seed=2)).indices(x)
    assert (a != b).mean() > 0.9


# -- reproducibility across processes ----------------------------------------------------------

_DIGEST_SCRIPT = """
import hashlib, numpy as np
from behaviours.tile_coding import TileCoder, TileCoderConfig
x = np.random.default_rng(2024).random((3000, 3))
for lookup in (True, False):
    coder = TileCoder(TileCoderConfig(resolution=(9, 5, 3), n_tilings=8, table_size=5000,
                                      wrap=(True, False, False), seed=77))
    idx = coder.indices(x) if lookup else coder.hashed_indices(x)
    print(hashlib.sha256(idx.astype('<i8').tobytes()).hexdigest())
"""


def test_indices_identical_in_fresh_processes_with_different_hash_seeds():
    here: list[str] = []
    exec(_DIGEST_SCRIPT, {"print": here.append})  # the same script, in this process
    assert here[0] == here[1]
    for hash_seed in ("1", "987654"):
        env = dict(os.environ, PYTHONHASHSEED=hash_seed)
        out = subprocess.run(
            [sys.executable, "-c", _DIGEST_SCRIPT],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.split()
        assert out == here


def test_pinned_indices_do_not_drift():
    """Shipped action values depend on this exact layout; a change must bump HASH_VERSION."""
    coder = TileCoder(TileCoderConfig(resolution=(8, 4), n_tilings=8, wrap=(True, False)))
    idx = coder.indices(np.array([[0.5, 0.2], [0.0, 1.0]]))
    assert idx.tolist() == [
        [1796, 2531, 2535, 2813, 2724, 1240, 3090, 583],
        [3793, 3771, 1539, 3750, 3484, 3176, 1752, 2217],
    ]


# -- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"resolution": ()}, "resolution"),
        ({"resolution": (4, 0)}, "resolution"),
        ({"resolution": (4,), "wrap": (True, False)}, "wrap"),
        ({"resolution": (4,), "n_tilings": 0}, "n_tilings"),
        ({"resolution": (4,), "table_size": 0}, "table_size"),
        ({"resolution": (4,), "seed": -1}, "seed"),
        ({"resolution": (4,), "seed": 2**32}, "seed"),
    ],
)
def test_bad_config_names_the_field(kwargs, field):
    with pytest.raises(ValueError, match=field):
        TileCoderConfig(**kwargs)


@pytest.mark.parametrize(
    "states",
    [
        np.array([[0.5, 1.01]]),
        np.array([[-1e-9, 0.5]]),
        np.array([[np.nan, 0.5]]),
        np.array([[0.5, 0.5, 0.5]]),
        np.zeros((2, 2, 2)),
    ],
)
def test_bad_states_are_rejected(states):
    coder = TileCoder(TileCoderConfig(resolution=(4, 4)))
    with pytest.raises(ValueError, match="states"):
        coder.indices(states)


def test_config_round_trips_through_dict_and_rejects_other_hash_versions():
    config = TileCoderConfig(resolution=(5, 3), n_tilings=4, table_size=333, wrap=(True, False))
    assert TileCoderConfig.from_dict(config.to_dict()) == config
    bad = dict(config.to_dict(), hash_version=0)
    with pytest.raises(ValueError, match="hash_version"):
        TileCoderConfig.from_dict(bad)
