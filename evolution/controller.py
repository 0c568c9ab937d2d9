"""The evolved one-layer neural controller (paper §3.5, Fig. 5; docs/design.md §5).

It has two parts, both plain weighted sums of inputs in [0, 1]:

**Recharge part** (3 weights, genome ``[0:3]``), used while docked:
``output = w0 * energy / max_energy + w1 * steps_recharged / max_recharge_steps + w2``;
the robot keeps recharging while ``output <= 0`` and stops otherwise.

**Selection part** (12 inputs x 3 outputs = 36 weights, genome ``[3:39]``, output-major: the 12
weights into Mate, then Forage, then Search), used every step the robot is not recharging. The
input order (:data:`INPUT_NAMES`) follows the paper's enumeration:

====  ==============================================================================
 idx  input
====  ==============================================================================
  0   energy / max_energy
 1-6  the six proximity readings, 5 front + 1 back (``cyber_rodent.constants.PROXIMITY_SIX``
      order), normalised to [0, 1] by the world
  7   distance to the nearest red face, normalised; 1 if none is seen
  8   distance to the nearest green LED, normalised; 1 if none is seen
  9   distance to the nearest blue battery pack, normalised; 1 if none is seen
 10   bias, always 1
 11   own LED state at the previous control step, 0 (off) or 1 (on)
====  ==============================================================================

The available behaviour with the largest activation wins: Mate is available only with another CR
in view, Forage only with a pack in view, Search always. Exact ties go to the lower index (Mate,
then Forage, then Search), which only matters for hand-made weights. The LED is on iff
activation(Mate) > activation(Forage), compared on the raw activations whether or not the
behaviours are available: the paper ties the LED to the two output nodes, not to the choice, so a
robot can signal willingness to mate before it sees a partner.

The controller is vectorised over robots: it reads a (n_robots, 39) weight matrix (one row per
robot's active agent), the robots' state and the perceived inputs, and writes into buffers it
owns, so the hot loop allocates nothing. The rule itself is :func:`evolution.kernels.decide`
(compiled) and its numpy reference; ``backend`` picks one.
"""

from __future__ import annotations

import numpy as np

from behaviours.inputs import FORAGE, MATE, SEARCH
from behaviours.kernels import InputBuffers
from cyber_rodent.backend import DEFAULT_BACKEND, Backend, bind, check_backend, pick
from cyber_rodent.validation import check_integer, check_number
from cyber_rodent.vision.types import BATTERY, FACE, LED
from evolution.config import GENOME_LENGTH
from evolution.genome import RECHARGE
from evolution.kernels import (
    IN_BATTERY_DISTANCE,
    IN_BIAS,
    IN_ENERGY,
    IN_FACE_DISTANCE,
    IN_LED_DISTANCE,
    IN_LED_PREVIOUS,
    IN_PROXIMITY_START,
    N_INPUTS,
    N_OUTPUTS,
    N_PROXIMITY,
    ControllerBuffers,
    ControllerRules,
    RobotState,
    decide,
    decide_reference,
)

#: Names of the selection part's outputs, in behaviour-index order.
BEHAVIOUR_NAMES = ("mate", "forage", "search")
#: The six proximity inputs.
IN_PROXIMITY = slice(IN_PROXIMITY_START, IN_PROXIMITY_START + N_PROXIMITY)
INPUT_NAMES = (
    "energy",
    "proximity_front",
    "proximity_front_left30",
    "proximity_front_right30",
    "proximity_front_left60",
    "proximity_front_right60",
    "proximity_back",
    "face_distance",
    "led_distance",
    "battery_distance",
    "bias",
    "led_previous",
)

assert len(INPUT_NAMES) == N_INPUTS
assert RECHARGE.stop - RECHARGE.start + N_INPUTS * N_OUTPUTS == GENOME_LENGTH


class NeuralController:
    """Evaluates every robot's active agent's controller in one call.

    Args:
        weights: (n_robots, 39) the active agents' genomes; read at every :meth:`decide`, so
            pass a live view (the scheduler's ``active_weights``) or write into it in place.
        robots: views of the robots' energy, recharge counters and LEDs.
        perceived: the perceived inputs (proximities, normalised distances, availability).
        max_energy: energy normalisation (paper: 200).
        max_recharge_steps: recharge-step normalisation (paper: 40).
        backend: ``"numba"`` (the compiled kernel) or ``"numpy"`` (its reference).

    Attributes:
        buffers: the :class:`~evolution.kernels.ControllerBuffers`: ``inputs`` (n, 12),
            ``activations`` (n, 3), ``behaviour`` (n,), ``led`` (n,), ``continue_recharge``
            (n,), written by every :meth:`decide`.
        rules: the :class:`~evolution.kernels.ControllerRules`.
    """

    def __init__(
        self,
        weights: np.ndarray,
        robots: RobotState,
        perceived: InputBuffers,
        max_energy: float = 200.0,
        max_recharge_steps: int = 40,
        backend: Backend = DEFAULT_BACKEND,
    ) -> None:
        n = check_integer("n_robots", weights.shape[0], 1)
        if weights.shape != (n, GENOME_LENGTH) or weights.dtype != np.float64:
            raise ValueError(f"weights must be float64 of shape ({n}, {GENOME_LENGTH})")
        self.rules = ControllerRules(
            max_energy=check_number("max_energy", max_energy, 0.0, low_open=True),
            max_recharge_steps=float(
                check_integer("max_recharge_steps", max_recharge_steps, 1)
            ),
            led=LED,
            face=FACE,
            battery=BATTERY,
        )
        inputs = np.zeros((n, N_INPUTS))
        inputs[:, IN_BIAS] = 1.0
        self.buffers = ControllerBuffers(
            weights=weights,
            inputs=inputs,
            activations=np.zeros((n, N_OUTPUTS)),
            behaviour=np.zeros(n, dtype=np.int64),
            led=np.zeros(n, dtype=np.bool_),
            continue_recharge=np.zeros(n, dtype=np.bool_),
        )
        self.n_robots = n
        self.backend = check_backend(backend)
        self.kernel = pick(self.backend, decide, decide_reference)
        self.decide = bind(self.kernel, self.rules, robots, perceived, self.buffers)
        """Evaluate every robot's controller into :attr:`buffers` (no arguments)."""

    @property
    def behaviour(self) -> np.ndarray:
        """(n,) the behaviour each robot chose at the last :meth:`decide`."""
        return self.buffers.behaviour

    @property
    def led(self) -> np.ndarray:
        """(n,) the LED decisions of the last :meth:`decide`."""
        return self.buffers.led

    @property
    def continue_recharge(self) -> np.ndarray:
        """(n,) bool, the recharge decisions of the last :meth:`decide` (True = continue)."""
        return self.buffers.continue_recharge


__all__ = [
    "BEHAVIOUR_NAMES",
    "FORAGE",
    "INPUT_NAMES",
    "IN_BATTERY_DISTANCE",
    "IN_BIAS",
    "IN_ENERGY",
    "IN_FACE_DISTANCE",
    "IN_LED_DISTANCE",
    "IN_LED_PREVIOUS",
    "IN_PROXIMITY",
    "MATE",
    "N_INPUTS",
    "N_OUTPUTS",
    "N_PROXIMITY",
    "SEARCH",
    "NeuralController",
]
