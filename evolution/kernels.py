"""The evolution's per-step rules: each as a compiled kernel and its numpy reference.

* :func:`decide` / :func:`decide_reference`: every robot's evolved controller (paper §3.5,
  ``docs/design.md`` §5): the 12 inputs, the selection part's three activations, the available
  behaviour with the largest one, the LED rule and the recharge decision;
* :func:`steer` / :func:`steer_reference`: the chosen commands to wheel speeds, the LED (dark
  while a robot keeps recharging) and the Mate signal;
* :func:`sense_decide_act` / :func:`sense_decide_act_reference`: the first half of every
  control step in one call: the geometric vision's nearest targets
  (:mod:`cyber_rodent.vision.kernels`), the input mapping and the greedy behaviours
  (:mod:`behaviours.kernels`), :func:`decide` and :func:`steer`, in that order;
* :func:`tick` / :func:`tick_reference`: the time-sharing scheduler's per-step bookkeeping
  (ageing, time slices, energy, captures) and whether anything may end a slot this step.

Each pair has the same signature. :func:`tick` and its reference are bit-identical. The
weighted sums of :func:`decide` add their terms in input order while numpy's ``matmul`` may
round the last bit differently, so activations agree to rounding and decisions agree except on
exact near-ties (``tests/test_kernel_parity.py``; runs use one backend throughout, so each is
reproducible on its own).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from behaviours.inputs import FORAGE, MATE, SEARCH
from behaviours.kernels import (
    OK,
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
from cyber_rodent.backend import jit, jit_inline
from cyber_rodent.vision.kernels import (
    GeometricScene,
    NearestTargets,
    nearest,
    nearest_reference,
)
from evolution.genome import RECHARGE, SELECTION

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Bools = npt.NDArray[np.bool_]

#: Genome layout (:mod:`evolution.genome`): the recharge part's three weights, then the
#: selection part's 12 x 3 (output-major: the 12 weights into Mate, then Forage, then Search).
RECHARGE_START: int = RECHARGE.start
SELECTION_START: int = SELECTION.start
#: Input indices of the selection part (paper §3.5's enumeration).
IN_ENERGY = 0
IN_PROXIMITY_START = 1  #: the six proximities occupy 1..6
N_PROXIMITY = 6
IN_FACE_DISTANCE = 7
IN_LED_DISTANCE = 8
IN_BATTERY_DISTANCE = 9
IN_BIAS = 10
IN_LED_PREVIOUS = 11
N_INPUTS = 12
N_OUTPUTS = 3
assert (MATE, FORAGE, SEARCH) == (0, 1, 2)


class ControllerRules(NamedTuple):
    """The controller's normalisations and the class columns of the distances it reads."""

    max_energy: float  #: energy input = energy / max_energy (paper: 200)
    max_recharge_steps: float  #: recharge-step input = steps / max_recharge_steps (paper: 40)
    led: int  #: columns of the perceived normalised distances
    face: int
    battery: int


class RobotState(NamedTuple):
    """What the controller reads from the robots themselves (views of the survival world)."""

    energy: Floats  #: (n,) the active agent's energy
    recharge_steps: Ints  #: (n,) consecutive steps recharged so far
    led_on: Bools  #: (n,) the LED as lit during the previous step


class ControllerBuffers(NamedTuple):
    """The controller's weights (the active agents' genomes) and everything it writes."""

    weights: Floats  #: (n, 39) the active agents' genomes (a view of the scheduler's)
    inputs: Floats  #: (n, 12) out: the selection part's inputs (bias column 1)
    activations: Floats  #: (n, 3) out: Mate, Forage, Search
    behaviour: Ints  #: (n,) out: the chosen behaviour
    led: Bools  #: (n,) out: LED on (activation Mate > activation Forage)
    continue_recharge: Bools  #: (n,) out: the recharge decision (True = keep recharging)


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


class StepOutcome(NamedTuple):
    """What happened to each robot's active agent in the step (the world's event arrays)."""

    energy: Floats  #: (n,) energy after the step
    died: Bools  #: (n,)
    captured: Bools  #: (n,) docked onto a pack
    mated_with: Ints  #: (n,) partner robot or -1


class ScheduleRules(NamedTuple):
    """The time-sharing limits (paper Table 1)."""

    time_sharing_steps: int
    lifetime_steps: int


# --- controller --------------------------------------------------------------------------------
@jit_inline
def decide(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, out: ControllerBuffers
) -> None:
    """Fill the controller's buffers for every robot (see :mod:`evolution.controller`)."""
    n = out.weights.shape[0]
    availability = perceived.behaviour
    for i in range(n):
        x = out.inputs[i]
        x[IN_ENERGY] = robots.energy[i] / rules.max_energy
        for k in range(N_PROXIMITY):
            x[IN_PROXIMITY_START + k] = perceived.proximity[i, k]
        x[IN_FACE_DISTANCE] = perceived.norm_distance[i, rules.face]
        x[IN_LED_DISTANCE] = perceived.norm_distance[i, rules.led]
        x[IN_BATTERY_DISTANCE] = perceived.norm_distance[i, rules.battery]
        x[IN_BIAS] = 1.0
        x[IN_LED_PREVIOUS] = 1.0 if robots.led_on[i] else 0.0
        w = out.weights[i]
        for o in range(N_OUTPUTS):
            base = SELECTION_START + o * N_INPUTS
            total = w[base] * x[0]
            for k in range(1, N_INPUTS):
                total += w[base + k] * x[k]
            out.activations[i, o] = total
        a_mate = out.activations[i, MATE]
        a_forage = out.activations[i, FORAGE]
        # The available behaviour with the largest activation; ties to the lower index.
        best, best_value = SEARCH, out.activations[i, SEARCH]
        if availability.forage_available[i] and a_forage >= best_value:
            best, best_value = FORAGE, a_forage
        if availability.mate_available[i] and a_mate >= best_value:
            best = MATE
        out.behaviour[i] = best
        out.led[i] = a_mate > a_forage
        r = RECHARGE_START
        value = robots.energy[i] / rules.max_energy
        value *= w[r]
        value += w[r + 1] * (robots.recharge_steps[i] / rules.max_recharge_steps)
        value += w[r + 2]
        out.continue_recharge[i] = value <= 0.0


def decide_reference(
    rules: ControllerRules, robots: RobotState, perceived: InputBuffers, out: ControllerBuffers
) -> None:
    """:func:`decide` in numpy."""
    n = out.weights.shape[0]
    x = out.inputs
    np.divide(robots.energy, rules.max_energy, out=x[:, IN_ENERGY])
    x[:, IN_PROXIMITY_START : IN_PROXIMITY_START + N_PROXIMITY] = perceived.proximity
    x[:, IN_FACE_DISTANCE] = perceived.norm_distance[:, rules.face]
    x[:, IN_LED_DISTANCE] = perceived.norm_distance[:, rules.led]
    x[:, IN_BATTERY_DISTANCE] = perceived.norm_distance[:, rules.battery]
    x[:, IN_BIAS] = 1.0
    x[:, IN_LED_PREVIOUS] = robots.led_on
    selection = out.weights[:, SELECTION_START : SELECTION_START + N_INPUTS * N_OUTPUTS]
    out.activations[...] = np.matmul(selection.reshape(n, N_OUTPUTS, N_INPUTS), x[:, :, None])[
        :, :, 0
    ]
    masked = out.activations.copy()
    masked[~perceived.behaviour.mate_available, MATE] = -np.inf
    masked[~perceived.behaviour.forage_available, FORAGE] = -np.inf
    out.behaviour[...] = np.argmax(masked, axis=1)
    np.greater(out.activations[:, MATE], out.activations[:, FORAGE], out=out.led)
    w = out.weights[:, RECHARGE_START : RECHARGE_START + 3]
    value = robots.energy / rules.max_energy
    value *= w[:, 0]
    value += w[:, 1] * (robots.recharge_steps.astype(float) / rules.max_recharge_steps)
    value += w[:, 2]
    np.less_equal(value, 0.0, out=out.continue_recharge)


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


# --- one fused call ----------------------------------------------------------------------------
@jit
def sense_decide_act(scene: GeometricScene, perceive: Perceive, decided: Decide, act: Act) -> int:
    """Sense, decide and act for every robot; returns the greedy behaviours' status.

    Returns:
        ``behaviours.kernels.OK``, or its error code (then ``act.out`` is incomplete; the
        caller raises the error it names).
    """
    nearest(scene, perceive.nearest)
    map_inputs(perceive.sensors, perceive.nearest, perceive.rules, perceive.out)
    decide(decided.rules, decided.robots, perceive.out, decided.out)
    status = greedy_commands(
        decided.out.behaviour, perceive.out.behaviour, act.tables, act.out.commands
    )
    if status != OK:
        return status
    steer(decided.out, act.docked, act.command_speeds, act.out)
    return status


def sense_decide_act_reference(
    scene: GeometricScene, perceive: Perceive, decided: Decide, act: Act
) -> int:
    """:func:`sense_decide_act` with the numpy references, in the same order."""
    nearest_reference(scene, perceive.nearest)
    map_inputs_reference(perceive.sensors, perceive.nearest, perceive.rules, perceive.out)
    decide_reference(decided.rules, decided.robots, perceive.out, decided.out)
    status = greedy_commands_reference(
        decided.out.behaviour, perceive.out.behaviour, act.tables, act.out.commands
    )
    if status != OK:
        return status
    steer_reference(decided.out, act.docked, act.command_speeds, act.out)
    return status


@jit
def sense_decide_learn(
    scene: GeometricScene, perceive: Perceive, decided: Decide, act: LearnAct
) -> int:
    """:func:`sense_decide_act` in learning mode: the agents' own learners act (and learn)
    in place of the fixed greedy behaviours (:func:`behaviours.kernels.learn_commands`)."""
    nearest(scene, perceive.nearest)
    map_inputs(perceive.sensors, perceive.nearest, perceive.rules, perceive.out)
    decide(decided.rules, decided.robots, perceive.out, decided.out)
    status = learn_commands(
        decided.out.behaviour, perceive.out.behaviour, act.tables, act.values, act.episodes,
        act.step, act.out.commands,
    )  # fmt: skip
    if status != OK:
        return status
    steer(decided.out, act.docked, act.command_speeds, act.out)
    return status


def sense_decide_learn_reference(
    scene: GeometricScene, perceive: Perceive, decided: Decide, act: LearnAct
) -> int:
    """:func:`sense_decide_learn` with the numpy references, in the same order."""
    nearest_reference(scene, perceive.nearest)
    map_inputs_reference(perceive.sensors, perceive.nearest, perceive.rules, perceive.out)
    decide_reference(decided.rules, decided.robots, perceive.out, decided.out)
    status = learn_commands_reference(
        decided.out.behaviour, perceive.out.behaviour, act.tables, act.values, act.episodes,
        act.step, act.out.commands,
    )  # fmt: skip
    if status != OK:
        return status
    steer_reference(decided.out, act.docked, act.command_speeds, act.out)
    return status


# --- scheduler ---------------------------------------------------------------------------------
@jit
def tick(counters: SlotCounters, outcome: StepOutcome, rules: ScheduleRules) -> bool:
    """One step of bookkeeping; True if a slot may end this step (the slow path must run).

    For active robots: age and slice +1, energy copied, a capture counted. ``switched`` is
    cleared.
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
    return bool(
        outcome.mated_with.max() >= 0
        or outcome.died.any()
        or counters.time_slice.max() >= rules.time_sharing_steps
        or counters.age.max() >= rules.lifetime_steps
    )


__all__ = [
    "Act",
    "ActionBuffers",
    "LearnAct",
    "sense_decide_learn",
    "sense_decide_learn_reference",
    "Decide",
    "Perceive",
    "sense_decide_act",
    "sense_decide_act_reference",
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
