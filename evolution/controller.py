"""The evolved controller of every robot, vectorised (paper §3.5, Fig. 5; docs/design.md §5).

The run's controller is a component (:mod:`evolution.controllers`, the setting
``evolution.controller``); :class:`NeuralController` evaluates it for every robot's active agent
in one call. The default is the paper's one-layer controller, with two parts, both plain
weighted sums of inputs in [0, 1]:

**Recharge part** (3 weights, genome ``[0:3]``), used while docked:
``output = w0 * energy / max_energy + w1 * steps_recharged / max_recharge_steps + w2``;
the robot keeps recharging while ``output <= 0`` and stops otherwise.

**Selection part** (12 inputs x 3 outputs = 36 weights, genome ``[3:39]``, output-major: the 12
weights into Mate, then Forage, then Search), used every step the robot is not recharging. The
inputs, in order, are the rows of the input table (:data:`evolution.input_kernels.INPUTS`, whose
names are :data:`INPUT_NAMES`; ``docs/design.md`` §5 shows it): the energy, the six proximity
readings, the normalised distances to the nearest red face, green LED and blue battery pack (1
if none is seen), the bias and the robot's own LED at the previous control step. A row added to
the table adds a column here and a weight to each output.

The available behaviour with the largest activation wins: Mate is available only with another CR
in view, Forage only with a pack in view, Search always. Exact ties go to the lower index (Mate,
then Forage, then Search), which only matters for hand-made weights. The LED is on iff
activation(Mate) > activation(Forage), compared on the raw activations whether or not the
behaviours are available: the paper ties the LED to the two output nodes, not to the choice, so a
robot can signal willingness to mate before it sees a partner. The ``mlp`` controller keeps these
output rules and the recharge part (:mod:`evolution.controller_kernels`).

The controller reads a (n_robots, genes) weight matrix (one row per robot's active agent), the
robots' state and the perceived inputs, and writes into buffers it owns, so the hot loop
allocates nothing. The rule is the controller's compiled kernel (the inputs filled first) or its
numpy reference; ``backend`` picks one.
"""

from __future__ import annotations

import numpy as np

from behaviours.inputs import FORAGE, MATE, SEARCH
from behaviours.kernels import InputBuffers
from cyber_rodent.backend import DEFAULT_BACKEND, Backend, bind, check_backend, pick
from cyber_rodent.commands import DESIGN_TOP_SPEED
from cyber_rodent.validation import check_integer, check_number
from evolution.config import EvolutionConfig
from evolution.controllers import ControllerLayout, resolve
from evolution.input_kernels import (
    IN_BATTERY_DISTANCE,
    IN_BIAS,
    IN_ENERGY,
    IN_FACE_DISTANCE,
    IN_LED_DISTANCE,
    IN_LED_PREVIOUS,
    IN_PROXIMITY_START,
    INPUT_NAMES,
    N_INPUTS,
    N_PROXIMITY,
)
from evolution.kernels import (
    N_OUTPUTS,
    ControllerBuffers,
    RobotState,
)

#: Names of the selection part's outputs, in behaviour-index order.
BEHAVIOUR_NAMES = ("mate", "forage", "search")
#: The six proximity inputs.
IN_PROXIMITY = slice(IN_PROXIMITY_START, IN_PROXIMITY_START + N_PROXIMITY)


class NeuralController:
    """Evaluates every robot's active agent's controller in one call.

    Args:
        weights: (n_robots, genes) the active agents' controller genes (39 for the paper's);
            read at every :meth:`decide`, so pass a live view (the scheduler's
            ``active_weights``) or write into it in place.
        robots: views of the robots' energy, recharge counters and LEDs.
        perceived: the perceived inputs (proximities, normalised distances, availability).
        max_energy: energy normalisation (paper: 200).
        max_recharge_steps: recharge-step normalisation (paper: 40).
        backend: ``"numba"`` (the compiled kernel) or ``"numpy"`` (its reference).
        controller: the controller and its inputs (:func:`evolution.controllers.resolve`);
            default: the paper's over the paper's inputs.
        state: (n_robots, state size) the active agents' own controller state, read and
            written by every :meth:`decide` (the scheduler's ``controller_state``: it swaps
            each agent's state in and out); default: a zero buffer of its own.
        lifetime_steps: the steps-since inputs' normalisation (paper: 400).

    Attributes:
        buffers: the :class:`~evolution.kernels.ControllerBuffers`: ``inputs`` (n, inputs),
            ``activations`` (n, 3), ``behaviour`` (n,), ``led`` (n,), ``continue_recharge``
            (n,), written by every :meth:`decide`.
        rules: the :class:`~evolution.kernels.ControllerRules`.
        layout: the resolved controller (its spec, genome blocks and inputs).
        kernels: its :class:`~evolution.kernels.StepKernels` (the runner's fused calls too).
    """

    def __init__(
        self,
        weights: np.ndarray,
        robots: RobotState,
        perceived: InputBuffers,
        max_energy: float = 200.0,
        max_recharge_steps: int = 40,
        backend: Backend = DEFAULT_BACKEND,
        controller: ControllerLayout | None = None,
        state: np.ndarray | None = None,
        lifetime_steps: int = 400,
        top_speed: float = DESIGN_TOP_SPEED,
    ) -> None:
        layout = controller if controller is not None else resolve(EvolutionConfig())
        n = check_integer("n_robots", weights.shape[0], 1)
        if weights.shape != (n, layout.length) or weights.dtype != np.float64:
            raise ValueError(f"weights must be float64 of shape ({n}, {layout.length})")
        if state is None:
            state = np.zeros((n, layout.state_size))
        if state.shape != (n, layout.state_size) or state.dtype != np.float64:
            raise ValueError(f"state must be float64 of shape ({n}, {layout.state_size})")
        self.layout = layout
        self.rules = layout.rules(
            check_number("max_energy", max_energy, 0.0, low_open=True),
            float(check_integer("max_recharge_steps", max_recharge_steps, 1)),
            float(check_integer("lifetime_steps", lifetime_steps, 1)),
            check_number("top_speed", top_speed, 0.0, low_open=True),
        )
        inputs = np.zeros((n, layout.n_inputs))
        for column, row in enumerate(layout.inputs):
            if row.low == row.high:  # a constant (the bias) holds its value from the start
                inputs[:, column] = row.low
        self.buffers = ControllerBuffers(
            weights=weights,
            inputs=inputs,
            activations=np.zeros((n, N_OUTPUTS)),
            behaviour=np.zeros(n, dtype=np.int64),
            led=np.zeros(n, dtype=np.bool_),
            continue_recharge=np.zeros(n, dtype=np.bool_),
            state=state,
        )
        self.n_robots = n
        self.backend = check_backend(backend)
        self.kernels = layout.kernels()
        self.kernel = pick(self.backend, self.kernels.controller, self.kernels.controller_reference)
        self.decide = bind(self.kernel, self.rules, robots, perceived, self.buffers)
        """Evaluate every robot's controller into :attr:`buffers` (no arguments)."""

    @property
    def behaviour(self) -> np.ndarray:
        """(n,) the behaviour each robot chose at the last :meth:`decide`."""
        return self.buffers.behaviour

    @property
    def state(self) -> np.ndarray:
        """(n, state size) the active agents' own controller state (empty if stateless)."""
        return self.buffers.state

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
