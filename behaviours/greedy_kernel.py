"""Compiled (numba) greedy action choice of the three behaviours, for every robot at once.

:class:`behaviours.policies.BehaviourPolicies` picks each robot's wheel command from its
behaviour's tile-coded action values once per control step. In numpy that is a dozen
fancy-indexing operations on (robots × tilings × actions) arrays, each a few microseconds of
overhead for a few hundred additions. :func:`act` does the same arithmetic in one compiled
loop, in the same order (tile coordinates, hashed lookup, the weight rows summed over the
tilings one after another, first maximum wins), so its choices equal the numpy path's bit for
bit (``tests/test_behaviours_policies.py`` compares them).

Compiled functions are cached on disk (numba's ``cache=True``).
"""

from __future__ import annotations

import math

import numpy as np

from cyber_rodent.compiled import AVAILABLE
from cyber_rodent.compiled import jit as _jit

__all__ = ["AVAILABLE"]

#: :func:`act` return codes.
OK, BAD_BEHAVIOUR, BAD_STATE = 0, 1, 2


@_jit
def act(behaviour, mate, forage, search, scale, offsets, count, strides, base, lookup, table, out):
    """Each robot's greedy command for its behaviour; returns :data:`OK` or an error code.

    Args:
        behaviour: (n,) int behaviour index per robot (0 Mate, 1 Forage, 2 Search).
        mate, forage, search: (n, dims) inputs of each behaviour, in [0, 1].
        scale: (B, dims) tiles per unit times tilings; offsets: (B, T, dims) tiling offsets;
        count: (B, dims) coordinates per dimension; strides: (B, dims) flat-index strides;
        base: (B, T) start of each tiling's block in ``lookup``; lookup: flat tile -> row of
        ``table``; table: (rows, n_actions) stacked action values.
        out: (n,) int64, the chosen commands.

    Returns:
        :data:`OK`, :data:`BAD_BEHAVIOUR` (an index outside [0, 3)) or :data:`BAD_STATE` (an
        input outside [0, 1] or NaN); ``out`` is incomplete unless OK.
    """
    n = behaviour.shape[0]
    n_tilings = offsets.shape[1]
    dims = scale.shape[1]
    n_actions = table.shape[1]
    acc = np.empty(n_actions)
    for i in range(n):
        b = behaviour[i]
        if b < 0 or b > 2:
            return BAD_BEHAVIOUR
    for i in range(n):
        b = behaviour[i]
        states = mate if b == 0 else forage if b == 1 else search
        for d in range(dims):
            x = states[i, d]
            if not (x >= 0.0 and x <= 1.0):
                return BAD_STATE
        for a in range(n_actions):
            acc[a] = 0.0
        for t in range(n_tilings):
            flat = 0
            for d in range(dims):
                q = np.int64(math.floor(states[i, d] * scale[b, d]))
                c = (q + offsets[b, t, d]) // n_tilings
                c %= count[b, d]
                flat += c * strides[b, d]
            row = lookup[flat + base[b, t]]
            for a in range(n_actions):
                acc[a] += table[row, a]
        best = 0
        for a in range(1, n_actions):
            if acc[a] > acc[best]:
                best = a
        out[i] = best
    return OK
