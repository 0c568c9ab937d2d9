"""The 39-weight controller: hand-computed outputs, the LED rule, availability, recharge."""

from __future__ import annotations

import numpy as np
import pytest

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


def _weights(recharge=(0.0, 0.0, 0.0), mate=None, forage=None, search=None) -> np.ndarray:
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


def _filled(controller: NeuralController) -> np.ndarray:
    return controller.fill_inputs(
        energy=np.array([100.0]),
        proximity=np.array([[0.1, 0.2, 0.3, 0.4, 0.5, 0.6]]),
        face_distance=np.array([0.2]),
        led_distance=np.array([0.3]),
        battery_distance=np.array([0.4]),
        led_previous=np.array([True]),
    )


def test_fill_inputs_places_and_normalises_each_input() -> None:
    controller = NeuralController(1)
    x = _filled(controller)
    np.testing.assert_array_equal(
        x[0], [0.5, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.2, 0.3, 0.4, 1.0, 1.0]
    )


def test_activations_hand_computed() -> None:
    controller = NeuralController(1)
    x = _filled(controller)
    # Mate: all weights 0.1 -> 0.1 * sum(x) = 0.1 * 5.5 = 0.55.
    # Forage: battery distance 2, bias -0.5 -> 0.8 - 0.5 = 0.3.
    # Search: energy -1, back proximity 3 -> -0.5 + 1.8 = 1.3.
    search = _one_hot(IN_ENERGY, -1.0) + _one_hot(6, 3.0)
    w = _weights(
        mate=np.full(N_INPUTS, 0.1),
        forage=_one_hot(IN_BATTERY_DISTANCE, 2.0) + _one_hot(IN_BIAS, -0.5),
        search=search,
    )[None]
    act = controller.compute_activations(w, x)
    np.testing.assert_allclose(act[0], [0.55, 0.3, 1.3], rtol=0, atol=1e-12)
    behaviour, led = controller.select(w, np.array([True]), np.array([True]))
    assert behaviour[0] == SEARCH
    assert led[0]  # 0.55 > 0.3


@pytest.mark.parametrize(
    ("mate_ok", "forage_ok", "expected"),
    [
        (True, True, MATE),  # Mate 1.0 > Search 0.95 > Forage 0.9
        (False, True, SEARCH),  # Mate unavailable: Search 0.95 beats Forage 0.9
        (True, False, MATE),
        (False, False, SEARCH),
    ],
)
def test_only_available_behaviours_win(mate_ok: bool, forage_ok: bool, expected: int) -> None:
    controller = NeuralController(1)
    _filled(controller)
    w = _weights(
        mate=_one_hot(IN_ENERGY, 2.0),  # 2 * 0.5 = 1.0
        forage=_one_hot(IN_BIAS, 0.9),  # 0.9
        search=_one_hot(IN_LED_PREVIOUS, 0.95),  # 0.95
    )[None]
    behaviour, led = controller.select(w, np.array([mate_ok]), np.array([forage_ok]))
    assert behaviour[0] == expected
    assert led[0]  # the LED follows the raw activations (1.0 > 0.9), not availability


def test_forage_wins_when_only_it_is_highest_and_available() -> None:
    controller = NeuralController(1)
    _filled(controller)
    w = _weights(forage=_one_hot(IN_BIAS, 1.0))[None]  # Mate 0, Forage 1, Search 0
    behaviour, led = controller.select(w, np.array([True]), np.array([True]))
    assert behaviour[0] == FORAGE and not led[0]
    behaviour, _ = controller.select(w, np.array([True]), np.array([False]))
    assert behaviour[0] == MATE  # Mate and Search tie at 0: the lower index wins


def test_led_rule_strict_greater() -> None:
    controller = NeuralController(3)
    controller.inputs[:] = 0.0
    controller.inputs[:, IN_BIAS] = 1.0
    w = np.stack(
        [
            _weights(mate=_one_hot(IN_BIAS, 0.5), forage=_one_hot(IN_BIAS, 0.4)),  # on
            _weights(mate=_one_hot(IN_BIAS, 0.4), forage=_one_hot(IN_BIAS, 0.5)),  # off
            _weights(mate=_one_hot(IN_BIAS, 0.5), forage=_one_hot(IN_BIAS, 0.5)),  # tie: off
        ]
    )
    _, led = controller.select(w, np.zeros(3, bool), np.zeros(3, bool))
    np.testing.assert_array_equal(led, [True, False, False])


def test_vectorised_select_matches_a_per_robot_reference() -> None:
    rng = np.random.default_rng(11)
    n = 4
    controller = NeuralController(n)
    for _ in range(2000):
        w = rng.uniform(-1, 1, (n, GENOME_LENGTH))
        x = rng.uniform(0, 1, (n, N_INPUTS))
        mate_ok = rng.random(n) < 0.5
        forage_ok = rng.random(n) < 0.5
        behaviour, led = controller.select(w, mate_ok, forage_ok, inputs=x)
        for r in range(n):
            act = w[r, 3:].reshape(3, N_INPUTS) @ x[r]
            allowed = [mate_ok[r], forage_ok[r], True]
            best = max((a, -i) for i, a in enumerate(act) if allowed[i])
            assert behaviour[r] == -best[1]
            assert led[r] == (act[MATE] > act[FORAGE])
            assert allowed[behaviour[r]]  # an unavailable behaviour is never chosen


def test_recharge_decision_hand_computed() -> None:
    controller = NeuralController(4)
    w = np.stack([_weights(recharge=(2.0, 1.0, -1.5)) for _ in range(4)])
    energy = np.array([100.0, 150.0, 100.0, 200.0])
    steps = np.array([10, 10, 20, 40])
    # 2*0.5 + 1*0.25 - 1.5 = -0.25 -> continue
    # 2*0.75 + 1*0.25 - 1.5 = 0.25 -> stop
    # 2*0.5 + 1*0.5 - 1.5 = 0 -> continue (the paper: "less or equal to zero")
    # 2*1 + 1*1 - 1.5 = 1.5 -> stop
    np.testing.assert_array_equal(
        controller.continue_recharge(w, energy, steps), [True, False, True, False]
    )


def test_bad_constructor_arguments() -> None:
    with pytest.raises(ValueError, match="n_robots"):
        NeuralController(0)
    with pytest.raises(ValueError, match="max_energy"):
        NeuralController(1, max_energy=0.0)
    with pytest.raises(ValueError, match="max_recharge_steps"):
        NeuralController(1, max_recharge_steps=0)


def test_decide_equals_fill_select_and_recharge() -> None:
    """The runner's one-call :meth:`NeuralController.decide` (compiled) makes the same
    decisions as the three numpy methods, on random agents and inputs, including the
    hand-made ties the tie rules are about."""
    rng = np.random.default_rng(5)
    n = 4
    fused, reference = NeuralController(n), NeuralController(n)
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
        behaviour, led, proceed = fused.decide(
            w, energy, proximity, face, led_d, battery, led_previous, mate_ok, forage_ok, steps
        )
        reference.fill_inputs(energy, proximity, face, led_d, battery, led_previous)
        expected_behaviour, expected_led = reference.select(w, mate_ok, forage_ok)
        np.testing.assert_array_equal(fused.inputs, reference.inputs)
        np.testing.assert_allclose(fused.activations, reference.activations, atol=1e-14)
        np.testing.assert_array_equal(behaviour, expected_behaviour)
        np.testing.assert_array_equal(led, expected_led)
        np.testing.assert_array_equal(proceed, reference.continue_recharge(w, energy, steps))
