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
  pack) pairs of robots that may dock (alive, not docked, not in their rotation reflex); the
  alignment test and the docking itself stay in Python (rare).

``tests/test_survival_kernel.py`` checks that both backends give bit-identical runs.
"""

from __future__ import annotations

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
    max_steps_code: int  #: ``RechargeEnd.MAX_STEPS``
    full_code: int  #: ``RechargeEnd.FULL``


class DockingTables(NamedTuple):
    """Which geoms are teeth and electrodes, and whose."""

    dock_code: npt.NDArray[np.int8]  #: (ngeom,) 1 teeth, 2 electrode, 0 other
    teeth_owner: Ints  #: (ngeom,) robot of a teeth geom, else -1
    electrode_owner: Ints  #: (ngeom,) pack of an electrode geom, else -1


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
) -> bool:
    """First half of a control step (``SurvivalWorld.begin_step`` after the recharge decisions).

    Writes the motor commands ``actuation.ctrl`` in rad/s, the LED state ``actuation.led_on``
    and the LED geoms' colours, and the step's ``flags``.

    Returns:
        False, with nothing written, if a wheel speed is NaN or outside ±``top_speed``.
    """
    wheels = commands.wheels
    top_speed = rules.top_speed
    n = wheels.shape[0]
    for i in range(n):
        for k in range(2):
            v = wheels[i, k]
            if not (-top_speed <= v <= top_speed):  # NaN fails too
                return False
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
        flags.mate_signal[i] = commands.mate[i] and alive[i] and not rech and not reflex
    return True


def begin_reference(
    commands: StepCommands,
    state: SurvivalState,
    actuation: Actuation,
    rules: SurvivalRules,
    flags: StepFlags,
) -> bool:
    """:func:`begin` in numpy: a handful of calls on (n,) arrays.

    Rare states (docked, reflex, dead) are counted with ``count_nonzero`` (cheap) and handled
    only when present.
    """
    wheels = commands.wheels
    top = rules.top_speed
    if not (-top <= wheels.min() and wheels.max() <= top):  # NaN fails too
        return False
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
    # Only free, living robots take part in a mating handshake.
    signal = flags.mate_signal
    np.logical_and(commands.mate, alive, out=signal)
    if n_recharging or n_reflex:
        np.logical_and(signal, ~flags.recharging, out=signal)
        np.logical_and(signal, ~flags.in_reflex, out=signal)
    return True


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
    step in its reflex nor has reflex steps left.

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
        if free and state.reflex_steps_left[i] == 0:
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
    k = int(np.count_nonzero(free))
    contacts.pairs[:k, 0] = robot[free]
    contacts.pairs[:k, 1] = pack[free]
    return k


__all__ = [
    "Actuation",
    "ContactScan",
    "DockingTables",
    "EnergyOutcome",
    "StepCommands",
    "StepFlags",
    "SurvivalRules",
    "SurvivalState",
    "begin",
    "begin_reference",
    "end",
    "end_reference",
    "teeth_on_electrodes",
    "teeth_on_electrodes_reference",
]
