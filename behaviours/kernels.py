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
    proximity_columns: Ints  #: (6,) sensors of the proximity inputs (``RobotModel.proximity``)
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


# --- in-life learning: Sarsa(λ) inside the step ----------------------------------------------
#
# The algorithm of :class:`behaviours.sarsa.SarsaLambda` (linear Sarsa(λ), replacing traces that
# clear the other actions' traces at the visited tiles, sparse traces dropped below a cutoff,
# ε-greedy with ties broken at random), for every robot's active agent at once, each with its
# own action values and meta-parameters. Every float operation is the one SarsaLambda's numpy
# code does, in the same order, so identical transitions give identical weights
# (``tests/test_learning.py``). That includes numpy's summation orders: the action values of
# the next state sum the tilings one after another (a reduction over the second axis), while
# Q(s, a) in the error is numpy's pairwise sum of a 1-D array (:func:`_pairwise_tile_sum`).

#: Tilings the pairwise sum covers (numpy switches to recursive halving above this).
MAX_LEARNING_TILINGS = 128


class LearnedValues(NamedTuple):
    """Every agent's private action values and learning parameters, by table index.

    Table ``k`` belongs to one agent slot; a newborn in the slot bumps ``serial[k]``, so an
    episode begun by the previous agent is never continued on the newborn's values.
    """

    values: npt.NDArray[np.floating]  #: (tables, rows, actions) float32 or float64
    alpha: Floats  #: (tables,) step size for the whole feature vector
    gamma: Floats  #: (tables,) discount
    lam: Floats  #: (tables,) trace decay
    epsilon: Floats  #: (tables,) exploration rate
    shaping: Floats  #: (tables, 3, 2) potential weights: Φ_b(s) = shaping[b] · s_b
    serial: Ints  #: (tables,) births into the table so far


class LearningEpisodes(NamedTuple):
    """Each robot's open learning episode: the behaviour it runs, learning on one agent's
    values. Traces are dense per robot with a list of the entries that may be nonzero."""

    open: Bools  #: (n,) an episode is open
    table: Ints  #: (n,) its agent's table
    serial: Ints  #: (n,) that table's serial when the episode began
    behaviour: Ints  #: (n,) its behaviour
    rows: Ints  #: (n, T) table rows of the last state's tiles (stacked behaviours)
    action: Ints  #: (n,) the last action
    potential: Floats  #: (n,) Φ of the last state
    reward: Floats  #: (n,) reward accrued since the last decision (shaping not yet added)
    trace: Floats  #: (n, rows * actions) eligibility traces, index row * actions + action
    active: Ints  #: (n, rows * actions) entries that may hold a nonzero trace
    n_active: Ints  #: (n,) how many of ``active`` are in use


class LearningStep(NamedTuple):
    """What the learner reads at a decision, and its scratch space."""

    table: Ints  #: (n,) the robot's active agent's table, -1 if the robot idles
    acting: Bools  #: (n,) its behaviour drives the wheels this step (not docked, no reflex)
    uniforms: Floats  #: (n, 4) this step's exploration draws in [0, 1)
    trace_cutoff: float  #: traces below this are dropped
    idle_command: int  #: command of a robot whose behaviour does not act
    rows_next: Ints  #: (T,) scratch: rows of the next state's tiles
    q_next: Floats  #: (actions,) scratch: the next state's action values


class LearningOutcome(NamedTuple):
    """What the step did to each robot's open episode (set by the learner after the step)."""

    reward: Floats  #: (n,) the step's reward, shaping aside
    goal: Bools  #: (n,) the episode's goal was reached: a terminal transition
    ended: Bools  #: (n,) the agent's life ended: close the episode without learning


@jit_inline
def _tile_rows(x0: float, x1: float, b: int, tables: GreedyTables, rows: Ints) -> None:
    """Rows of the stacked table of the tiles of state (x0, x1) of behaviour ``b``."""
    n_tilings = tables.offsets.shape[1]
    for t in range(n_tilings):
        flat = 0
        for d in range(2):
            x = x0 if d == 0 else x1
            q = np.int64(math.floor(x * tables.scale[b, d]))
            c = (q + tables.offsets[b, t, d]) // n_tilings
            c %= tables.coordinate_count[b, d]
            flat += c * tables.strides[b, d]
        rows[t] = tables.lookup[flat + tables.base[b, t]]


@jit_inline
def _sequential_q(values: npt.NDArray[np.floating], k: int, rows: Ints, out: Floats) -> None:
    """Each action's value: its tiles' weights added one tiling after another."""
    for a in range(out.shape[0]):
        total = 0.0
        for t in range(rows.shape[0]):
            total += np.float64(values[k, rows[t], a])
        out[a] = total


@jit_inline
def _pairwise_tile_sum(values: npt.NDArray[np.floating], k: int, rows: Ints, a: int) -> float:
    """numpy's pairwise sum of one action's tile weights (up to 128 tiles)."""
    n = rows.shape[0]
    if n < 8:
        total = 0.0
        for t in range(n):
            total += np.float64(values[k, rows[t], a])
        return total
    r0 = np.float64(values[k, rows[0], a])
    r1 = np.float64(values[k, rows[1], a])
    r2 = np.float64(values[k, rows[2], a])
    r3 = np.float64(values[k, rows[3], a])
    r4 = np.float64(values[k, rows[4], a])
    r5 = np.float64(values[k, rows[5], a])
    r6 = np.float64(values[k, rows[6], a])
    r7 = np.float64(values[k, rows[7], a])
    tail = n - n % 8
    for i in range(8, tail, 8):
        r0 += np.float64(values[k, rows[i], a])
        r1 += np.float64(values[k, rows[i + 1], a])
        r2 += np.float64(values[k, rows[i + 2], a])
        r3 += np.float64(values[k, rows[i + 3], a])
        r4 += np.float64(values[k, rows[i + 4], a])
        r5 += np.float64(values[k, rows[i + 5], a])
        r6 += np.float64(values[k, rows[i + 6], a])
        r7 += np.float64(values[k, rows[i + 7], a])
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for t in range(tail, n):
        total += np.float64(values[k, rows[t], a])
    return total


@jit_inline
def _choose(q: Floats, epsilon: float, u0: float, u1: float) -> int:
    """ε-greedy: with probability ε a uniform action (``u0 < ε``, picked by ``u1``), else a
    greedy one, a tie broken uniformly by ``u1``."""
    n = int(q.shape[0])
    if epsilon > 0.0 and u0 < epsilon:
        a = int(u1 * n)
        return a if a < n else n - 1
    best = q[0]
    count = 1
    for a in range(1, n):
        if q[a] > best:
            best = q[a]
            count = 1
        elif q[a] == best:
            count += 1
    pick = int(u1 * count)
    if pick >= count:
        pick = count - 1
    for a in range(n):
        if q[a] == best:
            if pick == 0:
                return a
            pick -= 1
    return n - 1


@jit_inline
def _potential(values: LearnedValues, k: int, b: int, x0: float, x1: float) -> float:
    """Φ_b(s) = w_b0 s_0 + w_b1 s_1 of agent table ``k``."""
    return float(values.shaping[k, b, 0] * x0 + values.shaping[k, b, 1] * x1)


@jit_inline
def _learn(
    values: LearnedValues, episodes: LearningEpisodes, i: int, delta: float, decay_cutoff: float
) -> None:
    """Move the traced weights by α/T δ e; then, if ``decay_cutoff`` > 0, decay the traces
    by γλ and drop those below the cutoff (a non-terminal step), else clear them."""
    k = episodes.table[i]
    n_tilings = episodes.rows.shape[1]
    flat = values.values[k].reshape(-1)
    trace = episodes.trace[i]
    active = episodes.active[i]
    x = (values.alpha[k] / n_tilings) * delta
    m = episodes.n_active[i]
    for j in range(m):
        e = active[j]
        flat[e] = np.float64(flat[e]) + x * trace[e]
    if decay_cutoff > 0.0:
        decay = values.gamma[k] * values.lam[k]
        kept = 0
        for j in range(m):
            e = active[j]
            d = trace[e] * decay
            if d >= decay_cutoff:
                trace[e] = d
                active[kept] = e
                kept += 1
            else:
                trace[e] = 0.0
        episodes.n_active[i] = kept
    else:
        for j in range(m):
            trace[active[j]] = 0.0
        episodes.n_active[i] = 0


@jit_inline
def _visit(episodes: LearningEpisodes, i: int, rows: Ints, a: int, n_actions: int) -> None:
    """Replacing traces for (s, a): the other actions' traces at s's tiles to 0, a's to 1."""
    trace = episodes.trace[i]
    active = episodes.active[i]
    for t in range(rows.shape[0]):
        base = rows[t] * n_actions
        for b in range(n_actions):
            if b != a:
                trace[base + b] = 0.0
    m = episodes.n_active[i]
    for t in range(rows.shape[0]):
        e = rows[t] * n_actions + a
        if trace[e] == 0.0:
            active[m] = e
            m += 1
        trace[e] = 1.0
    episodes.n_active[i] = m


@jit_inline
def _clear(episodes: LearningEpisodes, i: int) -> None:
    trace = episodes.trace[i]
    active = episodes.active[i]
    for j in range(episodes.n_active[i]):
        trace[active[j]] = 0.0
    episodes.n_active[i] = 0
    episodes.open[i] = False


@jit
def learn_commands(
    behaviour: Ints,
    inputs: BehaviourInputs,
    tables: GreedyTables,
    values: LearnedValues,
    episodes: LearningEpisodes,
    step: LearningStep,
    out: Ints,
) -> int:
    """Each robot's command from its active agent's own values, learning as it goes.

    Per robot, in order: an open episode that goes on (same agent, same behaviour, the
    behaviour acts) takes one Sarsa(λ) step to the state reached; one that does not is cut
    (the last transition still bootstraps from the state reached, as at a time limit, and the
    traces are cleared) or, if its agent's life ended, dropped; then a robot whose behaviour
    acts and has no open episode begins one. The reward of a transition is the step's reward
    plus the agent's shaping ``γ Φ(s') − Φ(s)``.

    Returns:
        :data:`OK`, :data:`BAD_BEHAVIOUR` or :data:`BAD_STATE` (then ``out`` is incomplete).
    """
    n = behaviour.shape[0]
    n_actions = values.values.shape[2]
    n_behaviours = tables.scale.shape[0]
    rows_next, q_next = step.rows_next, step.q_next
    for i in range(n):
        b = behaviour[i]
        if b < 0 or b >= n_behaviours:
            return BAD_BEHAVIOUR
        for c in range(3):
            states = inputs.mate if c == 0 else inputs.forage if c == 1 else inputs.search
            for d in range(2):
                x = states[i, d]
                if not (x >= 0.0 and x <= 1.0):
                    return BAD_STATE
    for i in range(n):
        b_now = behaviour[i]
        k_now = step.table[i]
        acting = step.acting[i] and k_now >= 0
        goes_on = False
        if episodes.open[i]:
            k = episodes.table[i]
            if values.serial[k] != episodes.serial[i]:
                _clear(episodes, i)  # its life ended; the table is a newborn's now
            elif acting and k_now == k and b_now == episodes.behaviour[i]:
                goes_on = True
            else:
                # Cut: bootstrap from the state reached under the episode's own behaviour.
                b = episodes.behaviour[i]
                states = inputs.mate if b == 0 else inputs.forage if b == 1 else inputs.search
                x0, x1 = states[i, 0], states[i, 1]
                _tile_rows(x0, x1, b, tables, rows_next)
                _sequential_q(values.values, k, rows_next, q_next)
                a_next = _choose(q_next, values.epsilon[k], step.uniforms[i, 0],
                                 step.uniforms[i, 1])  # fmt: skip
                gamma = values.gamma[k]
                reward = episodes.reward[i] + (
                    gamma * _potential(values, k, b, x0, x1) - episodes.potential[i]
                )
                q_sa = _pairwise_tile_sum(values.values, k, episodes.rows[i],
                                          episodes.action[i])  # fmt: skip
                delta = reward - q_sa
                delta += gamma * q_next[a_next]
                _learn(values, episodes, i, delta, 0.0)
                episodes.open[i] = False
        if not acting:
            out[i] = step.idle_command
            continue
        states = inputs.mate if b_now == 0 else inputs.forage if b_now == 1 else inputs.search
        x0, x1 = states[i, 0], states[i, 1]
        _tile_rows(x0, x1, b_now, tables, rows_next)
        _sequential_q(values.values, k_now, rows_next, q_next)
        a_next = _choose(q_next, values.epsilon[k_now], step.uniforms[i, 2], step.uniforms[i, 3])
        potential = _potential(values, k_now, b_now, x0, x1)
        if goes_on:
            gamma = values.gamma[k_now]
            reward = episodes.reward[i] + (gamma * potential - episodes.potential[i])
            q_sa = _pairwise_tile_sum(values.values, k_now, episodes.rows[i], episodes.action[i])
            delta = reward - q_sa
            delta += gamma * q_next[a_next]
            _learn(values, episodes, i, delta, step.trace_cutoff)
        else:
            episodes.open[i] = True
            episodes.table[i] = k_now
            episodes.serial[i] = values.serial[k_now]
            episodes.behaviour[i] = b_now
        _visit(episodes, i, rows_next, a_next, n_actions)
        for t in range(rows_next.shape[0]):
            episodes.rows[i, t] = rows_next[t]
        episodes.action[i] = a_next
        episodes.potential[i] = potential
        episodes.reward[i] = 0.0
        out[i] = a_next
    return OK


@jit
def learn_outcome(
    values: LearnedValues, episodes: LearningEpisodes, outcome: LearningOutcome
) -> None:
    """After the step: a reached goal is a terminal transition (Φ = 0 after it), a life that
    ended closes its episode unlearned, and every other open episode accrues the reward."""
    for i in range(episodes.open.shape[0]):
        if not episodes.open[i]:
            continue
        if outcome.ended[i]:
            _clear(episodes, i)
        elif outcome.goal[i]:
            k = episodes.table[i]
            reward = outcome.reward[i] + (0.0 - episodes.potential[i])
            delta = reward - _pairwise_tile_sum(values.values, k, episodes.rows[i],
                                                episodes.action[i])  # fmt: skip
            _learn(values, episodes, i, delta, 0.0)
            episodes.open[i] = False
        else:
            episodes.reward[i] += outcome.reward[i]


# numpy references of the learner: the same rules, robot by robot, in numpy.
def _tile_rows_reference(x: Floats, b: int, tables: GreedyTables) -> Ints:
    n_tilings = tables.offsets.shape[1]
    q = np.floor(x * tables.scale[b]).astype(np.int64)
    coords = (q[None, :] + tables.offsets[b]) // n_tilings
    coords %= tables.coordinate_count[b][None, :]
    flat = (coords * tables.strides[b][None, :]).sum(axis=-1) + tables.base[b]
    rows: Ints = tables.lookup[flat]
    return rows


def _sequential_q_reference(values: npt.NDArray[np.floating], k: int, rows: Ints) -> Floats:
    # A running sum over the tilings (cumsum adds strictly one after another).
    q: Floats = np.cumsum(values[k, rows].astype(np.float64), axis=0)[-1]
    return q


def _pairwise_tile_sum_reference(
    values: npt.NDArray[np.floating], k: int, rows: Ints, a: int
) -> float:
    return float(np.ascontiguousarray(values[k, rows, a], dtype=np.float64).sum())


def _choose_reference(q: Floats, epsilon: float, u0: float, u1: float) -> int:
    n = int(q.shape[0])
    if epsilon > 0.0 and u0 < epsilon:
        return min(int(u1 * n), n - 1)
    best = np.flatnonzero(q == q.max())
    return int(best[min(int(u1 * best.size), best.size - 1)])


def _learn_reference(
    values: LearnedValues, episodes: LearningEpisodes, i: int, delta: float, decay_cutoff: float
) -> None:
    k = int(episodes.table[i])
    n_tilings = episodes.rows.shape[1]
    flat = values.values[k].reshape(-1)
    trace = episodes.trace[i]
    m = int(episodes.n_active[i])
    active = episodes.active[i, :m]
    x = (values.alpha[k] / n_tilings) * delta
    flat[active] = (flat[active].astype(np.float64) + x * trace[active]).astype(flat.dtype)
    if decay_cutoff > 0.0:
        decayed = trace[active] * (values.gamma[k] * values.lam[k])
        keep = decayed >= decay_cutoff
        trace[active] = np.where(keep, decayed, 0.0)
        kept = active[keep]
        episodes.active[i, : kept.size] = kept
        episodes.n_active[i] = kept.size
    else:
        trace[active] = 0.0
        episodes.n_active[i] = 0


def _visit_reference(
    episodes: LearningEpisodes, i: int, rows: Ints, a: int, n_actions: int
) -> None:
    trace = episodes.trace[i]
    others = np.delete(np.arange(n_actions), a)
    trace[(rows[:, None] * n_actions + others[None, :]).reshape(-1)] = 0.0
    chosen = rows * n_actions + a
    # First occurrences in tiling order of the entries not yet listed (trace 0).
    fresh, first = np.unique(chosen[trace[chosen] == 0.0], return_index=True)
    fresh = fresh[np.argsort(first)]
    m = int(episodes.n_active[i])
    episodes.active[i, m : m + fresh.size] = fresh
    episodes.n_active[i] = m + fresh.size
    trace[chosen] = 1.0


def _clear_reference(episodes: LearningEpisodes, i: int) -> None:
    m = int(episodes.n_active[i])
    episodes.trace[i, episodes.active[i, :m]] = 0.0
    episodes.n_active[i] = 0
    episodes.open[i] = False


def _potential_reference(values: LearnedValues, k: int, b: int, x: Floats) -> float:
    return float(values.shaping[k, b, 0] * x[0] + values.shaping[k, b, 1] * x[1])


def learn_commands_reference(
    behaviour: Ints,
    inputs: BehaviourInputs,
    tables: GreedyTables,
    values: LearnedValues,
    episodes: LearningEpisodes,
    step: LearningStep,
    out: Ints,
) -> int:
    """:func:`learn_commands` in numpy."""
    n = behaviour.shape[0]
    if n and (behaviour.min() < 0 or behaviour.max() >= tables.scale.shape[0]):
        return BAD_BEHAVIOUR
    every = np.stack((inputs.mate, inputs.forage, inputs.search))
    if every.size and not (every.min() >= 0.0 and every.max() <= 1.0):
        return BAD_STATE
    n_actions = values.values.shape[2]
    u = step.uniforms
    for i in range(n):
        b_now = int(behaviour[i])
        k_now = int(step.table[i])
        acting = bool(step.acting[i]) and k_now >= 0
        goes_on = False
        if episodes.open[i]:
            k = int(episodes.table[i])
            if values.serial[k] != episodes.serial[i]:
                _clear_reference(episodes, i)
            elif acting and k_now == k and b_now == episodes.behaviour[i]:
                goes_on = True
            else:
                b = int(episodes.behaviour[i])
                x = every[b, i]
                q = _sequential_q_reference(values.values, k, _tile_rows_reference(x, b, tables))
                a_next = _choose_reference(q, values.epsilon[k], u[i, 0], u[i, 1])
                gamma = values.gamma[k]
                reward = episodes.reward[i] + (
                    gamma * _potential_reference(values, k, b, x) - episodes.potential[i]
                )
                q_sa = _pairwise_tile_sum_reference(
                    values.values, k, episodes.rows[i], int(episodes.action[i])
                )
                delta = reward - q_sa
                delta += gamma * q[a_next]
                _learn_reference(values, episodes, i, delta, 0.0)
                episodes.open[i] = False
        if not acting:
            out[i] = step.idle_command
            continue
        x = every[b_now, i]
        rows = _tile_rows_reference(x, b_now, tables)
        q = _sequential_q_reference(values.values, k_now, rows)
        a_next = _choose_reference(q, values.epsilon[k_now], u[i, 2], u[i, 3])
        potential = _potential_reference(values, k_now, b_now, x)
        if goes_on:
            gamma = values.gamma[k_now]
            reward = episodes.reward[i] + (gamma * potential - episodes.potential[i])
            q_sa = _pairwise_tile_sum_reference(
                values.values, k_now, episodes.rows[i], int(episodes.action[i])
            )
            delta = reward - q_sa
            delta += gamma * q[a_next]
            _learn_reference(values, episodes, i, delta, step.trace_cutoff)
        else:
            episodes.open[i] = True
            episodes.table[i] = k_now
            episodes.serial[i] = values.serial[k_now]
            episodes.behaviour[i] = b_now
        _visit_reference(episodes, i, rows, a_next, n_actions)
        episodes.rows[i] = rows
        episodes.action[i] = a_next
        episodes.potential[i] = potential
        episodes.reward[i] = 0.0
        out[i] = a_next
    return OK


def learn_outcome_reference(
    values: LearnedValues, episodes: LearningEpisodes, outcome: LearningOutcome
) -> None:
    """:func:`learn_outcome` in numpy."""
    for i in np.flatnonzero(episodes.open).tolist():
        if outcome.ended[i]:
            _clear_reference(episodes, i)
        elif outcome.goal[i]:
            k = int(episodes.table[i])
            reward = outcome.reward[i] + (0.0 - episodes.potential[i])
            delta = reward - _pairwise_tile_sum_reference(
                values.values, k, episodes.rows[i], int(episodes.action[i])
            )
            _learn_reference(values, episodes, i, delta, 0.0)
            episodes.open[i] = False
        else:
            episodes.reward[i] += outcome.reward[i]


__all__ = [
    "MAX_LEARNING_TILINGS",
    "LearnedValues",
    "LearningEpisodes",
    "LearningOutcome",
    "LearningStep",
    "learn_commands",
    "learn_commands_reference",
    "learn_outcome",
    "learn_outcome_reference",
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
