"""The watchdog's per-step rule (:mod:`cyber_rodent.survival.watchdog`), compiled and in numpy.

:func:`watch` updates every robot's tipped and stuck counters from the chassis' pose and the
step's commands and flags, and writes a code per robot of what changed
(:data:`TIP_STARTED` ... :data:`RESCUE_DUE`, bits); it returns whether any robot's code is
nonzero, so the Python side (events, rescues) runs only on the rare steps that need it.
:func:`watch_reference` is the same rule in numpy, bit for bit (comparisons and counts only).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cyber_rodent.backend import jit

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Bools = npt.NDArray[np.bool_]

#: Bits of :attr:`WatchState.change`.
TIP_STARTED, TIP_ENDED, STUCK_STARTED, STUCK_ENDED, RESCUE_DUE = 1, 2, 4, 8, 16


class WatchRules(NamedTuple):
    """The watchdog's thresholds."""

    tip_uprightness: float  #: tipped below this uprightness
    stuck_limit: int  #: control steps of commanded motion without progress: stuck
    stuck_distance2: float  #: m², the squared progress that restarts the count
    stuck_cos: float  #: cosine of the turn (from the heading where the run began) that does too
    moving_command: float  #: m/s, the drive or turn command that counts as commanding motion
    rescue_after: int  #: control steps tipped or stuck before a rescue is due (0: never)
    #: share of the step's commanded travel or turn that, achieved, counts as moving
    progress_share: float
    step_s: float  #: s, one control step
    half_wheel_base: float  #: m, turn rate = (right - left) / 2 / half_wheel_base


class WatchInputs(NamedTuple):
    """What the watchdog reads each step (views of MuJoCo's and the world's arrays)."""

    xmat: Floats  #: (nbody, 9) MjData.xmat
    xpos: Floats  #: (nbody, 3) MjData.xpos
    chassis: Ints  #: (n,) each robot's chassis body
    wheels: Floats  #: (n, 2) m/s, the step's wheel commands
    docked: Bools  #: (n,) docked (may stand still)
    reflex_steps: Ints  #: (n,) steps of the rotation reflex still to run (> 0: may not move on)
    active: Bools  #: (n,) runs an agent


class WatchState(NamedTuple):
    """The watchdog's counters and its output."""

    tipped_steps: Ints  #: (n,) control steps tipped so far (0: not tipped)
    stuck_steps: Ints  #: (n,) control steps stuck so far (0: not stuck)
    trying: Ints  #: (n,) control steps of commanded motion without progress
    anchor: Floats  #: (n, 2) where the current run of such steps began
    anchor_heading: Floats  #: (n, 2) the chassis' x axis (world x, y) when it began
    last: Floats  #: (n, 2) the chassis' position at the previous step
    last_heading: Floats  #: (n, 2) its x axis (world x, y) at the previous step
    ended: Ints  #: (n, 2) out: how long a tip (column 0), a jam (1) that ended lasted
    change: Ints  #: (n,) out: what changed this step (bits)


@jit
def watch(rules: WatchRules, inputs: WatchInputs, state: WatchState) -> bool:
    """One step of the watchdog for every robot; True if any robot's ``change`` is nonzero."""
    anything = False
    for i in range(state.change.shape[0]):
        change = 0
        body = inputs.chassis[i]
        tipped = inputs.xmat[body, 8] < rules.tip_uprightness
        if tipped:
            if state.tipped_steps[i] == 0:
                change |= TIP_STARTED
            state.tipped_steps[i] += 1
        elif state.tipped_steps[i] > 0:
            change |= TIP_ENDED
            state.ended[i, 0] = state.tipped_steps[i]
            state.tipped_steps[i] = 0
        x, y = inputs.xpos[body, 0], inputs.xpos[body, 1]
        hx, hy = inputs.xmat[body, 0], inputs.xmat[body, 3]
        mean = (inputs.wheels[i, 0] + inputs.wheels[i, 1]) * 0.5
        turn = (inputs.wheels[i, 1] - inputs.wheels[i, 0]) * 0.5
        moving = (
            max(abs(mean), abs(turn)) >= rules.moving_command
            and inputs.active[i]
            and not inputs.docked[i]
            and inputs.reflex_steps[i] == 0
            and not tipped
        )
        # This step's own progress: a robot that achieves a share of what it commanded (a
        # robot dithering left and right on the spot) is moving, not held.
        sx, sy = x - state.last[i, 0], y - state.last[i, 1]
        lx, ly = state.last_heading[i, 0], state.last_heading[i, 1]
        rotated = abs(np.arctan2(lx * hy - ly * hx, lx * hx + ly * hy))
        share = rules.progress_share
        travelled = np.sqrt(sx * sx + sy * sy) >= share * abs(mean) * rules.step_s
        spun = rotated >= share * abs(turn) / rules.half_wheel_base * rules.step_s
        progressed = (abs(mean) >= rules.moving_command and travelled) or (
            abs(turn) >= rules.moving_command and spun
        )
        state.last[i, 0], state.last[i, 1] = x, y
        state.last_heading[i, 0], state.last_heading[i, 1] = hx, hy
        dx, dy = x - state.anchor[i, 0], y - state.anchor[i, 1]
        ax, ay = state.anchor_heading[i, 0], state.anchor_heading[i, 1]
        norms = (hx * hx + hy * hy) * (ax * ax + ay * ay)
        turned = norms <= 0.0 or hx * ax + hy * ay < rules.stuck_cos * np.sqrt(norms)
        if not moving or progressed or dx * dx + dy * dy > rules.stuck_distance2 or turned:
            state.anchor[i, 0], state.anchor[i, 1] = x, y
            state.anchor_heading[i, 0], state.anchor_heading[i, 1] = hx, hy
            state.trying[i] = 0
        else:
            state.trying[i] += 1
        if state.trying[i] >= rules.stuck_limit:
            if state.stuck_steps[i] == 0:
                change |= STUCK_STARTED
            state.stuck_steps[i] += 1
        elif state.stuck_steps[i] > 0:
            change |= STUCK_ENDED
            state.ended[i, 1] = state.stuck_steps[i]
            state.stuck_steps[i] = 0
        due = rules.rescue_after
        if due > 0 and (state.tipped_steps[i] >= due or state.stuck_steps[i] >= due):
            change |= RESCUE_DUE
        state.change[i] = change
        if change:
            anything = True
    return anything


def watch_reference(rules: WatchRules, inputs: WatchInputs, state: WatchState) -> bool:
    """:func:`watch` in numpy."""
    body = inputs.chassis
    tipped = inputs.xmat[body, 8] < rules.tip_uprightness
    was_tipped = state.tipped_steps > 0
    change = np.zeros_like(state.change)
    change[tipped & ~was_tipped] |= TIP_STARTED
    tip_ended = ~tipped & was_tipped
    change[tip_ended] |= TIP_ENDED
    state.ended[tip_ended, 0] = state.tipped_steps[tip_ended]
    state.tipped_steps[tipped] += 1
    state.tipped_steps[~tipped] = 0
    position = inputs.xpos[body, :2]
    heading = inputs.xmat[body][:, [0, 3]]
    mean = (inputs.wheels[:, 0] + inputs.wheels[:, 1]) * 0.5
    turn = (inputs.wheels[:, 1] - inputs.wheels[:, 0]) * 0.5
    command = np.maximum(np.abs(mean), np.abs(turn))
    moving = (command >= rules.moving_command) & inputs.active & ~inputs.docked
    moving &= (inputs.reflex_steps == 0) & ~tipped
    step = position - state.last
    lh = state.last_heading
    cross = lh[:, 0] * heading[:, 1] - lh[:, 1] * heading[:, 0]
    rotated = np.abs(np.arctan2(cross, lh[:, 0] * heading[:, 0] + lh[:, 1] * heading[:, 1]))
    share = rules.progress_share
    travelled = np.sqrt(step[:, 0] * step[:, 0] + step[:, 1] * step[:, 1]) >= (
        share * np.abs(mean) * rules.step_s
    )
    spun = rotated >= share * np.abs(turn) / rules.half_wheel_base * rules.step_s
    progressed = ((np.abs(mean) >= rules.moving_command) & travelled) | (
        (np.abs(turn) >= rules.moving_command) & spun
    )
    state.last[...] = position
    state.last_heading[...] = heading
    gap = position - state.anchor
    far = gap[:, 0] * gap[:, 0] + gap[:, 1] * gap[:, 1] > rules.stuck_distance2
    h, a = heading, state.anchor_heading
    norms = (h[:, 0] * h[:, 0] + h[:, 1] * h[:, 1]) * (a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1])
    dot = h[:, 0] * a[:, 0] + h[:, 1] * a[:, 1]
    turned = (norms <= 0.0) | (dot < rules.stuck_cos * np.sqrt(norms))
    restart = ~moving | progressed | far | turned
    state.anchor[restart] = position[restart]
    state.anchor_heading[restart] = heading[restart]
    state.trying[restart] = 0
    state.trying[~restart] += 1
    stuck = state.trying >= rules.stuck_limit
    was_stuck = state.stuck_steps > 0
    change[stuck & ~was_stuck] |= STUCK_STARTED
    stuck_ended = ~stuck & was_stuck
    change[stuck_ended] |= STUCK_ENDED
    state.ended[stuck_ended, 1] = state.stuck_steps[stuck_ended]
    state.stuck_steps[stuck] += 1
    state.stuck_steps[~stuck] = 0
    if rules.rescue_after > 0:
        due = (state.tipped_steps >= rules.rescue_after) | (state.stuck_steps >= rules.rescue_after)
        change[due] |= RESCUE_DUE
    state.change[...] = change
    return bool(change.any())


__all__ = [
    "RESCUE_DUE",
    "STUCK_ENDED",
    "STUCK_STARTED",
    "TIP_ENDED",
    "TIP_STARTED",
    "WatchInputs",
    "WatchRules",
    "WatchState",
    "watch",
    "watch_reference",
]
