"""Compiled (numba) per-step mechanics of the survival world: commands, energy, captures.

:class:`cyber_rodent.survival.SurvivalWorld` runs its rules around every control step's
physics. With numpy that is some thirty calls on (n,)-arrays, ~50 µs per step, a tenth of the
physics itself; here each half is one compiled loop over the robots:

* :func:`begin`: validate the wheel commands, then the motor commands (docked and dead robots
  stand still, a rotation reflex overrides the caller), the LEDs (the model's LED colours
  change only for robots whose LED switched) and who signals for mating;
* :func:`end`: reflex countdown, recharge energy, the stopping rules (reported, not applied:
  undocking draws the reflex from the world's generator, which stays in Python), the energy
  decay of everyone else and deaths;
* :func:`teeth_on_electrodes`: the contact scan for captures; it returns only the (robot,
  pack) pairs of robots that may dock (alive, not docked, not in their rotation reflex); the
  alignment test and the docking itself stay in Python (rare).

The numpy implementation in ``survival.py`` is the reference (used without numba);
``tests/test_survival_kernel.py`` checks that both give bit-identical runs.
"""

from __future__ import annotations

from cyber_rodent.compiled import AVAILABLE
from cyber_rodent.compiled import jit as _jit

__all__ = ["AVAILABLE", "begin", "end", "teeth_on_electrodes"]


@_jit
def teeth_on_electrodes(
    geom, dock_code, teeth_owner, electrode_owner, alive, docked, in_reflex, reflex_steps_left, out
):
    """Fill ``out[:k]`` with (robot, pack) of each eligible teeth-electrode contact; return k.

    Args:
        geom: (ncon, 2) the contacts' geom pairs.
        dock_code: (ngeom,) 1 for teeth geoms, 2 for electrode geoms, 0 otherwise.
        teeth_owner, electrode_owner: (ngeom,) robot / pack of a teeth / electrode geom, -1.
        alive, docked: (n,) bool; in_reflex: (n,) bool, the robot started the step in its
            reflex; reflex_steps_left: (n,) int.
        out: (ncon, 2) int64 output.
    """
    k = 0
    for c in range(geom.shape[0]):
        g1 = geom[c, 0]
        g2 = geom[c, 1]
        if (dock_code[g1] | dock_code[g2]) != 3:
            continue
        i = teeth_owner[g1]
        if i >= 0:
            j = electrode_owner[g2]
        else:
            i = teeth_owner[g2]
            j = electrode_owner[g1]
        if alive[i] and not docked[i] and not in_reflex[i] and reflex_steps_left[i] == 0:
            out[k, 0] = i
            out[k, 1] = j
            k += 1
    return k


@_jit
def begin(
    wheels, led, mate, docked, alive, reflex_steps_left, reflex_wheels, inv_radius, top_speed,
    led_on, geom_rgba, led_geom, on_rgba, off_rgba, ctrl, recharging, in_reflex, mate_signal,
):  # fmt: skip
    """First half of a control step (``SurvivalWorld.begin_step`` after the recharge decisions).

    Writes the motor commands ``ctrl`` (n, 2) in rad/s, the LED state ``led_on`` and the LED
    geoms' colours in ``geom_rgba``, and the step's ``recharging``, ``in_reflex`` and
    ``mate_signal`` flags.

    Returns:
        (valid, n_recharging, n_reflex); valid is False, and nothing is written, if a wheel
        speed is NaN or outside ±``top_speed``.
    """
    n = wheels.shape[0]
    for i in range(n):
        for k in range(2):
            v = wheels[i, k]
            if not (-top_speed <= v <= top_speed):  # NaN fails too
                return False, 0, 0
    n_recharging = 0
    n_reflex = 0
    for i in range(n):
        rech = docked[i]
        reflex = reflex_steps_left[i] > 0
        recharging[i] = rech
        in_reflex[i] = reflex
        n_recharging += rech
        n_reflex += reflex
        left = wheels[i, 0]
        right = wheels[i, 1]
        if rech or not alive[i]:
            left = 0.0
            right = 0.0
        if reflex:
            left = reflex_wheels[i, 0]
            right = reflex_wheels[i, 1]
        ctrl[i, 0] = left * inv_radius
        ctrl[i, 1] = right * inv_radius
        on = led[i] and alive[i]
        if on != led_on[i]:
            led_on[i] = on
            colour = on_rgba if on else off_rgba
            for k in range(4):
                geom_rgba[led_geom[i], k] = colour[k]
        mate_signal[i] = mate[i] and alive[i] and not rech and not reflex
    return True, n_recharging, n_reflex


@_jit
def end(
    in_reflex, reflex_steps_left, recharging, energy, recharge_steps, alive, gain, max_energy,
    max_recharge_steps, decay, max_steps_code, full_code, stop_reason, died,
):  # fmt: skip
    """Second half's energy rules (``SurvivalWorld.end_step`` before captures and mating).

    Counts down reflexes; recharging robots gain ``gain`` (capped at ``max_energy``) and a
    recharge step, and ``stop_reason[i]`` is set to ``max_steps_code`` or ``full_code`` when a
    stopping rule ends robot i's recharge (0 otherwise); every other living robot pays
    ``decay``, and ``died[i]`` marks those whose energy reached 0 (set to 0, no longer alive).

    Returns:
        (number of recharges to end, number of deaths).
    """
    n = energy.shape[0]
    n_stops = 0
    n_died = 0
    for i in range(n):
        if in_reflex[i]:
            reflex_steps_left[i] -= 1
        stop_reason[i] = 0
        died[i] = False
        if recharging[i]:
            energy[i] = min(energy[i] + gain, max_energy)
            recharge_steps[i] += 1
            if recharge_steps[i] >= max_recharge_steps:
                stop_reason[i] = max_steps_code
                n_stops += 1
            elif energy[i] >= max_energy:
                stop_reason[i] = full_code
                n_stops += 1
        elif alive[i]:
            energy[i] -= decay
            if energy[i] <= 0.0:
                energy[i] = 0.0
                alive[i] = False
                died[i] = True
                n_died += 1
    return n_stops, n_died
