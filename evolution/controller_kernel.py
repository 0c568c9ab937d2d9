"""Compiled (numba) evaluation of every robot's controller in one call.

:meth:`evolution.controller.NeuralController.decide` runs, once per control step, the input
assembly, the selection part (12 inputs × 3 outputs), the availability mask, the LED rule and
the recharge part for all robots. In numpy those are some twenty calls on (robots × 12) arrays,
whose cost is call overhead. :func:`decide` does the same arithmetic in one compiled loop. The
weighted sums add their terms in input order; numpy's ``matmul`` may round the last bit
differently, so the activations agree to rounding and the decisions agree except on exact
near-ties (``tests/test_evolution_controller.py`` compares both on random agents).
"""

from __future__ import annotations

from cyber_rodent.compiled import AVAILABLE
from cyber_rodent.compiled import jit as _jit

__all__ = ["AVAILABLE"]


@_jit
def decide(
    weights,
    recharge_start,
    selection_start,
    energy,
    proximity,
    face_distance,
    led_distance,
    battery_distance,
    led_previous,
    mate_available,
    forage_available,
    steps_recharged,
    max_energy,
    max_recharge_steps,
    inputs,
    activations,
    behaviour,
    led,
    proceed,
):
    """Fill the controller's buffers for every robot (see ``NeuralController.decide``).

    Args:
        weights: (n, 39) genomes; recharge_start, selection_start: where the recharge part
            (3 weights) and the selection part (36, output-major) start in a genome.
        energy: (n,) raw energy; proximity: (n, 6) in [0, 1]; face_distance, led_distance,
            battery_distance: (n,) normalised; led_previous: (n,) bool.
        mate_available, forage_available: (n,) bool; steps_recharged: (n,) int.
        max_energy, max_recharge_steps: the normalisations.
        inputs: (n, 12) output (bias column 1); activations: (n, 3) output.
        behaviour: (n,) output; led, proceed: (n,) bool outputs (LED on; keep recharging).
    """
    n = weights.shape[0]
    n_in = inputs.shape[1]
    n_prox = proximity.shape[1]
    for i in range(n):
        x = inputs[i]
        x[0] = energy[i] / max_energy
        for k in range(n_prox):
            x[1 + k] = proximity[i, k]
        x[7] = face_distance[i]
        x[8] = led_distance[i]
        x[9] = battery_distance[i]
        x[10] = 1.0
        x[11] = 1.0 if led_previous[i] else 0.0
        w = weights[i]
        for o in range(3):
            base = selection_start + o * n_in
            total = w[base] * x[0]
            for k in range(1, n_in):
                total += w[base + k] * x[k]
            activations[i, o] = total
        a_mate, a_forage, a_search = activations[i, 0], activations[i, 1], activations[i, 2]
        # The available behaviour with the largest activation; ties to the lower index.
        best, best_value = 2, a_search
        if forage_available[i] and a_forage >= best_value:
            best, best_value = 1, a_forage
        if mate_available[i] and a_mate >= best_value:
            best = 0
        behaviour[i] = best
        led[i] = a_mate > a_forage
        r = recharge_start
        out = energy[i] / max_energy
        out *= w[r]
        out += w[r + 1] * (steps_recharged[i] / max_recharge_steps)
        out += w[r + 2]
        proceed[i] = out <= 0.0
