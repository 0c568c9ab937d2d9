"""Compiled (numba) mapping from sensor readings and nearest targets to behaviour inputs.

:class:`evolution.runner.perception.Perception` turns, every control step, the raw range
readings and each robot's nearest LED, face and pack into the controller's and behaviours'
inputs: two dozen numpy calls on (robots × 6) and (robots × 3) arrays whose cost is almost all
call overhead. :func:`map_inputs` does the same operations, in the same order and with the same
rounding (one division, one subtraction, clipping; bearings and distances normalised as
:mod:`behaviours.inputs` does), in one compiled loop, so its results are bit-identical
(``tests/test_evolution_runner_perception.py`` compares them).
"""

from __future__ import annotations

import math

from cyber_rodent.compiled import AVAILABLE
from cyber_rodent.compiled import jit as _jit

__all__ = ["AVAILABLE"]

_TWO_PI = 2 * math.pi


@_jit
def _clip01(x: float) -> float:
    """np.clip(x, 0, 1) (NaN stays NaN)."""
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@_jit
def map_inputs(
    raw,
    range_max,
    ranges,
    prox,
    prox_max,
    bearing,
    distance,
    visible,
    max_distance,
    led,
    face,
    battery,
    proximity,
    norm_bearing,
    norm_distance,
    mate,
    forage,
    search,
    mate_available,
    forage_available,
):
    """Fill the range, proximity and input buffers of every robot.

    Args:
        raw: (n, 8) rangefinder sensordata (-1: no hit); range_max: (n, 8) sensor ranges.
        ranges: (n, 8) output, readings saturated at the range (``World.range_readings``).
        prox: (6,) sensor columns of the proximity inputs; prox_max: (n, 6) their ranges.
        bearing, distance, visible: (n, 3) nearest target of each class.
        max_distance: m, distance normalisation; led, face, battery: class columns.
        proximity: (n, 6) output ``clip(1 - range / max, 0, 1)``.
        norm_bearing, norm_distance: (n, 3) outputs.
        mate, forage, search: (n, 2) outputs; mate_available, forage_available: (n,) outputs.
    """
    n = raw.shape[0]
    n_range = raw.shape[1]
    n_prox = prox.shape[0]
    n_classes = bearing.shape[1]
    for i in range(n):
        for j in range(n_range):
            r = raw[i, j]
            ranges[i, j] = range_max[i, j] if (r < 0.0 or r > range_max[i, j]) else r
        top1 = -math.inf
        top2 = -math.inf
        for j in range(n_prox):
            p = _clip01(1.0 - ranges[i, prox[j]] / prox_max[i, j])
            proximity[i, j] = p
            if p > top1:
                top2 = top1
                top1 = p
            elif p > top2:
                top2 = p
        search[i, 0] = top1
        search[i, 1] = top2
        for c in range(n_classes):
            norm_bearing[i, c] = _clip01((bearing[i, c] + math.pi) / _TWO_PI)
            norm_distance[i, c] = _clip01(distance[i, c] / max_distance)
        led_seen = visible[i, led]
        target = led if led_seen else face
        mate[i, 0] = norm_bearing[i, target]
        mate[i, 1] = norm_distance[i, target]
        forage[i, 0] = norm_bearing[i, battery]
        forage[i, 1] = norm_distance[i, battery]
        mate_available[i] = led_seen or visible[i, face]
        forage_available[i] = visible[i, battery]
