"""Hashed tile coding of normalised inputs, reproducible across processes and Python runs.

The paper (Elfwing et al., §3.4) learns every basic behaviour with Sarsa(λ) over *tile coding*:
a state is covered by ``n_tilings`` overlapping grids ("tilings"), each shifted by a fraction of a
tile, and the active tile of every tiling is one binary feature. Linear Q over these features
generalises locally (nearby states share most tiles) while staying cheap: a state has exactly
``n_tilings`` active features.

Design choices (the paper gives none of these):

* **Inputs are in [0, 1].** The paper maps every sensory input to [0, 1]; the coder rejects
  anything else (including NaN) with a ``ValueError`` instead of silently clipping, because an
  out-of-range input here always means a normalisation bug upstream.
* **Per-dimension resolution.** ``resolution[d]`` tiles span [0, 1] along dimension ``d`` in every
  tiling, so a fine bearing and a coarse distance can share one coder.
* **Asymmetric offsets.** Tiling ``t`` is shifted by ``((t * (2d + 1)) mod n_tilings) /
  n_tilings`` of a tile along dimension ``d`` (the displacement vector (1, 3, 5, ...) recommended
  by Sutton & Barto and used by Sutton's ``tiles3``); uniform diagonal offsets would line the tiles
  up along the diagonal and generalise worse.
* **Wrap-around.** A dimension flagged in ``wrap`` is periodic: 0 and 1 are the same point. Use it
  for a bearing normalised from [-π, π] (a target at -179° and one at +179° are both straight
  behind and should share tiles). Distances and proximity readings are not periodic.
* **Hashing into a fixed table.** The integer tile coordinates ``(tiling, c_0, ..., c_{d-1})``
  are hashed with a seeded 32-bit integer mixer (Wellons' ``lowbias32``) and reduced modulo
  ``table_size``. The hash is plain integer arithmetic that we implement ourselves: no Python
  ``hash()`` (salted per process for ``str``), no dict visit order, so the same config gives the
  same indices in every process, on every Python run and in the torch export
  (:mod:`behaviours.export`), which reimplements exactly these operations. All intermediate
  products stay below 2**49, so int64 arithmetic in numpy and torch never overflows.
* **Vectorised.** A batch of states maps to a ``(batch, n_tilings)`` index array with a handful
  of numpy operations. When the coordinate space is small (the usual case: a few dimensions of
  ≲ 20 tiles) the hash of every coordinate is precomputed into a lookup table at construction;
  the result is identical to hashing on the fly (a test checks it), only faster.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cyber_rodent.validation import integer, validate_fields

#: Version of the hash and offset scheme. Saved with action values: a table trained under one
#: scheme is meaningless under another, so loading checks it.
HASH_VERSION = 1

#: Low 32 and 16 bits (the hash works on unsigned 32-bit values held in int64).
MASK32 = 0xFFFFFFFF
MASK16 = 0xFFFF
#: Multipliers of Chris Wellons' ``lowbias32`` integer hash (a well-tested 32-bit mixer).
MIX_MUL_1 = 0x7FEB352D
MIX_MUL_2 = 0x846CA68B
#: Lookup tables larger than this many entries are not precomputed (hash on the fly instead).
_MAX_LOOKUP_ENTRIES = 1 << 22


def _mul32(x: np.ndarray, constant: int) -> np.ndarray:
    """``(x * constant) mod 2**32`` for ``0 <= x < 2**32`` without int64 overflow.

    The constant is split into 16-bit halves so that every partial product is below 2**49; the
    same formula runs unchanged on torch int64 tensors (torch has no uint32 multiply).
    """
    lo = constant & MASK16
    hi = constant >> 16
    product: np.ndarray = (x * lo + (((x * hi) & MASK16) << 16)) & MASK32
    return product


def mix32(x: np.ndarray) -> np.ndarray:
    """Wellons' ``lowbias32`` mixer on int64 arrays holding unsigned 32-bit values.

    A bijection of [0, 2**32) with good avalanche; the building block of the tile hash.

    Args:
        x: int64 array with values in [0, 2**32).

    Returns:
        int64 array, same shape, values in [0, 2**32).
    """
    x = x ^ (x >> 16)
    x = _mul32(x, MIX_MUL_1)
    x = x ^ (x >> 15)
    x = _mul32(x, MIX_MUL_2)
    mixed: np.ndarray = x ^ (x >> 16)
    return mixed


@dataclass(frozen=True)
class TileCoderConfig:
    """Geometry of a hashed tile coder.

    Attributes:
        resolution: tiles spanning [0, 1] per input dimension (≥ 1 each); its length is the
            number of input dimensions.
        n_tilings: number of offset tilings = active features per state (1–1024). Sutton &
            Barto recommend a power of two ≥ 4 × dimensions; 8 suits the 2-D behaviour inputs.
        table_size: size of the hashed feature table (1 to 2**31). Large enough that collisions
            between reachable tiles are rare; a 2-D input at resolution 10 with 8 tilings touches
            ≤ 8 × 11 × 11 = 968 tiles, so 4096 keeps collisions small.
        wrap: per dimension, whether it is periodic (0 ≡ 1), e.g. a bearing. Default (empty):
            none.
        seed: hash seed in [0, 2**32). Different seeds give independent hash layouts.
    """

    resolution: tuple[int, ...]
    n_tilings: int = integer(8, 1, 1024)
    table_size: int = integer(4096, 1, 2**31)
    wrap: tuple[bool, ...] = ()
    seed: int = integer(0, 0, 2**32 - 1)

    def __post_init__(self) -> None:
        resolution = tuple(int(r) for r in self.resolution)
        if len(resolution) == 0:
            raise ValueError("resolution: need at least one input dimension, got an empty tuple")
        if any(r < 1 or r > 1_000_000 for r in resolution):
            raise ValueError(f"resolution: every entry must be in [1, 1000000], got {resolution}")
        object.__setattr__(self, "resolution", resolution)
        wrap = tuple(bool(w) for w in self.wrap) if self.wrap else (False,) * len(resolution)
        if len(wrap) != len(resolution):
            raise ValueError(
                f"wrap: need one flag per input dimension ({len(resolution)}), got {len(wrap)}"
            )
        object.__setattr__(self, "wrap", wrap)
        validate_fields(self)

    @property
    def n_dims(self) -> int:
        """Number of input dimensions."""
        return len(self.resolution)

    def to_dict(self) -> dict[str, Any]:
        """Plain-dict form (JSON-safe), saved alongside action values."""
        return {
            "resolution": list(self.resolution),
            "n_tilings": self.n_tilings,
            "table_size": self.table_size,
            "wrap": list(self.wrap),
            "seed": self.seed,
            "hash_version": HASH_VERSION,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TileCoderConfig:
        """Inverse of :meth:`to_dict`; rejects a table hashed under another scheme."""
        version = data.get("hash_version")
        if version != HASH_VERSION:
            raise ValueError(
                f"hash_version: this code hashes tiles with scheme {HASH_VERSION}, "
                f"the data was made with {version!r}"
            )
        return cls(
            resolution=tuple(data["resolution"]),
            n_tilings=int(data["n_tilings"]),
            table_size=int(data["table_size"]),
            wrap=tuple(data["wrap"]),
            seed=int(data["seed"]),
        )


def _describe_range(x: np.ndarray) -> str:
    """Human-readable summary of bad inputs for error messages (off the hot path)."""
    finite = x[~np.isnan(x)]
    text = f"values in [{finite.min()}, {finite.max()}]" if finite.size else "no numbers"
    return text + (" and NaN" if finite.size < x.size else "")


class TileCoder:
    """Maps batches of states in [0, 1]^d to hashed tile indices.

    Example:
        >>> coder = TileCoder(TileCoderConfig(resolution=(8, 4), wrap=(True, False)))
        >>> coder.indices(np.array([[0.5, 0.2]])).shape
        (1, 8)
    """

    def __init__(self, config: TileCoderConfig) -> None:
        self.config = config
        n, dims = config.n_tilings, config.n_dims
        resolution = np.asarray(config.resolution, dtype=np.int64)
        #: x * scale, floored, is the input position in units of 1/n_tilings of a tile.
        self.scale = resolution.astype(np.float64) * n
        tilings = np.arange(n, dtype=np.int64)
        displacement = 2 * np.arange(dims, dtype=np.int64) + 1
        #: (n_tilings, n_dims) offsets in units of 1/n_tilings of a tile.
        self.offsets = (tilings[:, None] * displacement[None, :]) % n
        # Coordinates along a dimension lie in [0, resolution]: resolution + 1 values, or
        # resolution values when periodic (coordinate `resolution` wraps to 0). Reducing modulo
        # this count is the identity for non-periodic dimensions and the wrap for periodic ones.
        wrap = np.asarray(config.wrap, dtype=bool)
        self.coordinate_count = np.where(wrap, resolution, resolution + 1)
        #: (n_tilings,) hash state after the seed and the tiling number.
        self.tiling_hash = mix32(mix32(np.full(n, config.seed, dtype=np.int64)) ^ tilings)

        per_tiling = int(np.prod(self.coordinate_count))
        self._lookup: np.ndarray | None = None
        if per_tiling * n <= _MAX_LOOKUP_ENTRIES:
            strides = np.ones(dims, dtype=np.int64)
            for d in range(dims - 2, -1, -1):
                strides[d] = strides[d + 1] * self.coordinate_count[d + 1]
            grid = np.stack(
                np.unravel_index(np.arange(per_tiling), tuple(self.coordinate_count)), axis=-1
            ).astype(np.int64)  # (per_tiling, dims), row-major like `strides`
            coords = np.broadcast_to(grid[:, None, :], (per_tiling, n, dims))
            self._lookup = np.ascontiguousarray(self._hash(coords).T).reshape(-1)
            self._strides = strides
            self._tiling_base = np.arange(n, dtype=np.int64) * per_tiling

    @property
    def lookup(self) -> np.ndarray | None:
        """Precomputed hash of every tile (flat tile index -> table row), or None if the
        coder hashes on the fly."""
        return self._lookup

    @property
    def strides(self) -> np.ndarray:
        """Flat-tile-index stride of each dimension (with a precomputed :attr:`lookup`)."""
        return self._strides

    @property
    def tiling_base(self) -> np.ndarray:
        """Where each tiling's block starts in :attr:`lookup`."""
        return self._tiling_base

    @property
    def n_tilings(self) -> int:
        """Active features per state."""
        return self.config.n_tilings

    @property
    def table_size(self) -> int:
        """Size of the hashed feature table."""
        return self.config.table_size

    def coordinates(self, states: np.ndarray) -> np.ndarray:
        """Integer tile coordinates before hashing.

        Args:
            states: (batch, n_dims) or (n_dims,) values in [0, 1].

        Returns:
            int64 array (batch, n_tilings, n_dims) (or (n_tilings, n_dims) for one state):
            along dimension ``d``, tiling ``t`` covers ``x`` with tile
            ``floor((floor(x * resolution[d] * n_tilings) + offsets[t, d]) / n_tilings)``,
            reduced modulo ``resolution[d]`` if the dimension wraps.
        """
        x, single = self._check(states)
        coords = self._coordinates(x)
        return coords[0] if single else coords

    def indices(self, states: np.ndarray) -> np.ndarray:
        """Hashed feature indices of the active tiles.

        Args:
            states: (batch, n_dims) or (n_dims,) values in [0, 1].

        Returns:
            int64 array (batch, n_tilings) (or (n_tilings,) for one state) in [0, table_size).

        Raises:
            ValueError: wrong shape, or any value outside [0, 1] (or NaN).
        """
        x, single = self._check(states)
        coords = self._coordinates(x)
        out: np.ndarray
        if self._lookup is not None:
            flat = coords @ self._strides + self._tiling_base
            out = self._lookup[flat]
        else:
            out = self._hash(coords)
        return out[0] if single else out

    def hashed_indices(self, states: np.ndarray) -> np.ndarray:
        """Like :meth:`indices` but always hashing on the fly (the reference path)."""
        x, single = self._check(states)
        out = self._hash(self._coordinates(x))
        return out[0] if single else out

    def _check(self, states: np.ndarray) -> tuple[np.ndarray, bool]:
        x = np.asarray(states, dtype=np.float64)
        single = x.ndim == 1
        if single:
            x = x[None, :]
        if x.ndim != 2 or x.shape[1] != self.config.n_dims:
            raise ValueError(
                f"states: expected shape (batch, {self.config.n_dims}) or "
                f"({self.config.n_dims},), got {np.shape(states)}"
            )
        # One comparison pair; also catches NaN (all comparisons with NaN are False).
        if x.size and not (x.min() >= 0.0 and x.max() <= 1.0):
            raise ValueError(f"states: every input must be in [0, 1], got {_describe_range(x)}")
        return x, single

    def _coordinates(self, x: np.ndarray) -> np.ndarray:
        q = np.floor(x * self.scale).astype(np.int64)  # (batch, dims)
        coords = (q[:, None, :] + self.offsets[None, :, :]) // self.config.n_tilings
        return coords % self.coordinate_count

    def _hash(self, coords: np.ndarray) -> np.ndarray:
        """Hash (..., n_tilings, n_dims) coordinates to (..., n_tilings) table indices."""
        h = np.broadcast_to(self.tiling_hash, coords.shape[:-1])
        for d in range(coords.shape[-1]):
            h = mix32(h ^ coords[..., d])
        return h % self.config.table_size
