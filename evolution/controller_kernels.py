"""The rules of the controllers beside the paper's (whose rule lives with the fused step in
:mod:`evolution.kernels`): each a compiled kernel and its numpy reference, registered in
:mod:`evolution.controllers`. A new controller's rule goes here.

**mlp**: one tanh hidden layer between the inputs and the three outputs. Genome blocks
(:data:`evolution.controllers.MLP`, in this order, the block starts in ``rules.layout``):

- ``recharge`` (3): the paper's recharge part, unchanged (:func:`evolution.kernels.
  recharge_decision`): ``w0 energy / max_energy + w1 steps / max_recharge_steps + w2 <= 0``
  continues recharging;
- ``hidden`` (H x inputs, unit-major): hidden unit ``j`` is ``h_j = tanh(sum_k W[j, k] x_k)``
  over the controller's inputs (the ``bias`` input is its bias);
- ``output`` (3 x (H + 1), output-major): activation ``a_o = sum_j V[o, j] h_j + V[o, H]`` for
  Mate, Forage and Search.

Selection and the LED are the paper's (:func:`evolution.kernels.choose`): the available
behaviour with the largest activation wins, the LED is on iff activation(Mate) >
activation(Forage).

The compiled kernel adds each sum's terms in index order; the reference uses ``matmul``, which
may round the last bit differently, so the two agree to rounding, like the paper's controller
(``tests/test_evolution_controllers.py``).

Every rule has the signature ``decide(rules, robots, perceived, out)``
(:class:`evolution.controllers.ControllerSpec`) and may use the paper's output rules
(:func:`evolution.kernels.choose`, :func:`evolution.kernels.recharge_decision`).
"""

from __future__ import annotations

import math

import numpy as np

from behaviours.kernels import InputBuffers
from cyber_rodent.backend import jit_inline
from evolution.input_kernels import ControllerRules, RobotState
from evolution.kernels import (
    N_OUTPUTS,
    ControllerBuffers,
    choose,
    choose_reference,
    recharge_decision,
    recharge_decision_reference,
)

#: Rows of ``rules.layout``: the blocks in genome order.
RECHARGE_BLOCK, HIDDEN_BLOCK, OUTPUT_BLOCK = 0, 1, 2


@jit_inline
def decide_mlp(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, out: ControllerBuffers
) -> None:
    """The MLP controller on the filled inputs (see the module docstring)."""
    n, n_inputs = out.inputs.shape
    recharge = rules.layout[RECHARGE_BLOCK, 0]
    hidden, units = rules.layout[HIDDEN_BLOCK, 0], rules.layout[HIDDEN_BLOCK, 1]
    output, width = rules.layout[OUTPUT_BLOCK, 0], rules.layout[OUTPUT_BLOCK, 2]
    availability = perceived.behaviour
    for i in range(n):
        x = out.inputs[i]
        w = out.weights[i]
        for o in range(N_OUTPUTS):
            out.activations[i, o] = 0.0
        for j in range(units):
            base = hidden + j * n_inputs
            total = w[base] * x[0]
            for k in range(1, n_inputs):
                total += w[base + k] * x[k]
            h = math.tanh(total)
            for o in range(N_OUTPUTS):
                out.activations[i, o] += w[output + o * width + j] * h
        for o in range(N_OUTPUTS):
            out.activations[i, o] += w[output + o * width + units]
        choose(i, availability, out)
        out.continue_recharge[i] = recharge_decision(i, rules, robots, w, recharge)


def decide_mlp_reference(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, out: ControllerBuffers
) -> None:
    """:func:`decide_mlp` in numpy."""
    n, n_inputs = out.inputs.shape
    recharge = int(rules.layout[RECHARGE_BLOCK, 0])
    hidden, units = int(rules.layout[HIDDEN_BLOCK, 0]), int(rules.layout[HIDDEN_BLOCK, 1])
    output, width = int(rules.layout[OUTPUT_BLOCK, 0]), int(rules.layout[OUTPUT_BLOCK, 2])
    first = out.weights[:, hidden : hidden + units * n_inputs].reshape(n, units, n_inputs)
    h = np.tanh(np.matmul(first, out.inputs[:, :, None])[:, :, 0])
    second = out.weights[:, output : output + N_OUTPUTS * width].reshape(n, N_OUTPUTS, width)
    out.activations[...] = np.matmul(second[:, :, :units], h[:, :, None])[:, :, 0]
    np.add(out.activations, second[:, :, units], out=out.activations)
    choose_reference(perceived.behaviour, out)
    recharge_decision_reference(rules, robots, out.weights, recharge, out.continue_recharge)


__all__ = ["HIDDEN_BLOCK", "OUTPUT_BLOCK", "RECHARGE_BLOCK", "decide_mlp", "decide_mlp_reference"]
