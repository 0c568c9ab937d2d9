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

The controller is vectorised over robots: it takes a (n_robots, 39) weight matrix (one row per
robot's active agent) and (n_robots, 12) inputs, and writes into buffers it owns, so the hot loop
allocates nothing.
"""

from __future__ import annotations

import numpy as np

from evolution import controller_kernel
from evolution.config import GENOME_LENGTH
from evolution.genome import RECHARGE, SELECTION

#: Behaviour indices of the selection part's outputs.
MATE, FORAGE, SEARCH = 0, 1, 2
BEHAVIOUR_NAMES = ("mate", "forage", "search")
N_OUTPUTS = 3

#: Input indices of the selection part.
IN_ENERGY = 0
IN_PROXIMITY = slice(1, 7)
IN_FACE_DISTANCE = 7
IN_LED_DISTANCE = 8
IN_BATTERY_DISTANCE = 9
IN_BIAS = 10
IN_LED_PREVIOUS = 11
N_INPUTS = 12
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
N_PROXIMITY = IN_PROXIMITY.stop - IN_PROXIMITY.start

assert len(INPUT_NAMES) == N_INPUTS
assert RECHARGE.stop - RECHARGE.start + N_INPUTS * N_OUTPUTS == GENOME_LENGTH


class NeuralController:
    """Evaluates every robot's active agent's controller in one vectorised call.

    Args:
        n_robots: rows of the weight matrix and inputs this controller will see.
        max_energy: energy normalisation (paper: 200).
        max_recharge_steps: recharge-step normalisation (paper: 40).

    Attributes:
        inputs: (n_robots, 12) input buffer; :meth:`fill_inputs` writes it, the bias column is 1.
        activations: (n_robots, 3) raw activations of Mate, Forage, Search from the last
            :meth:`select`.
        behaviour: (n_robots,) int, the winning behaviour of the last :meth:`select`.
        led: (n_robots,) bool, the LED decision of the last :meth:`select`.
    """

    def __init__(
        self, n_robots: int, max_energy: float = 200.0, max_recharge_steps: int = 40
    ) -> None:
        if not isinstance(n_robots, int) or n_robots < 1:
            raise ValueError(f"n_robots must be an integer in [1, ∞), got {n_robots!r}")
        if not max_energy > 0:
            raise ValueError(f"max_energy must be in (0, ∞), got {max_energy!r}")
        if not max_recharge_steps > 0:
            raise ValueError(f"max_recharge_steps must be in (0, ∞), got {max_recharge_steps!r}")
        self.n_robots = n_robots
        self.max_energy = float(max_energy)
        self.max_recharge_steps = float(max_recharge_steps)
        self.inputs = np.zeros((n_robots, N_INPUTS))
        self.inputs[:, IN_BIAS] = 1.0
        self._masked = np.zeros((n_robots, N_OUTPUTS))
        self._unavailable = np.zeros(n_robots, dtype=bool)
        self._column = np.zeros((n_robots, N_OUTPUTS, 1))
        self.activations = self._column[:, :, 0]
        self.behaviour = np.zeros(n_robots, dtype=np.intp)
        self.led = np.zeros(n_robots, dtype=bool)
        self._recharge_out = np.zeros(n_robots)
        self._continue = np.zeros(n_robots, dtype=bool)

    def fill_inputs(
        self,
        energy: np.ndarray,
        proximity: np.ndarray,
        face_distance: np.ndarray,
        led_distance: np.ndarray,
        battery_distance: np.ndarray,
        led_previous: np.ndarray,
    ) -> np.ndarray:
        """Assemble the (n_robots, 12) inputs in place and return the buffer.

        Args:
            energy: (n,) raw energy; divided by ``max_energy`` here.
            proximity: (n, 6) proximity readings already normalised to [0, 1].
            face_distance: (n,) normalised distance to the nearest face (1 if unseen).
            led_distance: (n,) normalised distance to the nearest green LED (1 if unseen).
            battery_distance: (n,) normalised distance to the nearest pack (1 if unseen).
            led_previous: (n,) own LED state at the previous step (bool or 0/1).
        """
        x = self.inputs
        np.divide(energy, self.max_energy, out=x[:, IN_ENERGY])
        x[:, IN_PROXIMITY] = proximity
        x[:, IN_FACE_DISTANCE] = face_distance
        x[:, IN_LED_DISTANCE] = led_distance
        x[:, IN_BATTERY_DISTANCE] = battery_distance
        x[:, IN_LED_PREVIOUS] = led_previous
        return x

    def compute_activations(self, weights: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """Raw activations (n, 3) of Mate, Forage, Search: ``W_robot (3x12) @ x_robot``."""
        n = weights.shape[0]
        w = weights[:, SELECTION].reshape(n, N_OUTPUTS, N_INPUTS)
        np.matmul(w, inputs[:, :, None], out=self._column)
        return self.activations

    def select(
        self,
        weights: np.ndarray,
        mate_available: np.ndarray,
        forage_available: np.ndarray,
        inputs: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Choose each robot's behaviour and LED state.

        Args:
            weights: (n, 39) active agents' genomes.
            mate_available: (n,) bool, another CR is in view.
            forage_available: (n,) bool, a battery pack is in view.
            inputs: (n, 12) inputs; defaults to the buffer :meth:`fill_inputs` wrote.

        Returns:
            ``(behaviour, led)``: (n,) int in {MATE, FORAGE, SEARCH} and (n,) bool. Both are this
            controller's buffers, overwritten by the next call.
        """
        act = self.compute_activations(weights, self.inputs if inputs is None else inputs)
        masked = self._masked
        masked[:] = act
        unavailable = self._unavailable
        np.logical_not(mate_available, out=unavailable)
        np.copyto(masked[:, MATE], -np.inf, where=unavailable)
        np.logical_not(forage_available, out=unavailable)
        np.copyto(masked[:, FORAGE], -np.inf, where=unavailable)
        np.argmax(masked, axis=1, out=self.behaviour)
        np.greater(act[:, MATE], act[:, FORAGE], out=self.led)
        return self.behaviour, self.led

    def decide(
        self,
        weights: np.ndarray,
        energy: np.ndarray,
        proximity: np.ndarray,
        face_distance: np.ndarray,
        led_distance: np.ndarray,
        battery_distance: np.ndarray,
        led_previous: np.ndarray,
        mate_available: np.ndarray,
        forage_available: np.ndarray,
        steps_recharged: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`fill_inputs`, :meth:`select` and :meth:`continue_recharge` in one call.

        What the evolution runner calls every step: one compiled call
        (:mod:`evolution.controller_kernel`) where numba is available, else the three
        methods. Arguments as theirs.

        Returns:
            ``(behaviour, led, continue_recharge)``, this controller's buffers.
        """
        if not controller_kernel.AVAILABLE:  # pragma: no cover - numba is a dependency
            self.fill_inputs(
                energy, proximity, face_distance, led_distance, battery_distance, led_previous
            )
            behaviour, led = self.select(weights, mate_available, forage_available)
            return behaviour, led, self.continue_recharge(weights, energy, steps_recharged)
        controller_kernel.decide(
            weights, RECHARGE.start, SELECTION.start, energy, proximity, face_distance,
            led_distance, battery_distance, led_previous, mate_available, forage_available,
            steps_recharged, self.max_energy, self.max_recharge_steps, self.inputs,
            self.activations, self.behaviour, self.led, self._continue,
        )  # fmt: skip
        return self.behaviour, self.led, self._continue

    @property
    def proceed(self) -> np.ndarray:
        """(n,) bool, the latest recharge decisions (True = continue; :meth:`decide`'s third
        result, a buffer of this controller)."""
        return self._continue

    def kernel_arguments(self) -> tuple:
        """The buffers ``controller_kernel.decide`` fills (inputs, activations, behaviour,
        LED, recharge decision), for callers that run it inside their own compiled code."""
        return (self.inputs, self.activations, self.behaviour, self.led, self._continue)

    def continue_recharge(
        self, weights: np.ndarray, energy: np.ndarray, steps_recharged: np.ndarray
    ) -> np.ndarray:
        """The recharge decision: True where ``w · [energy/200, steps/40, 1] <= 0`` (continue).

        Args:
            weights: (n, 39) active agents' genomes.
            energy: (n,) raw energy.
            steps_recharged: (n,) consecutive steps recharged so far.

        Returns:
            (n,) bool buffer (overwritten by the next call).
        """
        w = weights[:, RECHARGE]
        out = self._recharge_out
        np.divide(energy, self.max_energy, out=out)
        out *= w[:, 0]
        out += w[:, 1] * (np.asarray(steps_recharged, dtype=float) / self.max_recharge_steps)
        out += w[:, 2]
        np.less_equal(out, 0.0, out=self._continue)
        return self._continue
