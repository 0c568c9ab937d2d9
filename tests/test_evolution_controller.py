"""The 39-weight controller: hand-computed outputs, the LED rule, availability, recharge.

Every hand-computed case runs on both backends: the compiled kernel and its numpy reference.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import pytest

from behaviours.kernels import BehaviourInputs, InputBuffers
from cyber_rodent.backend import Backend
from cyber_rodent.vision.types import BATTERY, FACE, LED
from evolution.config import GENOME_LENGTH
from evolution.controller import (
    FORAGE,
    IN_BATTERY_DISTANCE,
    IN_BIAS,
    IN_ENERGY,
    IN_FACE_DISTANCE,
    IN_LED_DISTANCE,
    IN_LED_PREVIOUS,
    IN_PROXIMITY,
    INPUT_NAMES,
    MATE,
    N_INPUTS,
    SEARCH,
    NeuralController,
)
from evolution.kernels import ControllerBuffers, RobotState

BACKENDS = pytest.mark.parametrize("backend", ["numba", "numpy"])


class Rig(NamedTuple):
    """A controller for n robots and the buffers it reads, which a test writes in place."""

    weights: np.ndarray
    robots: RobotState
    perceived: InputBuffers
    controller: NeuralController


def _rig(n: int, backend: Backend, **controller_args: Any) -> Rig:
    """n robots with zero weights, energy, proximities and steps, nothing in view, LEDs off."""
    weights = np.zeros((n, GENOME_LENGTH))
    robots = RobotState(
        energy=np.zeros(n),
        recharge_steps=np.zeros(n, dtype=np.int64),
        led_on=np.zeros(n, dtype=np.bool_),
    )
    perceived = InputBuffers(
        proximity=np.zeros((n, 6)),
        norm_bearing=np.full((n, 3), 0.5),
        norm_distance=np.ones((n, 3)),
        behaviour=BehaviourInputs(
            mate=np.zeros((n, 2)),
            forage=np.zeros((n, 2)),
            search=np.zeros((n, 2)),
            mate_available=np.zeros(n, dtype=np.bool_),
            forage_available=np.zeros(n, dtype=np.bool_),
        ),
    )
    controller = NeuralController(weights, robots, perceived, backend=backend, **controller_args)
    return Rig(weights, robots, perceived, controller)


def _decide(
    rig: Rig,
    weights: Any = None,
    *,
    energy: Any = None,
    proximity: Any = None,
    face: Any = None,
    led: Any = None,
    battery: Any = None,
    led_previous: Any = None,
    mate_available: Any = None,
    forage_available: Any = None,
    recharge_steps: Any = None,
) -> ControllerBuffers:
    """Write the given values (broadcast over robots) into the rig's buffers, then decide."""
    perceived, robots = rig.perceived, rig.robots
    writes = (
        (rig.weights, weights),
        (robots.energy, energy),
        (perceived.proximity, proximity),
        (perceived.norm_distance[:, FACE], face),
        (perceived.norm_distance[:, LED], led),
        (perceived.norm_distance[:, BATTERY], battery),
        (robots.led_on, led_previous),
        (perceived.behaviour.mate_available, mate_available),
        (perceived.behaviour.forage_available, forage_available),
        (robots.recharge_steps, recharge_steps),
    )
    for target, value in writes:
        if value is not None:
            target[...] = value
    rig.controller.decide()
    return rig.controller.buffers


#: One robot's perceived values: x = [0.5, 0.1 .. 0.6, 0.2, 0.3, 0.4, 1 (bias), 1 (LED on)].
PERCEIVED = {
    "energy": 100.0,
    "proximity": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
    "face": 0.2,
    "led": 0.3,
    "battery": 0.4,
    "led_previous": True,
}


def _weights(
    recharge: Any = (0.0, 0.0, 0.0), mate: Any = None, forage: Any = None, search: Any = None
) -> np.ndarray:
    """One genome row from its parts (each selection part 12 weights, input order)."""
    parts = [np.asarray(recharge, dtype=float)]
    for part in (mate, forage, search):
        parts.append(np.zeros(N_INPUTS) if part is None else np.asarray(part, dtype=float))
    row = np.concatenate(parts)
    assert row.shape == (GENOME_LENGTH,)
    return row


def _one_hot(index: int, value: float) -> np.ndarray:
    w = np.zeros(N_INPUTS)
    w[index] = value
    return w


def test_input_order_is_documented() -> None:
    assert INPUT_NAMES[IN_ENERGY] == "energy"
    assert INPUT_NAMES[IN_PROXIMITY] == (
        "proximity_front",
        "proximity_front_left30",
        "proximity_front_right30",
        "proximity_front_left60",
        "proximity_front_right60",
        "proximity_back",
    )
    assert INPUT_NAMES[IN_FACE_DISTANCE] == "face_distance"
    assert INPUT_NAMES[IN_LED_DISTANCE] == "led_distance"
    assert INPUT_NAMES[IN_BATTERY_DISTANCE] == "battery_distance"
    assert INPUT_NAMES[IN_BIAS] == "bias"
    assert INPUT_NAMES[IN_LED_PREVIOUS] == "led_previous"


@BACKENDS
def test_inputs_place_and_normalise_each_input(backend: Backend) -> None:
    rig = _rig(1, backend)
    x = _decide(rig, **PERCEIVED).inputs
    np.testing.assert_array_equal(
        x[0], [0.5, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.2, 0.3, 0.4, 1.0, 1.0]
    )
    x = _decide(rig, led_previous=False).inputs  # the LED previous input is 0 when it was off
    np.testing.assert_array_equal(
        x[0], [0.5, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.2, 0.3, 0.4, 1.0, 0.0]
    )


@BACKENDS
def test_activations_hand_computed(backend: Backend) -> None:
    # Mate: all weights 0.1 -> 0.1 * sum(x) = 0.1 * 5.5 = 0.55.
    # Forage: battery distance 2, bias -0.5 -> 0.8 - 0.5 = 0.3.
    # Search: energy -1, back proximity 3 -> -0.5 + 1.8 = 1.3.
    search = _one_hot(IN_ENERGY, -1.0) + _one_hot(6, 3.0)
    w = _weights(
        mate=np.full(N_INPUTS, 0.1),
        forage=_one_hot(IN_BATTERY_DISTANCE, 2.0) + _one_hot(IN_BIAS, -0.5),
        search=search,
    )
    out = _decide(_rig(1, backend), w, mate_available=True, forage_available=True, **PERCEIVED)
    np.testing.assert_allclose(out.activations[0], [0.55, 0.3, 1.3], rtol=0, atol=1e-12)
    assert out.behaviour[0] == SEARCH
    assert out.led[0]  # 0.55 > 0.3


@BACKENDS
@pytest.mark.parametrize(
    ("mate_ok", "forage_ok", "expected"),
    [
        (True, True, MATE),  # Mate 1.0 > Search 0.95 > Forage 0.9
        (False, True, SEARCH),  # Mate unavailable: Search 0.95 beats Forage 0.9
        (True, False, MATE),
        (False, False, SEARCH),
    ],
)
def test_only_available_behaviours_win(
    backend: Backend, mate_ok: bool, forage_ok: bool, expected: int
) -> None:
    w = _weights(
        mate=_one_hot(IN_ENERGY, 2.0),  # 2 * 0.5 = 1.0
        forage=_one_hot(IN_BIAS, 0.9),  # 0.9
        search=_one_hot(IN_LED_PREVIOUS, 0.95),  # 0.95
    )
    rig = _rig(1, backend)
    _decide(rig, w, mate_available=mate_ok, forage_available=forage_ok, **PERCEIVED)
    assert rig.controller.behaviour[0] == expected
    # The LED follows the raw activations (1.0 > 0.9), not availability.
    assert rig.controller.led[0]


@BACKENDS
def test_forage_wins_when_only_it_is_highest_and_available(backend: Backend) -> None:
    rig = _rig(1, backend)
    w = _weights(forage=_one_hot(IN_BIAS, 1.0))  # Mate 0, Forage 1, Search 0
    _decide(rig, w, mate_available=True, forage_available=True, **PERCEIVED)
    assert rig.controller.behaviour[0] == FORAGE and not rig.controller.led[0]
    _decide(rig, forage_available=False)
    assert rig.controller.behaviour[0] == MATE  # Mate and Search tie at 0: the lower index wins


@BACKENDS
def test_led_rule_strict_greater(backend: Backend) -> None:
    # Every input 0 but the bias (1).
    w = np.stack(
        [
            _weights(mate=_one_hot(IN_BIAS, 0.5), forage=_one_hot(IN_BIAS, 0.4)),  # on
            _weights(mate=_one_hot(IN_BIAS, 0.4), forage=_one_hot(IN_BIAS, 0.5)),  # off
            _weights(mate=_one_hot(IN_BIAS, 0.5), forage=_one_hot(IN_BIAS, 0.5)),  # tie: off
        ]
    )
    rig = _rig(3, backend)
    out = _decide(rig, w, face=0.0, led=0.0, battery=0.0)
    np.testing.assert_array_equal(out.inputs[:, IN_BIAS], 1.0)
    np.testing.assert_array_equal(np.delete(out.inputs, IN_BIAS, axis=1), 0.0)
    np.testing.assert_array_equal(rig.controller.led, [True, False, False])


@BACKENDS
def test_decide_matches_a_per_robot_reference(backend: Backend) -> None:
    rng = np.random.default_rng(11)
    n = 4
    rig = _rig(n, backend)
    for _ in range(2000):
        w = rng.uniform(-1, 1, (n, GENOME_LENGTH))
        energy = rng.uniform(0, 200, n)
        proximity = rng.uniform(0, 1, (n, 6))
        face, led_d, battery = rng.uniform(0, 1, (3, n))
        led_previous = rng.random(n) < 0.5
        mate_ok = rng.random(n) < 0.5
        forage_ok = rng.random(n) < 0.5
        out = _decide(
            rig,
            w,
            energy=energy,
            proximity=proximity,
            face=face,
            led=led_d,
            battery=battery,
            led_previous=led_previous,
            mate_available=mate_ok,
            forage_available=forage_ok,
        )
        x = np.column_stack(
            [energy / 200.0, proximity, face, led_d, battery, np.ones(n), led_previous]
        )
        np.testing.assert_array_equal(out.inputs, x)
        for r in range(n):
            act = w[r, 3:].reshape(3, N_INPUTS) @ x[r]
            np.testing.assert_allclose(out.activations[r], act, rtol=0, atol=1e-14)
            allowed = [mate_ok[r], forage_ok[r], True]
            best = max((a, -i) for i, a in enumerate(act) if allowed[i])
            assert out.behaviour[r] == -best[1]
            assert out.led[r] == (act[MATE] > act[FORAGE])
            assert allowed[out.behaviour[r]]  # an unavailable behaviour is never chosen


@BACKENDS
def test_recharge_decision_hand_computed(backend: Backend) -> None:
    rig = _rig(4, backend)
    w = np.stack([_weights(recharge=(2.0, 1.0, -1.5)) for _ in range(4)])
    energy = np.array([100.0, 150.0, 100.0, 200.0])
    steps = np.array([10, 10, 20, 40])
    # 2*0.5 + 1*0.25 - 1.5 = -0.25 -> continue
    # 2*0.75 + 1*0.25 - 1.5 = 0.25 -> stop
    # 2*0.5 + 1*0.5 - 1.5 = 0 -> continue (the paper: "less or equal to zero")
    # 2*1 + 1*1 - 1.5 = 1.5 -> stop
    _decide(rig, w, energy=energy, recharge_steps=steps)
    np.testing.assert_array_equal(rig.controller.continue_recharge, [True, False, True, False])


@BACKENDS
def test_bad_constructor_arguments(backend: Backend) -> None:
    with pytest.raises(ValueError, match="n_robots"):
        _rig(0, backend)
    with pytest.raises(ValueError, match="max_energy"):
        _rig(1, backend, max_energy=0.0)
    with pytest.raises(ValueError, match="max_recharge_steps"):
        _rig(1, backend, max_recharge_steps=0)


def test_backends_agree() -> None:
    """The compiled kernel and its numpy reference make the same decisions on random agents
    and inputs, including the hand-made ties the tie rules are about."""
    rng = np.random.default_rng(5)
    n = 4
    rig = _rig(n, "numba")
    compiled = rig.controller
    reference = NeuralController(rig.weights, rig.robots, rig.perceived, backend="numpy")
    decisive_ties = led_ties = both_available = continued = stopped = 0
    for trial in range(3000):
        w = rng.uniform(-1, 1, (n, GENOME_LENGTH))
        if trial % 10 == 0:  # exact ties between outputs (and zero activations)
            w[:, 3:] = np.round(w[:, 3:]) * (rng.random((n, 36)) < 0.2)
        energy = rng.uniform(0, 200, n)
        proximity = rng.uniform(0, 1, (n, 6))
        face, led_d, battery = rng.uniform(0, 1, (3, n))
        led_previous = rng.random(n) < 0.5
        mate_ok, forage_ok = rng.random((2, n)) < 0.5
        steps = rng.integers(0, 41, n)
        _decide(
            rig,
            w,
            energy=energy,
            proximity=proximity,
            face=face,
            led=led_d,
            battery=battery,
            led_previous=led_previous,
            mate_available=mate_ok,
            forage_available=forage_ok,
            recharge_steps=steps,
        )
        reference.decide()
        got, expected = compiled.buffers, reference.buffers
        np.testing.assert_array_equal(got.inputs, expected.inputs)
        np.testing.assert_allclose(got.activations, expected.activations, rtol=0, atol=1e-14)
        np.testing.assert_array_equal(got.behaviour, expected.behaviour)
        np.testing.assert_array_equal(got.led, expected.led)
        np.testing.assert_array_equal(got.continue_recharge, expected.continue_recharge)
        # Guard against agreeing vacuously: the cases the rules are about must occur.
        act = expected.activations
        masked = np.where(np.column_stack([mate_ok, forage_ok, np.ones(n, bool)]), act, -np.inf)
        decisive_ties += int(((masked == masked.max(axis=1, keepdims=True)).sum(axis=1) > 1).sum())
        led_ties += int((act[:, MATE] == act[:, FORAGE]).sum())
        both_available += int((mate_ok & forage_ok).sum())
        continued += int(expected.continue_recharge.sum())
        stopped += int((~expected.continue_recharge).sum())
    assert decisive_ties > 0 and led_ties > 0
    assert both_available > 0 and continued > 0 and stopped > 0
