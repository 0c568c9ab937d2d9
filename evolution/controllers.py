"""Controllers as components: a registry of the rules that map a robot's inputs to its decision.

A controller turns the input vector (:mod:`evolution.input_kernels`, the same for every
controller) into a robot's decision: the behaviour (Mate, Forage or Search; only available
ones), the LED and, while docked, whether to keep recharging. The run's controller is the
setting ``evolution.controller`` (:class:`~evolution.config.EvolutionConfig`); each name is an
entry of :data:`CONTROLLERS`, a :class:`ControllerSpec` that declares

- its **genome blocks** as a function of the run's config and the number of inputs
  (:class:`GeneBlock`: name, shape, initial range), from which the genome's length, layout,
  initial draw, crossover points and mutation follow (:class:`evolution.genome.GenomeLayout`;
  learning mode's genes come after the controller's);
- its **rule**, a compiled kernel beside its numpy reference with the same signature,
  ``decide(rules, robots, perceived, out)``: it reads the filled inputs ``out.inputs`` and the
  genes ``out.weights`` (the blocks' starts and shapes are in ``rules.layout``) and writes
  ``out.activations``, ``out.behaviour``, ``out.led`` and ``out.continue_recharge``
  (:class:`evolution.kernels.ControllerBuffers`);
- its **own state** per agent (``state_size(config, n_inputs)`` numbers, 0 for a stateless
  controller): the rule reads and writes ``out.state`` (n, state size), the active agents'
  state. The state belongs to the agent, not to the robot: it is zero at birth (every newborn),
  the scheduler saves it when a robot switches the agent out and restores it when the agent
  comes back (:mod:`evolution.scheduler`), and checkpoints hold it, so a resumed run continues
  bit for bit. A controller needs nothing else to remember;
- its **constants** (``constants(config)``: numbers its rule reads from ``rules.constants``);
- whether a deployment bundle can hold it (its standalone reference step implements it).

The runner's fused step is built around the rule by :func:`step_kernels`
(:func:`evolution.kernels.build_step_kernels`: the paper's fused functions rebuilt around the
rule, compiled in-process, once per controller and input table); the paper's controller with
the paper's inputs uses those functions as they are, compiled once per installation
(``prebuilt``), which are the runs of the paper, bit for bit.

Built in:

- ``paper`` (the default): the paper's one-layer controller (§3.5): 3 recharge weights and
  3 x inputs selection weights, 39 genes (:func:`evolution.kernels.decide_paper`);
- ``mlp``: one tanh hidden layer of ``evolution.hidden_units`` units between the same inputs
  and the same three outputs, with the paper's 3-weight recharge part
  (:mod:`evolution.controller_kernels`). The recharge decision stays the paper's linear rule: it
  reads a quantity the selection inputs lack (the steps recharged), runs only while docked
  when the selection part is idle, and a line in (energy, steps) is all a keep-or-stop threshold
  needs; so the two controllers differ only in the selection part, whose capacity is what the
  comparison is about, and the genome's first three genes mean the same in both;
- ``ctrnn``: a continuous-time recurrent network (Beer 1995) of ``evolution.hidden_units``
  units, one Euler step per control step, with evolved time constants, biases and gains
  (ranges in ``evolution.ctrnn``) and the paper's recharge part; its unit states are each
  agent's own (:mod:`evolution.controller_kernels`).

**Adding a controller** is one entry here (its blocks and its two kernels, written beside the
mlp's in :mod:`evolution.controller_kernels`) and its test; a program can also add one at run
time with :func:`register_controller` (a test does, to prove the seam). ``docs/design.md`` §3
and §9.28.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from behaviours.kernels import InputBuffers
from cyber_rodent.commands import DESIGN_TOP_SPEED
from cyber_rodent.vision.types import BATTERY, FACE, LED
from evolution.controller_kernels import (
    decide_ctrnn,
    decide_ctrnn_reference,
    decide_mlp,
    decide_mlp_reference,
)
from evolution.input_kernels import (
    N_PAPER_INPUTS,
    PAPER_INPUTS,
    ControllerInput,
    ControllerRules,
    Fill,
    InputSources,
    RobotState,
    compiled_reader,
    extend_fill,
    fill_inputs,
    fill_inputs_reference,
    fill_nothing,
    fill_nothing_reference,
    fill_rows_reference,
    select_inputs,
)
from evolution.kernels import (
    N_OUTPUTS,
    N_RECHARGE,
    PAPER_STEP,
    ControllerKernel,
    StepKernels,
    build_step_kernels,
    decide_paper,
    decide_paper_reference,
)


class CtrnnRanges(Protocol):
    """The ranges of the ``ctrnn`` controller's time constants and gains
    (:class:`evolution.config.CtrnnConfig`)."""

    @property
    def tau_low(self) -> float: ...
    @property
    def tau_high(self) -> float: ...
    @property
    def gain_low(self) -> float: ...
    @property
    def gain_high(self) -> float: ...


class ControllerSettings(Protocol):
    """The settings the built-in controllers read of a run's configuration. A controller's
    functions (:class:`ControllerSpec`) and :func:`resolve` are given the run's
    :class:`evolution.config.EvolutionConfig`, of which a registered controller may read any
    field; it is named here by these fields so that the config, which checks its controller
    against this registry, and the registry do not import each other."""

    @property
    def controller(self) -> str:
        """``evolution.controller``: the controller's name in :data:`CONTROLLERS`."""

    @property
    def inputs(self) -> str:
        """``evolution.inputs``: the input names (:func:`evolution.input_kernels.select_inputs`)."""

    @property
    def hidden_units(self) -> int:
        """``evolution.hidden_units``: ``mlp``'s and ``ctrnn``'s units."""

    @property
    def ctrnn(self) -> CtrnnRanges:
        """``evolution.ctrnn``: ``ctrnn``'s ranges."""


@dataclass(frozen=True)
class GeneBlock:
    """A contiguous block of a controller's genes.

    Attributes:
        name: the block's name (``recharge``, ``selection``, ...).
        shape: its shape, ``(size,)`` or ``(rows, columns)`` (row-major in the genome).
        meaning: what its genes are, in words.
        initial_scale: a newborn's genes are U[low, high] (``genetic.initial_weight_low/high``)
            times this (1: the paper's range).
    """

    name: str
    shape: tuple[int, ...]
    meaning: str = ""
    initial_scale: float = 1.0

    def __post_init__(self) -> None:
        if not 1 <= len(self.shape) <= 2 or min(self.shape) < 1:
            raise ValueError(f"block {self.name}: shape must be (n,) or (rows, columns) of "
                             f"positive sizes, got {self.shape}")  # fmt: skip
        if not (math.isfinite(self.initial_scale) and self.initial_scale > 0):
            raise ValueError(f"block {self.name}: initial_scale must be > 0")

    @property
    def size(self) -> int:
        """Genes in the block."""
        return math.prod(self.shape)


@dataclass(frozen=True)
class ControllerSpec:
    """One controller (see the module docstring).

    Attributes:
        name: its value of ``evolution.controller``.
        description: one line.
        blocks: ``blocks(config, n_inputs)``: the genome blocks, in genome order.
        decide: the rule, compiled (``decide(rules, robots, perceived, out)``).
        decide_reference: the rule in numpy, the same signature.
        deployable: a deployment bundle can hold it.
        prebuilt: fused kernels compiled once per installation, used with the paper's inputs
            (None: built in-process by :func:`step_kernels`).
        state_size: ``state_size(config, n_inputs)``: numbers of each agent's own state (the
            rule's ``out.state`` row); None: stateless (0).
        constants: ``constants(config)``: the numbers the rule reads as ``rules.constants``;
            None: none.
    """

    name: str
    description: str
    blocks: Callable[[ControllerSettings, int], tuple[GeneBlock, ...]]
    decide: ControllerKernel
    decide_reference: ControllerKernel
    deployable: bool = False
    prebuilt: StepKernels | None = None
    state_size: Callable[[ControllerSettings, int], int] | None = None
    constants: Callable[[ControllerSettings], tuple[float, ...]] | None = None

    def __post_init__(self) -> None:
        if not re.fullmatch(r"[a-z][a-z0-9_]*", self.name):
            raise ValueError(f"controller name must be snake_case, got {self.name!r}")


def paper_blocks(n_inputs: int) -> tuple[GeneBlock, ...]:
    """The paper's genome blocks over ``n_inputs`` inputs (it has no other setting)."""
    return (
        GeneBlock("recharge", (N_RECHARGE,), "weights of energy, steps recharged and bias"),
        GeneBlock("selection", (N_OUTPUTS, n_inputs), "Mate, Forage, Search x inputs"),
    )


def _mlp_blocks(config: ControllerSettings, n_inputs: int) -> tuple[GeneBlock, ...]:
    units = config.hidden_units
    return (
        GeneBlock("recharge", (N_RECHARGE,), "weights of energy, steps recharged and bias"),
        GeneBlock("hidden", (units, n_inputs), "hidden units x inputs"),
        GeneBlock("output", (N_OUTPUTS, units + 1), "Mate, Forage, Search x (units, bias)"),
    )


def _ctrnn_blocks(config: ControllerSettings, n_inputs: int) -> tuple[GeneBlock, ...]:
    units = config.hidden_units
    return (
        GeneBlock("recharge", (N_RECHARGE,), "weights of energy, steps recharged and bias"),
        GeneBlock("input", (units, n_inputs), "units x inputs"),
        GeneBlock("recurrent", (units, units), "units x units (from unit m into unit j)"),
        GeneBlock("bias", (units,), "each unit's bias"),
        GeneBlock("tau", (units,), "each unit's time constant, log-mapped onto evolution.ctrnn"),
        GeneBlock("gain", (units,), "each unit's gain, log-mapped onto evolution.ctrnn"),
        GeneBlock("output", (N_OUTPUTS, units + 1), "Mate, Forage, Search x (units, bias)"),
    )


#: The paper's one-layer controller (§3.5).
PAPER = ControllerSpec(
    name="paper",
    description="the paper's one-layer controller: 3 recharge + 3 x inputs selection weights",
    blocks=lambda config, n_inputs: paper_blocks(n_inputs),
    decide=decide_paper,
    decide_reference=decide_paper_reference,
    deployable=True,
    prebuilt=PAPER_STEP,
)
#: One tanh hidden layer of ``evolution.hidden_units`` units; the paper's recharge part.
MLP = ControllerSpec(
    name="mlp",
    description="one tanh hidden layer (evolution.hidden_units) between the inputs and the "
    "three outputs; the paper's recharge part",
    blocks=_mlp_blocks,
    decide=decide_mlp,
    decide_reference=decide_mlp_reference,
)
#: A continuous-time recurrent network with memory (Beer 1995); the paper's recharge part.
CTRNN = ControllerSpec(
    name="ctrnn",
    description="a continuous-time recurrent network (Beer 1995) of evolution.hidden_units "
    "units with evolved time constants, biases and gains; memory per agent; the paper's "
    "recharge part",
    blocks=_ctrnn_blocks,
    decide=decide_ctrnn,
    decide_reference=decide_ctrnn_reference,
    state_size=lambda config, n_inputs: 2 * config.hidden_units,
    constants=lambda config: (
        config.ctrnn.tau_low, config.ctrnn.tau_high, config.ctrnn.gain_low,
        config.ctrnn.gain_high,
    ),  # fmt: skip
)
#: The built-in controllers, in the order ``cyber-rodent config`` lists them.
BUILT_IN: tuple[ControllerSpec, ...] = (PAPER, MLP, CTRNN)
#: Every controller by name: the built-in ones and any registered since.
CONTROLLERS: dict[str, ControllerSpec] = {spec.name: spec for spec in BUILT_IN}


def controller_names() -> tuple[str, ...]:
    """The names ``evolution.controller`` accepts now."""
    return tuple(CONTROLLERS)


def register_controller(spec: ControllerSpec) -> None:
    """Make ``spec`` a value of ``evolution.controller`` in this process.

    Raises:
        ValueError: a controller of that name exists.
    """
    if not isinstance(spec, ControllerSpec):
        raise ValueError(f"spec must be a ControllerSpec, got {type(spec).__name__}")
    if spec.name in CONTROLLERS:
        raise ValueError(f"a controller named {spec.name!r} exists")
    CONTROLLERS[spec.name] = spec


def unregister_controller(name: str) -> None:
    """Remove a controller added by :func:`register_controller`.

    Raises:
        ValueError: ``name`` is built in or unknown.
    """
    if name not in CONTROLLERS or CONTROLLERS[name] in BUILT_IN:
        raise ValueError(f"{name!r} is not a registered controller")
    del CONTROLLERS[name]


@dataclass(frozen=True)
class ControllerLayout:
    """A controller resolved for one run: its spec, its genome blocks and its inputs.

    Attributes:
        spec: the controller.
        blocks: its genome blocks, in genome order.
        inputs: the input table it reads (one column per row).
        state_size: numbers of each agent's own state (0: stateless).
        constants: the numbers its rule reads as ``rules.constants``.
    """

    spec: ControllerSpec
    blocks: tuple[GeneBlock, ...]
    inputs: tuple[ControllerInput, ...]
    state_size: int = 0
    constants: tuple[float, ...] = ()

    @property
    def length(self) -> int:
        """The controller's genes."""
        return sum(block.size for block in self.blocks)

    @property
    def n_inputs(self) -> int:
        return len(self.inputs)

    def block(self, name: str) -> slice:
        """The genes of block ``name``.

        Raises:
            KeyError: no such block.
        """
        start = 0
        for block in self.blocks:
            if block.name == name:
                return slice(start, start + block.size)
            start += block.size
        raise KeyError(f"controller {self.spec.name} has no block {name!r}")

    def layout_array(self) -> np.ndarray:
        """(blocks, 3) int64: each block's start, rows and columns (``ControllerRules.layout``)."""
        rows, start = [], 0
        for block in self.blocks:
            shape = block.shape if len(block.shape) == 2 else (1, block.shape[0])
            rows.append((start, *shape))
            start += block.size
        return np.array(rows, dtype=np.int64)

    def initial_scale(self) -> tuple[float, ...] | None:
        """Per gene, the factor of the initial range; None if it is 1 throughout."""
        if all(block.initial_scale == 1.0 for block in self.blocks):
            return None
        return tuple(s for block in self.blocks for s in [block.initial_scale] * block.size)

    def rules(
        self,
        max_energy: float,
        max_recharge_steps: float,
        lifetime_steps: float = 400.0,
        top_speed: float = DESIGN_TOP_SPEED,
    ) -> ControllerRules:
        """The kernels' constants for this controller (class columns of the vision; the
        robot's top speed, m/s, for the wheel inputs)."""
        return ControllerRules(
            float(max_energy), float(max_recharge_steps), LED, FACE, BATTERY,
            self.layout_array(), np.array(self.constants, dtype=np.float64),
            float(lifetime_steps), float(top_speed),
        )  # fmt: skip

    def kernels(self) -> StepKernels:
        """The controller stage and the fused calls (:func:`step_kernels`)."""
        return step_kernels(self.spec, self.inputs)


def resolve(
    config: ControllerSettings, inputs: tuple[ControllerInput, ...] | None = None
) -> ControllerLayout:
    """The controller of ``config`` (``evolution.controller``) over ``inputs`` (default: the
    run's, ``evolution.inputs``: :func:`evolution.input_kernels.select_inputs`).

    Raises:
        ValueError: the controller or an input is not registered (in this process), or the
            controller declares a negative state size.
    """
    spec = CONTROLLERS.get(config.controller)
    if spec is None:
        raise ValueError(
            f"evolution.controller must be one of {', '.join(CONTROLLERS)}, got "
            f"{config.controller!r}"
        )
    rows = select_inputs(config.inputs) if inputs is None else inputs
    size = 0 if spec.state_size is None else int(spec.state_size(config, len(rows)))
    if size < 0:
        raise ValueError(f"controller {spec.name}: state_size must be >= 0, got {size}")
    constants = () if spec.constants is None else tuple(map(float, spec.constants(config)))
    return ControllerLayout(spec, tuple(spec.blocks(config, len(rows))), rows, size, constants)


def genome_length(config: ControllerSettings) -> int:
    """The controller's genes for ``config`` (without learning mode's)."""
    return resolve(config).length


@functools.cache
def fill_kernels(inputs: tuple[ControllerInput, ...]) -> tuple[Fill, Fill]:
    """The compiled fill of ``inputs`` and its reference: :func:`~evolution.input_kernels.
    fill_inputs` for the paper's inputs (compiled once per installation), then, for each further
    row, its column from its own reader (compiled in this process)."""
    fill: Fill
    reference: Fill
    if inputs[:N_PAPER_INPUTS] == PAPER_INPUTS:
        fill, reference, first = fill_inputs, fill_inputs_reference, N_PAPER_INPUTS
    else:
        fill, reference, first = fill_nothing, fill_nothing_reference, 0
    rest = inputs[first:]
    for offset, row in enumerate(rest):
        fill = extend_fill(fill, compiled_reader(row), first + offset, row.arg)
    if not rest:
        return fill, reference
    start = reference

    def extended_reference(
        rules: ControllerRules, robots: RobotState, perceived: InputBuffers, out: np.ndarray
    ) -> None:
        start(rules, robots, perceived, out)
        fill_rows_reference(rest, first, InputSources(rules, robots, perceived), out)

    return fill, extended_reference


@functools.cache
def step_kernels(spec: ControllerSpec, inputs: tuple[ControllerInput, ...]) -> StepKernels:
    """The controller stage and fused calls of ``spec`` over ``inputs``, built once per process:
    the spec's ``prebuilt`` kernels with the paper's inputs, else
    :func:`evolution.kernels.build_step_kernels` around its rule and :func:`fill_kernels`."""
    if spec.prebuilt is not None and inputs == PAPER_INPUTS:
        return spec.prebuilt
    fill, fill_reference = fill_kernels(inputs)
    return build_step_kernels(fill, fill_reference, spec.decide, spec.decide_reference)


__all__ = [
    "BUILT_IN",
    "CONTROLLERS",
    "CTRNN",
    "MLP",
    "PAPER",
    "ControllerLayout",
    "ControllerSpec",
    "GeneBlock",
    "controller_names",
    "fill_kernels",
    "genome_length",
    "paper_blocks",
    "register_controller",
    "resolve",
    "step_kernels",
    "unregister_controller",
]
