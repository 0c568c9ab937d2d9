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

**ctrnn**: a continuous-time recurrent neural network (Beer 1995) of H units between the
inputs and the three outputs, with memory: each agent's unit states ``y`` are its own state
(``out.state[i, :H]``, zero at birth, kept by the scheduler across the agent's time-sharing
slots; ``out.state[i, H:2H]`` is scratch for the units' firing rates, recomputed every step).
Genome blocks (:data:`evolution.controllers.CTRNN`, in this order):

- ``recharge`` (3): the paper's recharge part, as for ``mlp``;
- ``input`` (H x inputs, unit-major): ``W[j, k]``, input ``k`` into unit ``j``;
- ``recurrent`` (H x H, unit-major): ``R[j, m]``, unit ``m``'s firing rate into unit ``j``;
- ``bias`` (H): ``θ_j``;
- ``tau`` (H): a gene ``t`` gives the time constant ``τ_j = τ_low (τ_high / τ_low) ** u``,
  ``u = (clip(t, -1, 1) + 1) / 2``, in control steps (log-uniform over the range, so an initial
  gene U[-1, 1] draws τ log-uniformly);
- ``gain`` (H): likewise ``g_j = g_low (g_high / g_low) ** u``;
- ``output`` (3 x (H + 1), output-major): activation ``a_o = sum_j V[o, j] r_j + V[o, H]``.

One control step is one forward-Euler step of ``τ_j dy_j/dt = -y_j + sum_m R[j, m] r_m +
sum_k W[j, k] x_k`` with ``r_m = σ(g_m (y_m + θ_m))`` and ``σ(z) = 1 / (1 + e^-z)``, dt = 1
control step: ``y_j += (-y_j + drive_j) / τ_j`` with the firing rates of the state before the
step; the outputs read the firing rates of the state after it. ``τ ≥ 1`` step keeps the Euler
step stable (it never overshoots the fixed point of a unit). The ranges are
``rules.constants = (τ_low, τ_high, g_low, g_high)`` (``evolution.ctrnn``).

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
#: Rows of ``rules.layout`` of the CTRNN's blocks.
(
    CTRNN_RECHARGE, CTRNN_INPUT, CTRNN_RECURRENT, CTRNN_BIAS, CTRNN_TAU, CTRNN_GAIN, CTRNN_OUTPUT
) = range(7)  # fmt: skip


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


# --- ctrnn ----------------------------------------------------------------------------------
@jit_inline
def _log_range(gene: float, low: float, high: float) -> float:
    """``low (high / low) ** u``, ``u = (clip(gene, -1, 1) + 1) / 2``."""
    u = (min(1.0, max(-1.0, gene)) + 1.0) * 0.5
    return float(low * (high / low) ** u)


@jit_inline
def _sigmoid(z: float) -> float:
    return 1.0 / (1.0 + math.exp(-z))


@jit_inline
def decide_ctrnn(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, out: ControllerBuffers
) -> None:
    """The CTRNN controller: one Euler step of every robot's network, then its outputs (see the
    module docstring)."""
    n, n_inputs = out.inputs.shape
    layout = rules.layout
    units = layout[CTRNN_BIAS, 2]
    recharge, inputs, recurrent = layout[CTRNN_RECHARGE, 0], layout[CTRNN_INPUT, 0], layout[
        CTRNN_RECURRENT, 0]  # fmt: skip
    bias, tau, gain = layout[CTRNN_BIAS, 0], layout[CTRNN_TAU, 0], layout[CTRNN_GAIN, 0]
    output, width = layout[CTRNN_OUTPUT, 0], layout[CTRNN_OUTPUT, 2]
    tau_low, tau_high = rules.constants[0], rules.constants[1]
    gain_low, gain_high = rules.constants[2], rules.constants[3]
    availability = perceived.behaviour
    for i in range(n):
        x = out.inputs[i]
        w = out.weights[i]
        y = out.state[i]
        for m in range(units):  # firing rates of the state before the step
            g = _log_range(w[gain + m], gain_low, gain_high)
            y[units + m] = _sigmoid(g * (y[m] + w[bias + m]))
        for j in range(units):
            base = inputs + j * n_inputs
            drive = w[base] * x[0]
            for k in range(1, n_inputs):
                drive += w[base + k] * x[k]
            base = recurrent + j * units
            for m in range(units):
                drive += w[base + m] * y[units + m]
            y[j] += (drive - y[j]) / _log_range(w[tau + j], tau_low, tau_high)
        for o in range(N_OUTPUTS):
            out.activations[i, o] = w[output + o * width + units]
        for m in range(units):  # firing rates of the state after it
            g = _log_range(w[gain + m], gain_low, gain_high)
            r = _sigmoid(g * (y[m] + w[bias + m]))
            y[units + m] = r
            for o in range(N_OUTPUTS):
                out.activations[i, o] += w[output + o * width + m] * r
        choose(i, availability, out)
        out.continue_recharge[i] = recharge_decision(i, rules, robots, w, recharge)


def _log_range_reference(genes: np.ndarray, low: float, high: float) -> np.ndarray:
    u = (np.clip(genes, -1.0, 1.0) + 1.0) * 0.5
    result: np.ndarray = low * (high / low) ** u
    return result


def _sigmoid_reference(z: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        result: np.ndarray = 1.0 / (1.0 + np.exp(-z))
    return result


def decide_ctrnn_reference(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, out: ControllerBuffers
) -> None:
    """:func:`decide_ctrnn` in numpy, over all robots at once; each sum adds its terms in the
    compiled kernel's order."""
    n, n_inputs = out.inputs.shape
    layout = rules.layout
    units = int(layout[CTRNN_BIAS, 2])
    w = out.weights

    def block(row: int, size: int) -> np.ndarray:
        start = int(layout[row, 0])
        return w[:, start : start + size]

    weights_in = block(CTRNN_INPUT, units * n_inputs).reshape(n, units, n_inputs)
    weights_rec = block(CTRNN_RECURRENT, units * units).reshape(n, units, units)
    bias = block(CTRNN_BIAS, units)
    c = rules.constants
    tau = _log_range_reference(block(CTRNN_TAU, units), float(c[0]), float(c[1]))
    gain = _log_range_reference(block(CTRNN_GAIN, units), float(c[2]), float(c[3]))
    width = int(layout[CTRNN_OUTPUT, 2])
    weights_out = block(CTRNN_OUTPUT, N_OUTPUTS * width).reshape(n, N_OUTPUTS, width)
    y, rates = out.state[:, :units], out.state[:, units : 2 * units]
    rates[...] = _sigmoid_reference(gain * (y + bias))
    drive = weights_in[:, :, 0] * out.inputs[:, None, 0]
    for k in range(1, n_inputs):
        drive += weights_in[:, :, k] * out.inputs[:, None, k]
    for m in range(units):
        drive += weights_rec[:, :, m] * rates[:, None, m]
    y += (drive - y) / tau
    out.activations[...] = weights_out[:, :, units]
    rates[...] = _sigmoid_reference(gain * (y + bias))
    for m in range(units):
        out.activations[...] += weights_out[:, :, m] * rates[:, None, m]
    choose_reference(perceived.behaviour, out)
    recharge = int(layout[CTRNN_RECHARGE, 0])
    recharge_decision_reference(rules, robots, out.weights, recharge, out.continue_recharge)


__all__ = [
    "CTRNN_BIAS",
    "CTRNN_GAIN",
    "CTRNN_INPUT",
    "CTRNN_OUTPUT",
    "CTRNN_RECHARGE",
    "CTRNN_RECURRENT",
    "CTRNN_TAU",
    "HIDDEN_BLOCK",
    "OUTPUT_BLOCK",
    "RECHARGE_BLOCK",
    "decide_ctrnn",
    "decide_ctrnn_reference",
    "decide_mlp",
    "decide_mlp_reference",
]
