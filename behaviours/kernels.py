"""The behaviours' per-step rules: each as a compiled kernel and its numpy reference.

Two rules run every control step for every robot (``docs/design.md`` §3):

* :func:`map_inputs` / :func:`map_inputs_reference`: range readings and the nearest LED, face
  and pack to the three behaviours' inputs in [0, 1] (the mapping of
  :mod:`behaviours.inputs`), plus the six proximities and the normalised distances that the
  evolved controller reads;
* :func:`greedy_commands` / :func:`greedy_commands_reference`: each robot's wheel command, the
  greedy action of its chosen behaviour's tile-coded action values.

Each pair has the same signature and gives bit-identical results
(``tests/test_kernel_parity.py``): the reference does the same operations in the same order
(one division, one subtraction, clipping; tiles summed over the tilings one after another,
first maximum wins). The kernels read and write named buffers: :class:`RangeSensors`,
:class:`~cyber_rodent.vision.kernels.NearestTargets`, :class:`InputRules`,
:class:`InputBuffers` (with :class:`BehaviourInputs`) and :class:`GreedyTables`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cyber_rodent.backend import jit, jit_inline
from cyber_rodent.vision.kernels import NearestTargets

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Bools = npt.NDArray[np.bool_]

_TWO_PI = 2 * math.pi

#: :func:`greedy_commands` return codes.
OK, BAD_BEHAVIOUR, BAD_STATE = 0, 1, 2


class RangeSensors(NamedTuple):
    """The robots' rangefinders: raw readings in, saturated readings and proximities out."""

    raw: Floats  #: (n, 8) sensordata, -1 where a ray hit nothing (or readings to re-use)
    range_max: Floats  #: (n, 8) each sensor's range, m
    ranges: Floats  #: (n, 8) out: readings saturated at the range (``World.range_readings``)
    proximity_columns: Ints  #: (6,) sensors of the proximity inputs (``PROXIMITY_SIX``)
    proximity_max: Floats  #: (n, 6) their ranges


class InputRules(NamedTuple):
    """Constants of the input mapping."""

    max_distance: float  #: m normalised to 1
    led: int  #: class columns of :class:`NearestTargets`
    face: int
    battery: int


class BehaviourInputs(NamedTuple):
    """Every robot's inputs of the three behaviours at one instant, all in [0, 1].

    Attributes:
        mate: (n, 2) ``[bearing, distance]`` of the nearest green LED, or of the nearest red face
            if no LED is seen; ``[0.5, 1]`` if neither.
        forage: (n, 2) ``[bearing, distance]`` of the nearest battery pack; ``[0.5, 1]`` if none.
        search: (n, 2) ``[largest, second largest]`` of the six proximity readings.
        mate_available: (n,) bool, another CR is in view (its LED or face is seen).
        forage_available: (n,) bool, a battery pack is in view.
    """

    mate: Floats
    forage: Floats
    search: Floats
    mate_available: Bools
    forage_available: Bools

    @property
    def n_robots(self) -> int:
        """Number of robots (rows)."""
        return int(self.mate.shape[0])

    def of(self, behaviour: int) -> Floats:
        """The (n, 2) input array of behaviour index ``behaviour``."""
        return (self.mate, self.forage, self.search)[behaviour]


class InputBuffers(NamedTuple):
    """Everything :func:`map_inputs` writes: the behaviours' inputs and the controller's."""

    proximity: Floats  #: (n, 6) ``clip(1 - range / range_max, 0, 1)``, larger = closer
    norm_bearing: Floats  #: (n, 3) ``clip((bearing + π) / 2π, 0, 1)``; 0.5 where unseen
    norm_distance: Floats  #: (n, 3) ``clip(distance / max_distance, 0, 1)``; 1 where unseen
    behaviour: BehaviourInputs


class GreedyTables(NamedTuple):
    """B behaviours' tile coders and action values, stacked (B = 3: Mate, Forage, Search)."""

    scale: Floats  #: (B, dims) tiles per unit times tilings
    offsets: Ints  #: (B, T, dims) tiling offsets
    coordinate_count: Ints  #: (B, dims) coordinates per dimension
    strides: Ints  #: (B, dims) flat-index strides
    base: Ints  #: (B, T) start of each tiling's block in ``lookup``
    lookup: Ints  #: flat tile -> row of ``table``
    table: Floats  #: (rows, n_actions) stacked action values


# --- input mapping -----------------------------------------------------------------------------
@jit
def _clip01(x: float) -> float:
    """np.clip(x, 0, 1) (NaN stays NaN)."""
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@jit_inline
def map_inputs(
    sensors: RangeSensors, nearest: NearestTargets, rules: InputRules, out: InputBuffers
) -> None:
    """Fill the range readings, proximities and behaviour inputs of every robot."""
    raw, range_max, ranges = sensors.raw, sensors.range_max, sensors.ranges
    prox, prox_max = sensors.proximity_columns, sensors.proximity_max
    n, n_range = raw.shape
    n_prox = prox.shape[0]
    n_classes = nearest.bearing.shape[1]
    led, face, battery = rules.led, rules.face, rules.battery
    for i in range(n):
        for j in range(n_range):
            r = raw[i, j]
            ranges[i, j] = range_max[i, j] if (r < 0.0 or r > range_max[i, j]) else r
        top1 = -math.inf
        top2 = -math.inf
        for j in range(n_prox):
            p = _clip01(1.0 - ranges[i, prox[j]] / prox_max[i, j])
            out.proximity[i, j] = p
            if p > top1:
                top2 = top1
                top1 = p
            elif p > top2:
                top2 = p
        out.behaviour.search[i, 0] = top1
        out.behaviour.search[i, 1] = top2
        for c in range(n_classes):
            out.norm_bearing[i, c] = _clip01((nearest.bearing[i, c] + math.pi) / _TWO_PI)
            out.norm_distance[i, c] = _clip01(nearest.distance[i, c] / rules.max_distance)
        led_seen = nearest.visible[i, led]
        target = led if led_seen else face
        b = out.behaviour
        b.mate[i, 0] = out.norm_bearing[i, target]
        b.mate[i, 1] = out.norm_distance[i, target]
        b.forage[i, 0] = out.norm_bearing[i, battery]
        b.forage[i, 1] = out.norm_distance[i, battery]
        b.mate_available[i] = led_seen or nearest.visible[i, face]
        b.forage_available[i] = nearest.visible[i, battery]


def map_inputs_reference(
    sensors: RangeSensors, nearest: NearestTargets, rules: InputRules, out: InputBuffers
) -> None:
    """:func:`map_inputs` in numpy.

    Unseen targets have bearing 0 and distance inf (the vision's convention), so their inputs
    are exactly 0.5 ("ahead") and 1.
    """
    raw, range_max, ranges = sensors.raw, sensors.range_max, sensors.ranges
    saturated = (raw < 0) | (raw > range_max)
    np.copyto(ranges, raw)
    np.putmask(ranges, saturated, range_max)
    p = out.proximity
    np.divide(ranges[:, sensors.proximity_columns], sensors.proximity_max, out=p)
    np.subtract(1.0, p, out=p)
    np.clip(p, 0.0, 1.0, out=p)
    nb, nd = out.norm_bearing, out.norm_distance
    np.add(nearest.bearing, math.pi, out=nb)
    np.divide(nb, _TWO_PI, out=nb)
    np.clip(nb, 0.0, 1.0, out=nb)
    np.divide(nearest.distance, rules.max_distance, out=nd)
    np.clip(nd, 0.0, 1.0, out=nd)
    led_seen = nearest.visible[:, rules.led]
    b = out.behaviour
    b.mate[:, 0] = nb[:, rules.face]
    b.mate[:, 1] = nd[:, rules.face]
    np.copyto(b.mate[:, 0], nb[:, rules.led], where=led_seen)
    np.copyto(b.mate[:, 1], nd[:, rules.led], where=led_seen)
    b.forage[:, 0] = nb[:, rules.battery]
    b.forage[:, 1] = nd[:, rules.battery]
    ordered = np.sort(p, axis=1)
    b.search[:, 0] = ordered[:, -1]
    b.search[:, 1] = ordered[:, -2]
    np.logical_or(led_seen, nearest.visible[:, rules.face], out=b.mate_available)
    np.copyto(b.forage_available, nearest.visible[:, rules.battery])


# --- greedy behaviours -------------------------------------------------------------------------
@jit_inline
def greedy_commands(
    behaviour: Ints, inputs: BehaviourInputs, tables: GreedyTables, out: Ints
) -> int:
    """Each robot's greedy command for its behaviour; returns :data:`OK` or an error code.

    Args:
        behaviour: (n,) behaviour index per robot (0 Mate, 1 Forage, 2 Search).
        inputs: the behaviours' inputs (``mate``, ``forage``, ``search``), in [0, 1].
        tables: the stacked tile coders and action values.
        out: (n,) the chosen commands.

    Returns:
        :data:`OK`, :data:`BAD_BEHAVIOUR` (an index outside [0, B)) or :data:`BAD_STATE` (an
        input outside [0, 1] or NaN); ``out`` is incomplete unless OK.
    """
    n = behaviour.shape[0]
    n_tilings = tables.offsets.shape[1]
    dims = tables.scale.shape[1]
    n_behaviours = tables.scale.shape[0]
    n_actions = tables.table.shape[1]
    acc = np.empty(n_actions)
    for i in range(n):
        b = behaviour[i]
        if b < 0 or b >= n_behaviours:
            return BAD_BEHAVIOUR
    for i in range(n):
        b = behaviour[i]
        states = inputs.mate if b == 0 else inputs.forage if b == 1 else inputs.search
        for d in range(dims):
            x = states[i, d]
            if not (x >= 0.0 and x <= 1.0):
                return BAD_STATE
        for a in range(n_actions):
            acc[a] = 0.0
        for t in range(n_tilings):
            flat = 0
            for d in range(dims):
                q = np.int64(math.floor(states[i, d] * tables.scale[b, d]))
                c = (q + tables.offsets[b, t, d]) // n_tilings
                c %= tables.coordinate_count[b, d]
                flat += c * tables.strides[b, d]
            row = tables.lookup[flat + tables.base[b, t]]
            for a in range(n_actions):
                acc[a] += tables.table[row, a]
        best = 0
        for a in range(1, n_actions):
            if acc[a] > acc[best]:
                best = a
        out[i] = best
    return OK


def greedy_commands_reference(
    behaviour: Ints, inputs: BehaviourInputs, tables: GreedyTables, out: Ints
) -> int:
    """:func:`greedy_commands` in numpy."""
    n = behaviour.shape[0]
    if n and (behaviour.min() < 0 or behaviour.max() >= tables.scale.shape[0]):
        return BAD_BEHAVIOUR
    # Each robot's own behaviour's input row: stack (3, n, 2), pick [behaviour, robot].
    states = np.stack((inputs.mate, inputs.forage, inputs.search))[behaviour, np.arange(n)]
    if states.size and not (states.min() >= 0.0 and states.max() <= 1.0):
        return BAD_STATE
    n_tilings = tables.offsets.shape[1]
    q = np.floor(states * tables.scale[behaviour]).astype(np.int64)  # (n, dims)
    coords = (q[:, None, :] + tables.offsets[behaviour]) // n_tilings
    coords %= tables.coordinate_count[behaviour][:, None, :]
    flat = (coords * tables.strides[behaviour][:, None, :]).sum(axis=-1) + tables.base[behaviour]
    # Reduction over a non-innermost axis: numpy adds the tilings strictly in order.
    out[:] = np.argmax(tables.table[tables.lookup[flat]].sum(axis=-2), axis=-1)
    return OK


__all__ = [
    "BAD_BEHAVIOUR",
    "BAD_STATE",
    "OK",
    "BehaviourInputs",
    "GreedyTables",
    "InputBuffers",
    "InputRules",
    "RangeSensors",
    "greedy_commands",
    "greedy_commands_reference",
    "map_inputs",
    "map_inputs_reference",
]
