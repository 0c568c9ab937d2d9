"""The controller's inputs as one declared table, and the rule that fills them from named buffers.

Every controller (:mod:`evolution.controllers`) reads the same input vector, one column per row
of :data:`INPUTS`, in table order. A row (:class:`ControllerInput`) names the input, says what
it reads, how it is normalised and its range, and names its **reader**: a scalar function
``read(i, src, arg) -> float`` of robot ``i`` over :class:`InputSources` (the controller's
rules, the robots' own state and the perceived inputs: the named buffers of the controller
stage) and the row's integer ``arg``. The reader is written once in plain, numba-compilable
Python: compiled, it fills its column inside the runner's one compiled step; called as Python,
it is the numpy backend's reference (the same operations, so both give the same bits).

Everything else is derived from the table: the column indices (``IN_*``), the count
(:data:`N_INPUTS`), the names (:data:`INPUT_NAMES`), every controller's genome length
(:mod:`evolution.controllers`), the deployment bundle's input list (and so its standalone
reference step), and the input table of ``docs/design.md`` (:func:`markdown_table`; a test
compares them).

**Adding an input** is one row here (at the end of :data:`INPUTS`, so the paper's columns keep
their places) plus its reader. The paper's twelve inputs are filled by :func:`fill_inputs`, a
compiled kernel that calls their readers in table order and is cached on disk with the other
kernels; any row after them is filled by a kernel composed in-process from the rows' own
readers (:func:`evolution.controllers.fill_kernels`), so a new input reaches the compiled path
with no other edit, at the price of compiling the step once per process. A program may also
add a row at run time (:func:`register_input`; a test or a notebook): it is part of every
controller's input vector in that process until :func:`unregister_input`, and a run's
checkpoints record the input names, so a run is never resumed with other inputs.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from behaviours.kernels import BehaviourInputs, InputBuffers
from cyber_rodent.backend import jit_built, jit_inline
from cyber_rodent.commands import DESIGN_TOP_SPEED
from cyber_rodent.robot import CYBER_RODENT_PROXIMITY, CYBER_RODENT_SENSORS
from cyber_rodent.vision.types import BATTERY, FACE, LED

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Bools = npt.NDArray[np.bool_]


class ControllerRules(NamedTuple):
    """The controller's constants: its normalisations, the class columns of the distances it
    reads, and where its genome's blocks lie."""

    max_energy: float  #: energy input = energy / max_energy (paper: 200)
    max_recharge_steps: float  #: recharge-step input = steps / max_recharge_steps (paper: 40)
    led: int  #: columns of the perceived normalised distances
    face: int
    battery: int
    #: (blocks, 3) each genome block's start, rows and columns, in the controller's block
    #: order (:class:`evolution.controllers.GeneBlock`); the default is the paper's layout.
    layout: Ints = np.array([[0, 1, 3], [3, 3, 12]], dtype=np.int64)  # noqa: RUF009
    #: the controller's own constants (:attr:`evolution.controllers.ControllerSpec.constants`:
    #: the CTRNN's time-constant and gain ranges); empty for the paper's
    constants: Floats = np.zeros(0)  # noqa: RUF009
    lifetime_steps: float = 400.0  #: steps-since inputs = clip(steps / lifetime_steps, 0, 1)
    #: wheel inputs = (speed / top_speed + 1) / 2, m/s (the robot's top speed)
    top_speed: float = DESIGN_TOP_SPEED


class RobotState(NamedTuple):
    """What the controller reads from the robots themselves (views of the survival world)."""

    energy: Floats  #: (n,) the active agent's energy
    recharge_steps: Ints  #: (n,) consecutive steps recharged so far
    led_on: Bools  #: (n,) the LED as lit during the previous step
    #: (n, 2) m/s, the left and right wheel speeds the robot commanded in the previous step
    wheels: Floats = np.zeros((0, 2))  # noqa: RUF009
    #: (n,) steps since the active agent last recharged (0 while docked; its age if never)
    since_recharge: Ints = np.zeros(0, dtype=np.int64)  # noqa: RUF009
    #: (n,) steps since the active agent last mated (0 in the mating step; its age if never)
    since_mating: Ints = np.zeros(0, dtype=np.int64)  # noqa: RUF009


class InputSources(NamedTuple):
    """Everything an input's reader may read (the controller stage's named buffers)."""

    rules: ControllerRules
    robots: RobotState
    perceived: InputBuffers


#: A reader: ``read(robot index, sources, row argument) -> input value``.
Reader = Callable[[int, InputSources, int], float]


# --- the readers of the paper's inputs -------------------------------------------------------
@jit_inline
def energy(i: int, src: InputSources, arg: int) -> float:
    """The active agent's energy over the maximum energy."""
    return float(src.robots.energy[i] / src.rules.max_energy)


@jit_inline
def proximity(i: int, src: InputSources, arg: int) -> float:
    """Proximity ``arg`` of the six (already normalised by the input mapping)."""
    return float(src.perceived.proximity[i, arg])


@jit_inline
def face_distance(i: int, src: InputSources, arg: int) -> float:
    """Normalised distance to the nearest red face (1 if none is seen)."""
    return float(src.perceived.norm_distance[i, src.rules.face])


@jit_inline
def led_distance(i: int, src: InputSources, arg: int) -> float:
    """Normalised distance to the nearest green LED (1 if none is seen)."""
    return float(src.perceived.norm_distance[i, src.rules.led])


@jit_inline
def battery_distance(i: int, src: InputSources, arg: int) -> float:
    """Normalised distance to the nearest blue battery pack (1 if none is seen)."""
    return float(src.perceived.norm_distance[i, src.rules.battery])


@jit_inline
def bias(i: int, src: InputSources, arg: int) -> float:
    """The constant 1."""
    return 1.0


@jit_inline
def led_previous(i: int, src: InputSources, arg: int) -> float:
    """1 if the robot's LED was lit during the previous step, else 0."""
    return 1.0 if src.robots.led_on[i] else 0.0


# --- the readers of the built-in inputs beyond the paper's ------------------------------------
@jit_inline
def wheel(i: int, src: InputSources, arg: int) -> float:
    """Wheel ``arg`` (0 left, 1 right) as commanded in the previous step, mapped from
    [-top speed, top speed] onto [0, 1] (0.5 stopped)."""
    value = (src.robots.wheels[i, arg] / src.rules.top_speed + 1.0) * 0.5
    return float(min(1.0, max(0.0, value)))


@jit_inline
def steps_since_recharge(i: int, src: InputSources, arg: int) -> float:
    """Steps since the active agent last recharged over the lifetime, at most 1."""
    return float(min(1.0, src.robots.since_recharge[i] / src.rules.lifetime_steps))


@jit_inline
def steps_since_mating(i: int, src: InputSources, arg: int) -> float:
    """Steps since the active agent last mated over the lifetime, at most 1."""
    return float(min(1.0, src.robots.since_mating[i] / src.rules.lifetime_steps))


# --- the table ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class ControllerInput:
    """One input of the controller: one column of every controller's input vector.

    Attributes:
        name: the input's name (unique; ``snake_case``).
        reads: what it reads, in words (the buffer and field).
        normalisation: how the value is normalised, in words. ``{max_energy}``,
            ``{max_recharge_steps}`` and ``{max_distance}`` stand for the run's numbers (the
            deployment bundle writes them in; the docs write the name).
        low, high: the value's range.
        description: what the input means.
        read: the reader, ``read(i, src, arg) -> float`` (numba-compilable Python, or a
            compiled ``jit_inline`` function); see the module docstring.
        arg: the integer passed to ``read`` (a sensor's or a class's column), default 0.
        observation: how a robot computes it from its raw observations, for the deployment
            bundle's standalone reference step: ``"energy"``, ``"proximity"`` (``arg`` = which
            of the six), ``"distance"`` (``arg`` = class column), ``"constant"`` (the value
            ``high``) or ``"led_previous"``; None: the input cannot be deployed (a bundle of a
            run with it is refused).
    """

    name: str
    reads: str
    normalisation: str
    low: float
    high: float
    description: str
    read: Reader
    arg: int = 0
    observation: str | None = None

    def __post_init__(self) -> None:
        if not re.fullmatch(r"[a-z][a-z0-9_]*", self.name):
            raise ValueError(f"input name must be snake_case, got {self.name!r}")
        if not callable(self.read):
            raise ValueError(f"input {self.name}: read must be a function, got {self.read!r}")
        if not self.low <= self.high:
            raise ValueError(f"input {self.name}: low ({self.low}) must be <= high ({self.high})")

    def python_reader(self) -> Reader:
        """The reader as plain Python (the numpy backend's form)."""
        python: Reader = getattr(self.read, "py_func", self.read)
        return python


def _proximity_rows() -> tuple[ControllerInput, ...]:
    rows = []
    # The paper's table names the Cyber Rodent's sensors; another robot reads its own six
    # proximity sensors (``RobotModel.proximity``) into the same columns.
    for k, sensor in enumerate(CYBER_RODENT_PROXIMITY):
        row = CYBER_RODENT_SENSORS[sensor]
        sensor_name, angle, reach = row.name, row.bearing_deg, row.limit
        rows.append(
            ControllerInput(
                name=f"proximity_{sensor_name.removeprefix('range_')}",
                reads=f"perceived.proximity[:, {k}]",
                normalisation=f"clip(1 - range[{sensor}] / {reach:g}, 0, 1) ({sensor_name}; "
                "0 = nothing in range, 1 = touching)",
                low=0.0,
                high=1.0,
                description=f"proximity reading of the {sensor_name} sensor ({angle:g} deg)",
                read=proximity,
                arg=k,
                observation="proximity",
            )
        )
    return tuple(rows)


def _distance_row(name: str, target: str, read: Reader, column: str) -> ControllerInput:
    return ControllerInput(
        name=f"{name}_distance",
        reads=f"perceived.norm_distance[:, rules.{column}]",
        normalisation="clip(distance_m / {max_distance}, 0, 1) of the nearest " + target
        + "; 1 if none is seen",
        low=0.0,
        high=1.0,
        description=f"distance to the nearest {target}",
        read=read,
        arg={"face": FACE, "led": LED, "battery": BATTERY}[column],
        observation="distance",
    )


#: The controller's inputs, in column order: the paper's twelve (§3.5). New inputs go at the end.
INPUTS: tuple[ControllerInput, ...] = (
    ControllerInput(
        name="energy",
        reads="robots.energy",
        normalisation="energy / {max_energy} (the active agent's energy)",
        low=0.0,
        high=1.0,
        description="the active agent's energy",
        read=energy,
        observation="energy",
    ),
    *_proximity_rows(),
    _distance_row("face", "red face", face_distance, "face"),
    _distance_row("led", "green LED", led_distance, "led"),
    _distance_row("battery", "blue battery pack", battery_distance, "battery"),
    ControllerInput(
        name="bias",
        reads="(constant)",
        normalisation="1",
        low=1.0,
        high=1.0,
        description="bias",
        read=bias,
        observation="constant",
    ),
    ControllerInput(
        name="led_previous",
        reads="robots.led_on",
        normalisation="1 if the robot's own LED was lit during the previous control step, "
        "else 0 (after an agent switch: the LED the previous agent left)",
        low=0.0,
        high=1.0,
        description="own LED at the previous control step",
        read=led_previous,
        observation="led_previous",
    ),
)

#: Built-in inputs beyond the paper's: a run reads them only where ``evolution.inputs`` names
#: them, so adding one here changes no run (the default genome stays the paper's 39 genes).
EXTRA_INPUTS: tuple[ControllerInput, ...] = (
    *(
        ControllerInput(
            name=f"wheel_{side}",
            reads=f"robots.wheels[:, {arg}]",
            normalisation="clip((speed / {top_speed} + 1) / 2, 0, 1) of the "
            + side + " wheel's command in the previous control step (0.5: stopped)",
            low=0.0,
            high=1.0,
            description=f"the {side} wheel's last command",
            read=wheel,
            arg=arg,
        )
        for arg, side in enumerate(("left", "right"))
    ),
    ControllerInput(
        name="steps_since_recharge",
        reads="robots.since_recharge",
        normalisation="clip(steps / {lifetime_steps}, 0, 1): steps since the active agent last "
        "recharged (0 while docked; since birth if it never did)",
        low=0.0,
        high=1.0,
        description="time since the agent's last recharge",
        read=steps_since_recharge,
    ),
    ControllerInput(
        name="steps_since_mating",
        reads="robots.since_mating",
        normalisation="clip(steps / {lifetime_steps}, 0, 1): steps since the active agent last "
        "mated (0 in the mating step; since birth if it never did)",
        low=0.0,
        high=1.0,
        description="time since the agent's last mating",
        read=steps_since_mating,
    ),
)

#: Column indices of the paper's inputs (derived from the table).
INPUT_NAMES: tuple[str, ...] = tuple(row.name for row in INPUTS)
N_INPUTS = len(INPUTS)
IN_ENERGY = INPUT_NAMES.index("energy")
IN_PROXIMITY_START = INPUT_NAMES.index("proximity_front")  #: the six proximities follow
N_PROXIMITY = len(CYBER_RODENT_PROXIMITY)
IN_FACE_DISTANCE = INPUT_NAMES.index("face_distance")
IN_LED_DISTANCE = INPUT_NAMES.index("led_distance")
IN_BATTERY_DISTANCE = INPUT_NAMES.index("battery_distance")
IN_BIAS = INPUT_NAMES.index("bias")
IN_LED_PREVIOUS = INPUT_NAMES.index("led_previous")
#: The rows :func:`fill_inputs` fills (compiled once per installation): the paper's twelve.
PAPER_INPUTS: tuple[ControllerInput, ...] = INPUTS[:12]
N_PAPER_INPUTS = len(PAPER_INPUTS)
assert [row.read for row in PAPER_INPUTS] == [
    energy, *[proximity] * N_PROXIMITY, face_distance, led_distance, battery_distance, bias,
    led_previous,
]  # fmt: skip
assert [row.arg for row in PAPER_INPUTS[IN_PROXIMITY_START : IN_FACE_DISTANCE]] == list(
    range(N_PROXIMITY)
)


@jit_inline
def fill_inputs(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, inputs: Floats
) -> None:
    """Fill the paper's twelve input columns of every robot (:data:`PAPER_INPUTS`, in order)."""
    src = InputSources(rules, robots, perceived)
    for i in range(inputs.shape[0]):
        x = inputs[i]
        x[IN_ENERGY] = energy(i, src, 0)
        for k in range(N_PROXIMITY):
            x[IN_PROXIMITY_START + k] = proximity(i, src, k)
        x[IN_FACE_DISTANCE] = face_distance(i, src, 0)
        x[IN_LED_DISTANCE] = led_distance(i, src, 0)
        x[IN_BATTERY_DISTANCE] = battery_distance(i, src, 0)
        x[IN_BIAS] = bias(i, src, 0)
        x[IN_LED_PREVIOUS] = led_previous(i, src, 0)


def fill_inputs_reference(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, inputs: Floats
) -> None:
    """:func:`fill_inputs` in Python: each row's reader, robot by robot."""
    fill_rows_reference(PAPER_INPUTS, 0, InputSources(rules, robots, perceived), inputs)


@jit_inline
def fill_nothing(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, inputs: Floats
) -> None:
    """Fill no column (the start of a table that does not begin with the paper's inputs)."""


def fill_nothing_reference(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, inputs: Floats
) -> None:
    """:func:`fill_nothing`."""


Fill = Callable[[ControllerRules, RobotState, InputBuffers, Floats], None]


def extend_fill(fill: Fill, read: Reader, column: int, arg: int) -> Fill:
    """A compiled fill that runs ``fill``, then fills column ``column`` with the compiled reader
    ``read`` (built in this process: :func:`cyber_rodent.backend.jit_built`)."""

    def filled(
        rules: ControllerRules, robots: RobotState, perceived: InputBuffers, inputs: Floats
    ) -> None:
        fill(rules, robots, perceived, inputs)
        src = InputSources(rules, robots, perceived)
        for i in range(inputs.shape[0]):
            inputs[i, column] = read(i, src, arg)

    return jit_built(filled, inline=True)


def compiled_reader(row: ControllerInput) -> Reader:
    """``row``'s reader, compiled (as given if it is compiled already)."""
    if hasattr(row.read, "py_func"):
        return row.read
    return jit_built(row.read, inline=True)


def fill_rows_reference(
    rows: tuple[ControllerInput, ...], first: int, src: InputSources, inputs: Floats
) -> None:
    """Fill columns ``first``, ``first + 1``, ... with ``rows``' readers called as Python."""
    for offset, row in enumerate(rows):
        read, column = row.python_reader(), first + offset
        for i in range(inputs.shape[0]):
            inputs[i, column] = read(i, src, row.arg)


# --- the inputs a run may name: the declared rows and those a program registered -------------
_REGISTERED: list[ControllerInput] = []
#: The name of ``evolution.inputs`` that stands for the paper's twelve inputs, in order.
PAPER = "paper"


def available_inputs() -> tuple[ControllerInput, ...]:
    """Every input a run may name in ``evolution.inputs``: the paper's (:data:`INPUTS`), the
    built-in extras (:data:`EXTRA_INPUTS`), then any registered with :func:`register_input`."""
    return INPUTS + EXTRA_INPUTS + tuple(_REGISTERED)


def input_names_allowed() -> tuple[str, ...]:
    """The names ``evolution.inputs`` accepts now: ``paper`` and every available input."""
    return (PAPER, *(row.name for row in available_inputs()))


def select_inputs(names: str) -> tuple[ControllerInput, ...]:
    """The inputs a run reads, from ``evolution.inputs``: comma-separated names, in column
    order, where ``paper`` stands for the paper's twelve (the default is ``paper`` alone).

    Raises:
        ValueError: one line naming ``evolution.inputs``, the offending name and the allowed
            ones (an unknown name, a name given twice, or no input at all).
    """
    rows = {row.name: row for row in available_inputs()}
    chosen: list[ControllerInput] = []
    for part in str(names).split(","):
        name = part.strip()
        if name == PAPER:
            chosen.extend(INPUTS)
        elif name in rows:
            chosen.append(rows[name])
        else:
            raise ValueError(
                f"evolution.inputs must be comma-separated names from "
                f"{', '.join(input_names_allowed())}, got {name!r}"
            )
    seen: set[str] = set()
    for row in chosen:
        if row.name in seen:
            raise ValueError(f"evolution.inputs names {row.name!r} twice, got {names!r}")
        seen.add(row.name)
    return tuple(chosen)


def source_fields() -> dict[str, tuple[str, ...]]:
    """What a reader may read: each part of :class:`InputSources` and its fields."""
    return {
        "rules": ControllerRules._fields,
        "robots": RobotState._fields,
        "perceived": (
            *(name for name in InputBuffers._fields if name != "behaviour"),
            *(f"behaviour.{name}" for name in BehaviourInputs._fields),
        ),
    }


def probe_sources() -> InputSources:
    """One robot at rest that sees nothing: what :func:`probe_reader` calls a reader on."""
    behaviour = BehaviourInputs(
        np.array([[0.5, 1.0]]), np.array([[0.5, 1.0]]), np.zeros((1, 2)),
        np.zeros(1, dtype=np.bool_), np.zeros(1, dtype=np.bool_),
    )  # fmt: skip
    perceived = InputBuffers(
        np.zeros((1, 6)), np.full((1, 3), 0.5), np.ones((1, 3)), behaviour
    )
    robots = RobotState(
        np.ones(1), np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.bool_), np.zeros((1, 2)),
        np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64),
    )  # fmt: skip
    return InputSources(ControllerRules(200.0, 40.0, LED, FACE, BATTERY), robots, perceived)


def probe_reader(row: ControllerInput) -> None:
    """Call ``row``'s reader once, as Python, on :func:`probe_sources`; a field it reads that
    the sources lack is one ``ValueError`` line listing the fields a reader may read.

    Raises:
        ValueError: the reader reads a field that does not exist, or returns no number.
    """
    try:
        value = row.python_reader()(0, probe_sources(), row.arg)
    except AttributeError as error:
        fields = "; ".join(
            f"src.{part}: {', '.join(names)}" for part, names in source_fields().items()
        )
        raise ValueError(
            f"input {row.name}: its reader failed ({error}); a reader may read {fields}"
        ) from None
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"input {row.name}: its reader must return a number, got {value!r}")


def register_input(row: ControllerInput) -> None:
    """Make ``row`` an input a run may name in ``evolution.inputs`` in this process (a
    registered input joins no run unless named).

    Raises:
        ValueError: an input of that name exists, or its reader reads a field that does not
            exist (the message lists the fields it may read).
    """
    if not isinstance(row, ControllerInput):
        raise ValueError(f"row must be a ControllerInput, got {type(row).__name__}")
    if row.name in {r.name for r in available_inputs()} or row.name == PAPER:
        raise ValueError(f"an input named {row.name!r} exists")
    probe_reader(row)
    _REGISTERED.append(row)


def unregister_input(name: str) -> None:
    """Remove the registered input ``name`` (the declared ones stay).

    Raises:
        ValueError: no input of that name was registered.
    """
    for row in _REGISTERED:
        if row.name == name:
            _REGISTERED.remove(row)
            return
    raise ValueError(f"no registered input named {name!r}")


# --- the table in words --------------------------------------------------------------------------
def normalisation_text(row: ControllerInput, numbers: Mapping[str, str]) -> str:
    """``row.normalisation`` with each ``{name}`` replaced by ``numbers[name]`` (kept if absent)."""
    return re.sub(
        r"\{(\w+)\}", lambda m: numbers.get(m.group(1), m.group(1)), row.normalisation
    )


def markdown_table(rows: tuple[ControllerInput, ...] = INPUTS) -> str:
    """The inputs as the Markdown table of ``docs/design.md`` §5."""
    lines = [
        "| idx | input | meaning | reads | normalisation | range |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for index, row in enumerate(rows):
        span = f"{row.low:g}" if row.low == row.high else f"[{row.low:g}, {row.high:g}]"
        text = normalisation_text(row, {})
        lines.append(
            f"| {index} | `{row.name}` | {row.description} | `{row.reads}` | {text} | {span} |"
        )
    return "\n".join(lines) + "\n"


def row_record(row: ControllerInput, index: int, numbers: Mapping[str, str]) -> dict[str, Any]:
    """One input as plain data (the deployment bundle's ``controller.inputs`` entry)."""
    record = dataclasses.asdict(row)
    del record["read"]
    record.update(index=index, value=normalisation_text(row, numbers))
    return record


__all__ = [
    "EXTRA_INPUTS",
    "INPUTS",
    "INPUT_NAMES",
    "PAPER",
    "IN_BATTERY_DISTANCE",
    "IN_BIAS",
    "IN_ENERGY",
    "IN_FACE_DISTANCE",
    "IN_LED_DISTANCE",
    "IN_LED_PREVIOUS",
    "IN_PROXIMITY_START",
    "N_INPUTS",
    "N_PAPER_INPUTS",
    "N_PROXIMITY",
    "PAPER_INPUTS",
    "ControllerInput",
    "ControllerRules",
    "InputSources",
    "Reader",
    "RobotState",
    "battery_distance",
    "bias",
    "energy",
    "face_distance",
    "Fill",
    "compiled_reader",
    "extend_fill",
    "fill_inputs",
    "fill_inputs_reference",
    "fill_nothing",
    "fill_nothing_reference",
    "fill_rows_reference",
    "available_inputs",
    "input_names_allowed",
    "probe_reader",
    "probe_sources",
    "select_inputs",
    "source_fields",
    "steps_since_mating",
    "steps_since_recharge",
    "wheel",
    "led_distance",
    "led_previous",
    "markdown_table",
    "normalisation_text",
    "proximity",
    "register_input",
    "row_record",
    "unregister_input",
]
