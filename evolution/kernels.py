"""The evolution's per-step rules: each as a compiled kernel and its numpy reference.

* :func:`decide` / :func:`decide_reference`: every robot's evolved controller of the paper
  (§3.5, ``docs/design.md`` §5): its inputs (:func:`evolution.input_kernels.fill_inputs`), then
  :func:`decide_paper`: the selection part's three activations, the available behaviour with
  the largest one and the LED rule (:func:`choose`), and the recharge decision
  (:func:`recharge_decision`); :func:`choose` and :func:`recharge_decision` are shared by every
  controller that keeps the paper's output rules (:mod:`evolution.controllers`);
* :func:`steer` / :func:`steer_reference`: the chosen commands to wheel speeds, the LED (dark
  while a robot keeps recharging) and the Mate signal;
* :func:`sense_decide_act` / :func:`sense_decide_act_reference`: the first half of every
  control step in one call: the geometric vision's nearest targets
  (:mod:`cyber_rodent.vision.kernels`), the input mapping and the greedy behaviours
  (:mod:`behaviours.kernels`), :func:`decide` and :func:`steer`, in that order;
* :data:`PAPER_STEP`: the paper's deciding stage and fused calls (learning mode's too), each
  beside its reference (:class:`StepKernels`), compiled once per installation;
  :func:`build_step_kernels` builds the same functions, their code unchanged, around any other
  controller's kernel and input table, in-process;
* :func:`tick` / :func:`tick_reference`: the time-sharing scheduler's per-step bookkeeping
  (ageing, time slices, energy, captures) and whether anything may end a slot this step.

Each pair has the same signature. :func:`tick` and its reference are bit-identical. The
weighted sums of :func:`decide` add their terms in input order while numpy's ``matmul`` may
round the last bit differently, so activations agree to rounding and decisions agree except on
exact near-ties (``tests/test_kernel_parity.py``; runs use one backend throughout, so each is
reproducible on its own).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from behaviours.inputs import FORAGE, MATE, SEARCH
from behaviours.kernels import (
    OK,
    BehaviourInputs,
    GreedyTables,
    InputBuffers,
    InputRules,
    LearnedValues,
    LearningEpisodes,
    LearningStep,
    RangeSensors,
    greedy_commands,
    greedy_commands_reference,
    learn_commands,
    learn_commands_reference,
    map_inputs,
    map_inputs_reference,
)
from cyber_rodent.backend import jit, jit_built, jit_inline, with_callees
from cyber_rodent.vision.kernels import (
    GeometricScene,
    NearestTargets,
    nearest,
    nearest_reference,
)
from evolution.input_kernels import (
    IN_BATTERY_DISTANCE,
    IN_BIAS,
    IN_ENERGY,
    IN_FACE_DISTANCE,
    IN_LED_DISTANCE,
    IN_LED_PREVIOUS,
    IN_PROXIMITY_START,
    N_PAPER_INPUTS,
    N_PROXIMITY,
    ControllerRules,
    RobotState,
    fill_inputs,
    fill_inputs_reference,
)

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Bools = npt.NDArray[np.bool_]

#: The paper's genome layout (:mod:`evolution.genome`): the recharge part's three weights, then
#: the selection part's 3 x inputs (output-major: the weights into Mate, then Forage, then
#: Search, each in input order).
RECHARGE_START = 0
N_RECHARGE = 3
SELECTION_START = RECHARGE_START + N_RECHARGE
#: The paper's inputs (:data:`evolution.input_kernels.INPUTS`; a table may have more).
N_INPUTS = N_PAPER_INPUTS
N_OUTPUTS = 3
assert (MATE, FORAGE, SEARCH) == (0, 1, 2)


class ControllerBuffers(NamedTuple):
    """The controller's weights (the active agents' genomes) and everything it writes."""

    weights: Floats  #: (n, genes) the active agents' controller genes (the scheduler's view)
    inputs: Floats  #: (n, inputs) out: the inputs, one column per row of the input table
    activations: Floats  #: (n, 3) out: Mate, Forage, Search
    behaviour: Ints  #: (n,) out: the chosen behaviour
    led: Bools  #: (n,) out: LED on (activation Mate > activation Forage)
    continue_recharge: Bools  #: (n,) out: the recharge decision (True = keep recharging)
    #: (n, S) in/out: the active agents' own controller state (S = the controller's
    #: ``state_size``, 0 for a stateless one). It belongs to the agent: the scheduler saves it
    #: when a robot switches its agent out and restores it when the agent comes back; a newborn
    #: starts from zeros (:mod:`evolution.controllers`).
    state: Floats


class ActionBuffers(NamedTuple):
    """What every robot does in the step: the world's inputs."""

    commands: Ints  #: (n,) wheel-command index (``cyber_rodent.commands.WHEEL_COMMANDS``)
    wheels: Floats  #: (n, 2) left, right wheel rim speeds, m/s
    led: Bools  #: (n,) green LED on
    mate: Bools  #: (n,) signals Mate (the IR exchange needs both partners to)


class Perceive(NamedTuple):
    """The sensing stage's buffers: range sensors and nearest targets to inputs."""

    sensors: RangeSensors
    nearest: NearestTargets
    rules: InputRules
    out: InputBuffers


class Decide(NamedTuple):
    """The deciding stage's buffers: the evolved controllers."""

    rules: ControllerRules
    robots: RobotState
    out: ControllerBuffers


class Act(NamedTuple):
    """The acting stage's buffers: behaviours to wheel speeds, LED and Mate signal."""

    tables: GreedyTables  #: the three greedy behaviours
    docked: Bools  #: (n,) the robot recharges (its LED stays dark if it continues)
    command_speeds: Floats  #: (n_commands, 2) wheel speeds of each command, m/s
    out: ActionBuffers


class LearnAct(NamedTuple):
    """Learning mode's acting stage: each agent's own learned behaviours (learning as they
    act) to wheel speeds, LED and Mate signal."""

    tables: GreedyTables  #: the behaviours' tile coders (their values are not read)
    values: LearnedValues  #: every agent's learned values and learning parameters
    episodes: LearningEpisodes  #: each robot's open learning episode
    step: LearningStep  #: the step's tables, acting flags and exploration draws
    docked: Bools  #: (n,) the robot recharges (its LED stays dark if it continues)
    command_speeds: Floats  #: (n_commands, 2) wheel speeds of each command, m/s
    out: ActionBuffers


class SlotCounters(NamedTuple):
    """The scheduler's per-robot counters of the active agents."""

    active: Bools  #: (n,) the robot runs an agent
    age: Ints  #: (n,) control steps lived
    time_slice: Ints  #: (n,) steps in the current time-sharing slot
    energy: Floats  #: (n,) the active agent's energy
    batteries: Ints  #: (n,) captures in its life
    switched: Bools  #: (n,) out: cleared here; the slow path sets it
    since_recharge: Ints  #: (n,) steps since the active agent last recharged (0 while docked)
    since_mating: Ints  #: (n,) steps since the active agent last mated (0 in the mating step)


class StepOutcome(NamedTuple):
    """What happened to each robot's active agent in the step (the world's event arrays)."""

    energy: Floats  #: (n,) energy after the step
    died: Bools  #: (n,)
    captured: Bools  #: (n,) docked onto a pack
    mated_with: Ints  #: (n,) partner robot or -1
    recharging: Bools  #: (n,) docked (recharging) after the step


class ScheduleRules(NamedTuple):
    """The time-sharing limits (paper Table 1)."""

    time_sharing_steps: int
    lifetime_steps: int


# --- controller --------------------------------------------------------------------------------
@jit_inline
def choose(i: int, availability: BehaviourInputs, out: ControllerBuffers) -> None:
    """Robot ``i``'s behaviour and LED from its three activations: the available behaviour with
    the largest activation, ties to the lower index; the LED on iff activation(Mate) >
    activation(Forage), available or not."""
    a_mate = out.activations[i, MATE]
    a_forage = out.activations[i, FORAGE]
    best, best_value = SEARCH, out.activations[i, SEARCH]
    if availability.forage_available[i] and a_forage >= best_value:
        best, best_value = FORAGE, a_forage
    if availability.mate_available[i] and a_mate >= best_value:
        best = MATE
    out.behaviour[i] = best
    out.led[i] = a_mate > a_forage


def choose_reference(availability: BehaviourInputs, out: ControllerBuffers) -> None:
    """:func:`choose` for every robot, in numpy."""
    masked = out.activations.copy()
    masked[~availability.mate_available, MATE] = -np.inf
    masked[~availability.forage_available, FORAGE] = -np.inf
    out.behaviour[...] = np.argmax(masked, axis=1)
    np.greater(out.activations[:, MATE], out.activations[:, FORAGE], out=out.led)


@jit_inline
def recharge_decision(
    i: int, rules: ControllerRules, robots: RobotState, w: Floats, start: int
) -> bool:
    """The paper's recharge part for robot ``i`` with the three weights at ``w[start:]``:
    ``w0 energy / max_energy + w1 steps / max_recharge_steps + w2 <= 0`` continues."""
    value = robots.energy[i] / rules.max_energy
    value *= w[start]
    value += w[start + 1] * (robots.recharge_steps[i] / rules.max_recharge_steps)
    value += w[start + 2]
    return bool(value <= 0.0)


def recharge_decision_reference(
    rules: ControllerRules, robots: RobotState, weights: Floats, start: int, out: Bools
) -> None:
    """:func:`recharge_decision` for every robot, in numpy, into ``out``."""
    w = weights[:, start : start + N_RECHARGE]
    value = robots.energy / rules.max_energy
    value *= w[:, 0]
    value += w[:, 1] * (robots.recharge_steps.astype(float) / rules.max_recharge_steps)
    value += w[:, 2]
    np.less_equal(value, 0.0, out=out)


@jit_inline
def decide_paper(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, out: ControllerBuffers
) -> None:
    """The paper's one-layer controller on the filled inputs (see :mod:`evolution.controller`)."""
    n, n_inputs = out.inputs.shape
    availability = perceived.behaviour
    for i in range(n):
        x = out.inputs[i]
        w = out.weights[i]
        for o in range(N_OUTPUTS):
            base = SELECTION_START + o * n_inputs
            total = w[base] * x[0]
            for k in range(1, n_inputs):
                total += w[base + k] * x[k]
            out.activations[i, o] = total
        choose(i, availability, out)
        out.continue_recharge[i] = recharge_decision(i, rules, robots, w, RECHARGE_START)


def decide_paper_reference(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, out: ControllerBuffers
) -> None:
    """:func:`decide_paper` in numpy."""
    n, n_inputs = out.inputs.shape
    stop = SELECTION_START + n_inputs * N_OUTPUTS
    selection = out.weights[:, SELECTION_START:stop].reshape(n, N_OUTPUTS, n_inputs)
    out.activations[...] = np.matmul(selection, out.inputs[:, :, None])[:, :, 0]
    choose_reference(perceived.behaviour, out)
    recharge_decision_reference(
        rules, robots, out.weights, RECHARGE_START, out.continue_recharge
    )


@jit_inline
def decide(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, out: ControllerBuffers
) -> None:
    """Fill the controller's buffers for every robot: the paper's inputs
    (:func:`~evolution.input_kernels.fill_inputs`), then :func:`decide_paper`."""
    fill_inputs(rules, robots, perceived, out.inputs)
    decide_paper(rules, robots, perceived, out)


#: :func:`decide` in numpy: its own code over the references of the rules it calls.
decide_reference = with_callees(
    decide, fill_inputs=fill_inputs_reference, decide_paper=decide_paper_reference
)


# --- acting ------------------------------------------------------------------------------------
@jit_inline
def steer(
    decided: ControllerBuffers, docked: Bools, command_speeds: Floats, out: ActionBuffers
) -> None:
    """Wheel speeds of the chosen commands, the LED and the Mate signal of every robot.

    A robot that keeps recharging runs no behaviour: its LED is dark (``docs/design.md`` §9).
    """
    for i in range(out.commands.shape[0]):
        out.led[i] = decided.led[i] and not (docked[i] and decided.continue_recharge[i])
        out.wheels[i, 0] = command_speeds[out.commands[i], 0]
        out.wheels[i, 1] = command_speeds[out.commands[i], 1]
        out.mate[i] = decided.behaviour[i] == MATE


def steer_reference(
    decided: ControllerBuffers, docked: Bools, command_speeds: Floats, out: ActionBuffers
) -> None:
    """:func:`steer` in numpy."""
    holding = np.logical_not(docked & decided.continue_recharge)
    np.logical_and(decided.led, holding, out=out.led)
    np.take(command_speeds, out.commands, axis=0, out=out.wheels)
    np.equal(decided.behaviour, MATE, out=out.mate)


# --- the fused calls ---------------------------------------------------------------------------
@jit_inline
def sense_decide(scene: GeometricScene, perceive: Perceive, decided: Decide) -> None:
    """The fused calls' first half for every robot: the nearest targets, the inputs, then the
    controller (:func:`decide`)."""
    nearest(scene, perceive.nearest)
    map_inputs(perceive.sensors, perceive.nearest, perceive.rules, perceive.out)
    decide(decided.rules, decided.robots, perceive.out, decided.out)


#: :func:`sense_decide` in numpy: its own code over the references of the rules it calls.
sense_decide_reference = with_callees(
    sense_decide, nearest=nearest_reference, map_inputs=map_inputs_reference,
    decide=decide_reference,
)  # fmt: skip


@jit
def sense_decide_act(scene: GeometricScene, perceive: Perceive, decided: Decide, act: Act) -> int:
    """Sense, decide and act for every robot; returns the greedy behaviours' status.

    Returns:
        ``behaviours.kernels.OK``, or its error code (then ``act.out`` is incomplete; the
        caller raises the error it names).
    """
    sense_decide(scene, perceive, decided)
    status = greedy_commands(
        decided.out.behaviour, perceive.out.behaviour, act.tables, act.out.commands
    )
    if status == OK:
        steer(decided.out, act.docked, act.command_speeds, act.out)
    return status


@jit
def sense_decide_learn(
    scene: GeometricScene, perceive: Perceive, decided: Decide, act: LearnAct
) -> int:
    """:func:`sense_decide_act` in learning mode: the agents' own learners act (and learn)
    in place of the fixed greedy behaviours (:func:`behaviours.kernels.learn_commands`)."""
    sense_decide(scene, perceive, decided)
    status = learn_commands(
        decided.out.behaviour, perceive.out.behaviour, act.tables, act.values, act.episodes,
        act.step, act.out.commands,
    )  # fmt: skip
    if status == OK:
        steer(decided.out, act.docked, act.command_speeds, act.out)
    return status


#: The fused calls in numpy: each one's own code over the references of the rules it calls, so
#: they call them in the same order.
sense_decide_act_reference = with_callees(
    sense_decide_act, sense_decide=sense_decide_reference,
    greedy_commands=greedy_commands_reference, steer=steer_reference,
)  # fmt: skip
sense_decide_learn_reference = with_callees(
    sense_decide_learn, sense_decide=sense_decide_reference,
    learn_commands=learn_commands_reference, steer=steer_reference,
)  # fmt: skip


# --- the fused calls of any controller -------------------------------------------------------
ControllerKernel = Callable[[ControllerRules, RobotState, InputBuffers, ControllerBuffers], None]
FillKernel = Callable[[ControllerRules, RobotState, InputBuffers, Floats], None]


class StepKernels(NamedTuple):
    """One controller's kernels with one input table, each beside its reference.

    Attributes:
        controller: fill the inputs, then decide: ``(rules, robots, perceived, out)`` (the
            step-by-step path's deciding stage).
        act: the fused sense → decide → act call (signature of :func:`sense_decide_act`).
        learn: learning mode's fused call (signature of :func:`sense_decide_learn`).
    """

    controller: ControllerKernel
    controller_reference: ControllerKernel
    act: Callable[[GeometricScene, Perceive, Decide, Act], int]
    act_reference: Callable[[GeometricScene, Perceive, Decide, Act], int]
    learn: Callable[[GeometricScene, Perceive, Decide, LearnAct], int]
    learn_reference: Callable[[GeometricScene, Perceive, Decide, LearnAct], int]


#: The paper's controller with the paper's inputs: this module's kernels, compiled once per
#: installation and cached on disk.
PAPER_STEP = StepKernels(
    decide, decide_reference, sense_decide_act, sense_decide_act_reference, sense_decide_learn,
    sense_decide_learn_reference,
)  # fmt: skip


def build_step_kernels(
    fill: FillKernel,
    fill_reference: FillKernel,
    decide_rule: ControllerKernel,
    decide_rule_reference: ControllerKernel,
) -> StepKernels:
    """:data:`PAPER_STEP` for another controller (``decide_rule``: it reads the filled inputs)
    or input table (``fill``), built in this process.

    One source serves the paper's controller and every other: the kernels are this module's
    own, their code unchanged, rebuilt around other callees
    (:func:`cyber_rodent.backend.with_callees`): :func:`decide` with ``fill`` and
    ``decide_rule`` in place of the paper's ``fill_inputs`` and ``decide_paper``,
    :func:`sense_decide` around that :func:`decide`, and :func:`sense_decide_act` and
    :func:`sense_decide_learn` around that :func:`sense_decide` (the references likewise, around
    the given references). They are compiled on first use and not cached on disk
    (:func:`cyber_rodent.backend.jit_built`). Build them once per controller and table
    (:func:`evolution.controllers.step_kernels`).
    """
    controller = jit_built(
        with_callees(decide, fill_inputs=fill, decide_paper=decide_rule), inline=True
    )
    reference = with_callees(decide, fill_inputs=fill_reference, decide_paper=decide_rule_reference)
    sensed = jit_built(with_callees(sense_decide, decide=controller), inline=True)
    sensed_reference = with_callees(sense_decide_reference, decide=reference)
    return StepKernels(
        controller,
        reference,
        jit_built(with_callees(sense_decide_act, sense_decide=sensed)),
        with_callees(sense_decide_act_reference, sense_decide=sensed_reference),
        jit_built(with_callees(sense_decide_learn, sense_decide=sensed)),
        with_callees(sense_decide_learn_reference, sense_decide=sensed_reference),
    )


# --- scheduler ---------------------------------------------------------------------------------
@jit
def tick(counters: SlotCounters, outcome: StepOutcome, rules: ScheduleRules) -> bool:
    """One step of bookkeeping; True if a slot may end this step (the slow path must run).

    For active robots: age and slice +1, energy copied, a capture counted, the steps since the
    last recharge (0 while docked) and since the last mating (0 in its step) counted. ``switched``
    is cleared.
    """
    something = False
    for i in range(counters.active.shape[0]):
        counters.switched[i] = False
        if counters.active[i]:
            counters.age[i] += 1
            counters.time_slice[i] += 1
            counters.energy[i] = outcome.energy[i]
            if outcome.captured[i]:
                counters.batteries[i] += 1
            if outcome.recharging[i]:
                counters.since_recharge[i] = 0
            else:
                counters.since_recharge[i] += 1
            if outcome.mated_with[i] >= 0:
                counters.since_mating[i] = 0
            else:
                counters.since_mating[i] += 1
        if (
            outcome.mated_with[i] >= 0
            or outcome.died[i]
            or counters.time_slice[i] >= rules.time_sharing_steps
            or counters.age[i] >= rules.lifetime_steps
        ):
            something = True
    return something


def tick_reference(counters: SlotCounters, outcome: StepOutcome, rules: ScheduleRules) -> bool:
    """:func:`tick` in numpy."""
    active = counters.active
    counters.switched[:] = False
    counters.age[...] += active
    counters.time_slice[...] += active
    np.copyto(counters.energy, outcome.energy, where=active)
    counters.batteries[...] += outcome.captured & active
    counters.since_recharge[...] += active
    counters.since_recharge[active & outcome.recharging] = 0
    counters.since_mating[...] += active
    counters.since_mating[active & (outcome.mated_with >= 0)] = 0
    return bool(
        outcome.mated_with.max() >= 0
        or outcome.died.any()
        or counters.time_slice.max() >= rules.time_sharing_steps
        or counters.age.max() >= rules.lifetime_steps
    )


__all__ = [
    "N_RECHARGE",
    "PAPER_STEP",
    "Act",
    "ActionBuffers",
    "ControllerKernel",
    "FillKernel",
    "StepKernels",
    "build_step_kernels",
    "choose",
    "choose_reference",
    "decide_paper",
    "decide_paper_reference",
    "recharge_decision",
    "recharge_decision_reference",
    "LearnAct",
    "sense_decide_learn",
    "sense_decide_learn_reference",
    "Decide",
    "Perceive",
    "sense_decide",
    "sense_decide_act",
    "sense_decide_act_reference",
    "sense_decide_reference",
    "steer",
    "steer_reference",
    "IN_BATTERY_DISTANCE",
    "IN_BIAS",
    "IN_ENERGY",
    "IN_FACE_DISTANCE",
    "IN_LED_DISTANCE",
    "IN_LED_PREVIOUS",
    "IN_PROXIMITY_START",
    "N_INPUTS",
    "N_OUTPUTS",
    "N_PROXIMITY",
    "RECHARGE_START",
    "SELECTION_START",
    "ControllerBuffers",
    "ControllerRules",
    "RobotState",
    "ScheduleRules",
    "SlotCounters",
    "StepOutcome",
    "decide",
    "decide_reference",
    "tick",
    "tick_reference",
]
