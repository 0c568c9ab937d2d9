"""The survival world's per-step rules: compiled kernels and their numpy references.

:class:`~cyber_rodent.survival.SurvivalWorld` runs its rules around every control step's
physics (docs/design.md §3, §5). Each rule is one compiled loop over the robots (numba) and one
numpy reference with the same signature, side by side; the world picks one of the two at
construction (``backend``) and binds it to its named buffers once:

* :func:`begin`: validate the wheel commands, then the motor commands (docked and dead robots
  stand still, a rotation reflex overrides the caller), the LEDs (the model's LED colours
  change only for robots whose LED switched; a dead robot's LED is dark) and who signals for
  mating;
* :func:`end`: reflex countdown, recharge energy, the stopping rules (reported, not applied:
  undocking draws the reflex from the world's generator, which stays in Python), the energy
  decay of everyone else and deaths;
* :func:`teeth_on_electrodes`: the contact scan for captures; it returns only the (robot,
  pack) pairs of robots that may dock (alive, not docked, not in their rotation reflex) onto
  packs that take a docking (active, ``WorldConfig.pack_reactivation_steps``); the alignment
  test and the docking itself stay in Python (rare);
* :func:`count_down_packs`: the end of a step for the packs that a docking made inactive:
  their countdowns, and their colour and dockability back when a countdown runs out (run only
  while some pack is inactive);
* :func:`mate`: IR mating: which signalling pairs hold the condition (robots of one arena, ports
  facing each other within the angle, within the distance), their consecutive-step streaks,
  and the exchanges (nearest pairs first, one partner per robot per step).

``tests/test_kernel_parity.py`` checks each kernel against its reference, and whole runs.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cyber_rodent.backend import jit

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Flags = npt.NDArray[np.bool_]


class SurvivalState(NamedTuple):
    """Per-robot state that persists from step to step (the world's public arrays)."""

    energy: Floats  #: (n,) virtual energy of the robot's active agent
    recharge_steps: Ints  #: (n,) consecutive recharge steps of the current docking
    docked: Flags  #: (n,) docked and recharging
    alive: Flags  #: (n,) energy above 0
    reflex_steps_left: Ints  #: (n,) steps of the rotation reflex still to run
    reflex_wheels: Floats  #: (n, 2) wheel speeds of the running reflex, m/s


class StepCommands(NamedTuple):
    """The caller's commands of the step (``SurvivalWorld.begin_step``)."""

    wheels: Floats  #: (n, 2) left/right wheel rim speeds, m/s
    led: Flags  #: (n,) green LED on
    mate: Flags  #: (n,) willing to mate
    continue_recharge: Flags  #: (n,) a docked robot's recharge decision (True: continue)


#: :func:`begin` results: done; a wheel speed is NaN or out of range; a docked robot stops
#: recharging and must be released first. Nothing is written unless the result is OK.
BEGIN_OK, BAD_WHEELS, RELEASE_FIRST = 0, 1, 2


class Actuation(NamedTuple):
    """Where :func:`begin` writes into the physical world: the motors and the LEDs."""

    ctrl: Floats  #: (n, 2) the wheel motors' controls, rad/s (a view of MjData.ctrl)
    led_on: Flags  #: (n,) the world's LED state (``World.led_on``)
    geom_rgba: npt.NDArray[np.float32]  #: (ngeom, 4) the model's geom colours
    led_geom: Ints  #: (n,) each robot's LED geom
    led_rgba: Floats  #: (2, 4) the LED's colour: dark (row 0) and lit (row 1)


class StepFlags(NamedTuple):
    """Who does what in the step in progress: written by :func:`begin`, read after it."""

    recharging: Flags  #: (n,) docked at the start of the step
    in_reflex: Flags  #: (n,) in the rotation reflex at the start of the step
    mate_signal: Flags  #: (n,) signals for mating this step (free and alive)


class EnergyOutcome(NamedTuple):
    """What :func:`end` reports for the world to act on (releases, death events)."""

    stop_reason: Ints  #: (n,) why a stopping rule ends the recharge (0: it does not)
    died: Flags  #: (n,) energy reached 0 this step


class SurvivalRules(NamedTuple):
    """The scalars of the rules (from ``SurvivalConfig`` and the robot)."""

    inv_wheel_radius: float  #: rad/s of wheel per m/s of rim speed
    top_speed: float  #: largest wheel rim speed, m/s
    recharge_gain: float  #: net energy change of a recharge step
    max_energy: float
    max_recharge_steps: int
    energy_decay: float
    mate_min_energy: float  #: a robot signals Mate only with energy above this
    max_steps_code: int  #: ``RechargeEnd.MAX_STEPS``
    full_code: int  #: ``RechargeEnd.FULL``


class DockingTables(NamedTuple):
    """Which geoms are teeth and electrodes, and whose; which packs take a docking now."""

    dock_code: npt.NDArray[np.int8]  #: (ngeom,) 1 teeth, 2 electrode, 0 other
    teeth_owner: Ints  #: (ngeom,) robot of a teeth geom, else -1
    electrode_owner: Ints  #: (ngeom,) pack of an electrode geom, else -1
    pack_active: Flags  #: (n_packs,) the pack takes new dockings (``World.pack_active``)


class PackAvailability(NamedTuple):
    """The packs' reactivation countdowns and what shows an inactive pack (the world's arrays).

    A docking onto pack j during control step t sets ``countdown[j]`` to N + 1 (N:
    ``WorldConfig.pack_reactivation_steps``) and darkens the pack; the end of every step,
    after its dockings, subtracts 1; at 0 the pack is active again, so it is inactive during
    the rest of step t and steps t+1 .. t+N.
    """

    countdown: Ints  #: (n_packs,) steps the pack stays inactive, this one included (0: active)
    active: Flags  #: (n_packs,) the pack is shown and takes dockings (``World.pack_active``)
    geom_rgba: npt.NDArray[np.float32]  #: (ngeom, 4) the model's geom colours
    pack_geom: Ints  #: (n_packs,) each pack's coloured body geom
    pack_rgba: Floats  #: (n_packs, 4) each pack's own colour (``World.pack_rgba``)


class ContactScan(NamedTuple):
    """The step's contact pairs (copied from MjData) and the scan's output."""

    geom: npt.NDArray[np.int32]  #: (capacity, 2) geom pairs; the first ``ncon[0]`` are valid
    ncon: Ints  #: (1,) number of contacts
    pairs: Ints  #: (capacity, 2) output: (robot, pack) of each eligible teeth/electrode contact


# --- begin: commands, LEDs, mating signals -------------------------------------------------


@jit
def begin(
    commands: StepCommands,
    state: SurvivalState,
    actuation: Actuation,
    rules: SurvivalRules,
    flags: StepFlags,
) -> int:
    """First half of a control step (``SurvivalWorld.begin_step``).

    Writes the motor commands ``actuation.ctrl`` in rad/s, the LED state ``actuation.led_on``
    and the LED geoms' colours, and the step's ``flags``.

    Returns:
        :data:`BEGIN_OK`; or, with nothing written, :data:`BAD_WHEELS` if a wheel speed is NaN
        or outside ±``top_speed``, else :data:`RELEASE_FIRST` if a docked robot's recharge
        decision is "stop" (its release draws the reflex from the world's generator, in
        Python; then this runs again).
    """
    wheels = commands.wheels
    top_speed = rules.top_speed
    n = wheels.shape[0]
    for i in range(n):
        for k in range(2):
            v = wheels[i, k]
            if not (-top_speed <= v <= top_speed):  # NaN fails too
                return BAD_WHEELS
    for i in range(n):
        if state.docked[i] and not commands.continue_recharge[i]:
            return RELEASE_FIRST
    inv_radius = rules.inv_wheel_radius
    alive = state.alive
    ctrl = actuation.ctrl
    for i in range(n):
        rech = state.docked[i]
        reflex = state.reflex_steps_left[i] > 0
        flags.recharging[i] = rech
        flags.in_reflex[i] = reflex
        left = wheels[i, 0]
        right = wheels[i, 1]
        if rech or not alive[i]:
            left = 0.0
            right = 0.0
        if reflex:
            left = state.reflex_wheels[i, 0]
            right = state.reflex_wheels[i, 1]
        ctrl[i, 0] = left * inv_radius
        ctrl[i, 1] = right * inv_radius
        on = commands.led[i] and alive[i]
        if on != actuation.led_on[i]:
            actuation.led_on[i] = on
            colour = actuation.led_rgba[1 if on else 0]
            for k in range(4):
                actuation.geom_rgba[actuation.led_geom[i], k] = colour[k]
        flags.mate_signal[i] = (
            commands.mate[i]
            and alive[i]
            and not rech
            and not reflex
            and state.energy[i] > rules.mate_min_energy
        )
    return BEGIN_OK


def begin_reference(
    commands: StepCommands,
    state: SurvivalState,
    actuation: Actuation,
    rules: SurvivalRules,
    flags: StepFlags,
) -> int:
    """:func:`begin` in numpy: a handful of calls on (n,) arrays.

    Rare states (docked, reflex, dead) are counted with ``count_nonzero`` (cheap) and handled
    only when present.
    """
    wheels = commands.wheels
    top = rules.top_speed
    if not (-top <= wheels.min() and wheels.max() <= top):  # NaN fails too
        return BAD_WHEELS
    if (state.docked & ~commands.continue_recharge).any():
        return RELEASE_FIRST
    count = np.count_nonzero
    alive = state.alive
    np.copyto(flags.recharging, state.docked)
    np.greater(state.reflex_steps_left, 0, out=flags.in_reflex)
    n_recharging = count(flags.recharging)
    n_reflex = count(flags.in_reflex)
    n_dead = len(alive) - count(alive)

    # Motor commands: docked and dead robots stand still, reflexes override the caller.
    if n_recharging or n_reflex or n_dead:
        wheels = wheels.copy()
        wheels[flags.recharging] = 0.0
        wheels[~alive] = 0.0
        wheels[flags.in_reflex] = state.reflex_wheels[flags.in_reflex]
    np.multiply(wheels, rules.inv_wheel_radius, out=actuation.ctrl)

    # LEDs: a dead robot's is dark; only the LEDs that switch change colour.
    led = commands.led & alive if n_dead else commands.led
    changed = np.not_equal(led, actuation.led_on)
    if count(changed):
        for i in np.flatnonzero(changed).tolist():
            on = bool(led[i])
            actuation.led_on[i] = on
            actuation.geom_rgba[actuation.led_geom[i]] = actuation.led_rgba[int(on)]
    # Only free, living robots with energy above the threshold take part in a handshake
    # (a living robot's energy is above 0, so the default threshold 0 adds no condition).
    signal = flags.mate_signal
    np.logical_and(commands.mate, alive, out=signal)
    if n_recharging or n_reflex:
        np.logical_and(signal, ~flags.recharging, out=signal)
        np.logical_and(signal, ~flags.in_reflex, out=signal)
    if rules.mate_min_energy > 0.0:
        np.logical_and(signal, state.energy > rules.mate_min_energy, out=signal)
    return BEGIN_OK


# --- end: energy, recharge stopping rules, deaths ------------------------------------------


@jit
def end(
    state: SurvivalState, rules: SurvivalRules, flags: StepFlags, outcome: EnergyOutcome
) -> tuple[int, int]:
    """Second half's energy rules (``SurvivalWorld.end_step`` before captures and mating).

    Counts down reflexes; recharging robots gain ``recharge_gain`` (capped at ``max_energy``)
    and a recharge step, and ``stop_reason[i]`` is set to ``max_steps_code`` or ``full_code``
    when a stopping rule ends robot i's recharge (0 otherwise); every other living robot pays
    ``energy_decay``, and ``died[i]`` marks those whose energy reached 0 (set to 0, no longer
    alive).

    Returns:
        (number of recharges to end, number of deaths).
    """
    energy = state.energy
    recharge_steps = state.recharge_steps
    alive = state.alive
    stop_reason = outcome.stop_reason
    died = outcome.died
    gain = rules.recharge_gain
    max_energy = rules.max_energy
    decay = rules.energy_decay
    n = energy.shape[0]
    n_stops = 0
    n_died = 0
    for i in range(n):
        if flags.in_reflex[i]:
            state.reflex_steps_left[i] -= 1
        stop_reason[i] = 0
        died[i] = False
        if flags.recharging[i]:
            energy[i] = min(energy[i] + gain, max_energy)
            recharge_steps[i] += 1
            if recharge_steps[i] >= rules.max_recharge_steps:
                stop_reason[i] = rules.max_steps_code
                n_stops += 1
            elif energy[i] >= max_energy:
                stop_reason[i] = rules.full_code
                n_stops += 1
        elif alive[i]:
            energy[i] -= decay
            if energy[i] <= 0.0:
                energy[i] = 0.0
                alive[i] = False
                died[i] = True
                n_died += 1
    return n_stops, n_died


def end_reference(
    state: SurvivalState, rules: SurvivalRules, flags: StepFlags, outcome: EnergyOutcome
) -> tuple[int, int]:
    """:func:`end` in numpy."""
    count = np.count_nonzero
    energy = state.energy
    rech = flags.recharging
    n_recharging = count(rech)
    if count(flags.in_reflex):
        np.subtract(state.reflex_steps_left, flags.in_reflex, out=state.reflex_steps_left)

    # Energy of recharging robots, then the recharge stopping rules.
    stop_reason = outcome.stop_reason
    stop_reason[:] = 0
    if n_recharging:
        energy[rech] = np.minimum(energy[rech] + rules.recharge_gain, rules.max_energy)
        state.recharge_steps[rech] += 1
        full = rech & (energy >= rules.max_energy)
        stop_reason[full] = rules.full_code
        stop_reason[rech & (state.recharge_steps >= rules.max_recharge_steps)] = (
            rules.max_steps_code
        )

    # Everyone else pays the step; energy 0 is death.
    died = outcome.died
    if n_recharging or count(state.alive) < len(energy):
        free = state.alive & ~rech
        energy[free] -= rules.energy_decay
        np.logical_and(free, energy <= 0.0, out=died)
    else:
        energy -= rules.energy_decay
        np.less_equal(energy, 0.0, out=died)
    n_died = count(died)
    if n_died:
        energy[died] = 0.0
        state.alive[died] = False
    return int(count(stop_reason)), int(n_died)


# --- teeth_on_electrodes: the contact scan for captures ------------------------------------


@jit
def teeth_on_electrodes(
    contacts: ContactScan, tables: DockingTables, state: SurvivalState, flags: StepFlags
) -> int:
    """Fill ``contacts.pairs[:k]`` with (robot, pack) of each eligible teeth-electrode contact.

    Teeth geoms have code 1 and electrodes code 2, so a contact pair ORs to 3 exactly when it
    is teeth on electrode. Eligible: the robot is alive, not docked, and neither started the
    step in its reflex nor has reflex steps left, and the pack is active.

    Returns:
        k, the number of pairs written.
    """
    geom = contacts.geom
    pairs = contacts.pairs
    dock_code = tables.dock_code
    k = 0
    for c in range(contacts.ncon[0]):
        g1 = geom[c, 0]
        g2 = geom[c, 1]
        if (dock_code[g1] | dock_code[g2]) != 3:
            continue
        i = tables.teeth_owner[g1]
        if i >= 0:
            j = tables.electrode_owner[g2]
        else:
            i = tables.teeth_owner[g2]
            j = tables.electrode_owner[g1]
        free = state.alive[i] and not state.docked[i] and not flags.in_reflex[i]
        if free and state.reflex_steps_left[i] == 0 and tables.pack_active[j]:
            pairs[k, 0] = i
            pairs[k, 1] = j
            k += 1
    return k


def teeth_on_electrodes_reference(
    contacts: ContactScan, tables: DockingTables, state: SurvivalState, flags: StepFlags
) -> int:
    """:func:`teeth_on_electrodes` in numpy."""
    geom = contacts.geom[: contacts.ncon[0]]
    code = tables.dock_code[geom]
    hits = np.flatnonzero(np.bitwise_or(code[:, 0], code[:, 1]) == 3)
    if not len(hits):
        return 0
    g1, g2 = geom[hits, 0], geom[hits, 1]
    robot = tables.teeth_owner[g1]
    electrode_second = robot >= 0
    robot = np.where(electrode_second, robot, tables.teeth_owner[g2])
    pack = np.where(electrode_second, tables.electrode_owner[g2], tables.electrode_owner[g1])
    free = state.alive[robot] & ~state.docked[robot] & ~flags.in_reflex[robot]
    free &= state.reflex_steps_left[robot] == 0
    free &= tables.pack_active[pack]
    k = int(np.count_nonzero(free))
    contacts.pairs[:k, 0] = robot[free]
    contacts.pairs[:k, 1] = pack[free]
    return k


# --- count_down_packs: inactive packs come back ---------------------------------------------


@jit
def count_down_packs(packs: PackAvailability) -> int:
    """End of a control step, after its dockings: every inactive pack's countdown minus 1; a
    pack whose countdown reaches 0 is active again, in its own colour.

    Returns:
        The number of packs still inactive.
    """
    inactive = 0
    for j in range(packs.countdown.shape[0]):
        if packs.countdown[j] <= 0:
            continue
        packs.countdown[j] -= 1
        if packs.countdown[j] > 0:
            inactive += 1
            continue
        packs.active[j] = True
        g = packs.pack_geom[j]
        for c in range(4):
            packs.geom_rgba[g, c] = packs.pack_rgba[j, c]
    return inactive


def count_down_packs_reference(packs: PackAvailability) -> int:
    """:func:`count_down_packs` in numpy."""
    counting = packs.countdown > 0
    np.subtract(packs.countdown, counting, out=packs.countdown)
    back = counting & (packs.countdown == 0)
    if back.any():
        packs.active[back] = True
        packs.geom_rgba[packs.pack_geom[back]] = packs.pack_rgba[back]
    return int(np.count_nonzero(packs.countdown))


# --- IR mating ---------------------------------------------------------------------------------
#: ``IrPorts.arena`` of a world whose robots are all in one arena (no arena test).
ONE_ARENA = np.zeros(0, dtype=np.int64)


class IrPorts(NamedTuple):
    """The robots' IR ports (views of MuJoCo's data) and the mating streaks."""

    site: Ints  #: (n,) each robot's IR port site
    site_xpos: Floats  #: (nsite, 3) site positions
    site_xmat: Floats  #: (nsite, 9) site frames, row-major; the port points along z
    streak: Ints  #: (n, n) consecutive steps each pair has held the condition (symmetric)
    streak_active: Flags  #: (1,) some pair has a streak
    pairs: Floats  #: (n * n, 3) scratch: distance², robot a, robot b of the facing pairs
    #: (n,) each robot's arena (``World.robot_arena``): only robots of one arena pair, as no
    #: IR link crosses a wall; empty (:data:`ONE_ARENA`): every robot is in one arena
    arena: Ints = ONE_ARENA


class MatingRules(NamedTuple):
    """The IR exchange's geometry (``SurvivalConfig``)."""

    reach2: float  #: mate_distance², m²
    cos_angle: float  #: cos(mate_angle_deg)
    consecutive_steps: int  #: mate_consecutive_steps


@jit
def mate(
    signal: Flags, alive: Flags, docked: Flags, ports: IrPorts, rules: MatingRules, partner: Ints
) -> bool:
    """Advance the streaks of the pairs that hold the mating condition; record exchanges.

    A pair holds the condition when both robots signal, are alive and free, are in the same
    arena (``ports.arena``), their ports are within ``rules.reach2`` of each other and each
    port faces the other within the angle.

    Args:
        signal: (n,) the robots that signal Mate this step (free and living ones only).
        alive, docked: (n,) the robots' state after the step's mechanics.
        ports: the IR ports and streaks (updated in place).
        rules: the geometry.
        partner: (n,) the step's mate partners (-1: none), written for new exchanges.

    Returns:
        True if an exchange happened.
    """
    n = signal.shape[0]
    signalling = 0
    for a in range(n):
        signalling += signal[a]
    if signalling < 2:
        if ports.streak_active[0]:
            ports.streak[:, :] = 0
            ports.streak_active[0] = False
        return False
    pos, axes, site = ports.site_xpos, ports.site_xmat, ports.site
    arena = ports.arena
    split = arena.shape[0] > 0
    pairs = ports.pairs
    k = 0
    for a in range(n):
        if not (signal[a] and alive[a] and not docked[a]):
            continue
        pa = pos[site[a]]
        for b in range(a + 1, n):
            if not (signal[b] and alive[b] and not docked[b]):
                continue
            if split and arena[a] != arena[b]:  # a wall between them: no IR link
                continue
            pb = pos[site[b]]
            dx, dy, dz = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
            d2 = dx * dx + dy * dy + dz * dz
            if not (0.0 < d2 <= rules.reach2):
                continue
            za, zb = axes[site[a]], axes[site[b]]  # each port's z axis: (m[2], m[5], m[8])
            dist = math.sqrt(d2)
            limit = rules.cos_angle * dist
            if (za[2] * dx + za[5] * dy + za[8] * dz) >= limit and (
                -(zb[2] * dx + zb[5] * dy + zb[8] * dz) >= limit
            ):
                # Facing pairs in order of (distance², a, b): nearest pairs exchange first.
                p = k
                while p > 0 and (
                    pairs[p - 1, 0] > d2
                    or (pairs[p - 1, 0] == d2 and (pairs[p - 1, 1], pairs[p - 1, 2]) > (a, b))
                ):
                    pairs[p] = pairs[p - 1]
                    p -= 1
                pairs[p, 0] = d2
                pairs[p, 1] = a
                pairs[p, 2] = b
                k += 1
    # Consecutive-step streaks: pairs that hold the condition count up, all others reset.
    for j in range(k):
        a, b = int(pairs[j, 1]), int(pairs[j, 2])
        pairs[j, 0] = ports.streak[a, b] + 1  # the new streak (the order is already fixed)
    if ports.streak_active[0]:
        ports.streak[:, :] = 0
    for j in range(k):
        a, b = int(pairs[j, 1]), int(pairs[j, 2])
        ports.streak[a, b] = ports.streak[b, a] = int(pairs[j, 0])
    ports.streak_active[0] = k > 0
    exchanged = False
    for j in range(k):  # one partner per robot per step, nearest pairs first
        a, b = int(pairs[j, 1]), int(pairs[j, 2])
        if ports.streak[a, b] >= rules.consecutive_steps and partner[a] < 0 and partner[b] < 0:
            partner[a] = b
            partner[b] = a
            ports.streak[a, b] = ports.streak[b, a] = 0
            exchanged = True
    return exchanged


def mate_reference(
    signal: Flags, alive: Flags, docked: Flags, ports: IrPorts, rules: MatingRules, partner: Ints
) -> bool:
    """:func:`mate` in Python and numpy (lists of the few signalling robots)."""
    if np.count_nonzero(signal) < 2:
        if ports.streak_active[0]:
            ports.streak[:] = 0
            ports.streak_active[0] = False
        return False
    who = np.flatnonzero(signal & alive & ~docked).tolist()
    pos = ports.site_xpos[ports.site].tolist()
    # Robots of one arena only (a wall between two arenas blocks the IR link).
    arena = ports.arena.tolist() if len(ports.arena) else [0] * len(signal)
    close = []
    for a_k, a in enumerate(who):
        pa = pos[a]
        for b in who[a_k + 1 :]:
            if arena[a] != arena[b]:
                continue
            pb = pos[b]
            dx, dy, dz = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
            d2 = dx * dx + dy * dy + dz * dz
            if 0.0 < d2 <= rules.reach2:
                close.append((a, b, d2, dx, dy, dz))
    facing = []
    if close:
        axes = ports.site_xmat[ports.site].tolist()  # row-major 3x3
        for a, b, d2, dx, dy, dz in close:
            za, zb = axes[a], axes[b]  # each port's z axis: (m[2], m[5], m[8])
            limit = rules.cos_angle * math.sqrt(d2)
            if (za[2] * dx + za[5] * dy + za[8] * dz) >= limit and (
                -(zb[2] * dx + zb[5] * dy + zb[8] * dz) >= limit
            ):
                facing.append((d2, a, b))
    streak = ports.streak
    previous = {(a, b): int(streak[a, b]) for _, a, b in facing}
    if ports.streak_active[0]:
        streak[:] = 0
    for (a, b), count in previous.items():
        streak[a, b] = streak[b, a] = count + 1
    ports.streak_active[0] = bool(facing)
    ready = sorted(p for p in facing if streak[p[1], p[2]] >= rules.consecutive_steps)
    exchanged = False
    for _, a, b in ready:  # one partner per robot per step, nearest pairs first
        if partner[a] < 0 and partner[b] < 0:
            partner[a] = b
            partner[b] = a
            streak[a, b] = streak[b, a] = 0
            exchanged = True
    return exchanged


__all__ = [
    "BAD_WHEELS",
    "BEGIN_OK",
    "RELEASE_FIRST",
    "IrPorts",
    "MatingRules",
    "ONE_ARENA",
    "mate",
    "mate_reference",
    "Actuation",
    "ContactScan",
    "DockingTables",
    "EnergyOutcome",
    "PackAvailability",
    "StepCommands",
    "StepFlags",
    "SurvivalRules",
    "SurvivalState",
    "begin",
    "begin_reference",
    "count_down_packs",
    "count_down_packs_reference",
    "end",
    "end_reference",
    "teeth_on_electrodes",
    "teeth_on_electrodes_reference",
]
