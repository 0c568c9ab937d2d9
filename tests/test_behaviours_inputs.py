"""Behaviour inputs, availability, the reactive baseline and the vectorised command interface."""

from __future__ import annotations

import math

import numpy as np
import pytest

from behaviours import (
    FORAGE,
    MATE,
    SEARCH,
    BehaviourPolicies,
    behaviour_index,
    behaviour_inputs,
)
from behaviours.inputs import search_inputs
from behaviours.reactive import ApproachConfig, AvoidConfig, ReactiveApproach, ReactiveAvoid
from cyber_rodent.commands import N_COMMANDS, command_index
from cyber_rodent.robot import cyber_rodent
from cyber_rodent.vision.types import BATTERY, DEFAULT_MAX_DISTANCE, FACE, LED, VisionFrame

#: The paper's robot, read from its MJCF file and sensor table.
CR = cyber_rodent()
#: Its range sensors as (name, bearing in degrees, range in metres).
RANGE_ROWS = [(row.name, row.bearing_deg, row.limit) for row in CR.range_sensors]

RANGE_MAX = np.array([r for _, _, r in RANGE_ROWS])  # 1.0 front, 0.3 the others



def _frame(n: int) -> VisionFrame:
    return VisionFrame.empty(n)


def test_indices_are_the_controllers_output_order():
    assert (MATE, FORAGE, SEARCH) == (0, 1, 2)
    assert behaviour_index("forage") == FORAGE
    with pytest.raises(ValueError, match="behaviour: unknown behaviour 'dance'.*mate, forage"):
        behaviour_index("dance")


def test_target_inputs_hand_computed():
    frame = _frame(3)
    # Robot 0 sees an LED 45° to the left at 0.65 m and a face; the LED wins.
    frame.visible[0, LED] = frame.visible[0, FACE] = True
    frame.bearing[0, LED], frame.distance[0, LED] = math.pi / 4, 0.65
    frame.bearing[0, FACE], frame.distance[0, FACE] = -math.pi / 2, 0.3
    # Robot 1 sees only a face straight behind-right (-90°) at 1.3 m, and a pack ahead at 0.325.
    frame.visible[1, FACE] = True
    frame.bearing[1, FACE], frame.distance[1, FACE] = -math.pi / 2, 1.3
    frame.visible[1, BATTERY] = True
    frame.bearing[1, BATTERY], frame.distance[1, BATTERY] = 0.0, 0.325
    # Robot 2 sees nothing.
    ranges = np.tile(RANGE_MAX, (3, 1))
    inp = behaviour_inputs(frame, ranges, RANGE_MAX)
    d = DEFAULT_MAX_DISTANCE
    np.testing.assert_allclose(inp.mate[0], [0.625, 0.65 / d])  # (π/4 + π) / 2π = 0.625
    np.testing.assert_allclose(inp.mate[1], [0.25, 1.3 / d])  # face fallback
    np.testing.assert_allclose(inp.mate[2], [0.5, 1.0])  # unseen: ahead, distance 1
    np.testing.assert_allclose(inp.forage[1], [0.5, 0.325 / d])
    np.testing.assert_allclose(inp.forage[0], [0.5, 1.0])
    assert inp.mate_available.tolist() == [True, True, False]
    assert inp.forage_available.tolist() == [False, True, False]
    for a in (inp.mate, inp.forage, inp.search):
        assert a.shape == (3, 2) and a.min() >= 0.0 and a.max() <= 1.0


def test_search_takes_the_two_largest_proximities_of_the_six():
    # Proximity = 1 - range / range_max. Sensors 0..4 front, 5 back; 6, 7 (sides) are ignored.
    ranges = np.array(
        [
            [0.5, 0.3, 0.3, 0.3, 0.3, 0.3, 0.0, 0.0],  # only the front range sensor: 1 - 0.5
            [1.0, 0.15, 0.3, 0.24, 0.3, 0.06, 0.3, 0.3],  # back 0.8, left30 0.5, left60 0.2
            [1.0, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3],  # nothing near
        ]
    )
    np.testing.assert_allclose(
        search_inputs(ranges, RANGE_MAX), [[0.5, 0.0], [0.8, 0.5], [0.0, 0.0]], atol=1e-12
    )
    per_robot = np.tile(RANGE_MAX, (3, 1))
    np.testing.assert_array_equal(
        search_inputs(ranges, per_robot), search_inputs(ranges, RANGE_MAX)
    )


def test_mismatched_shapes_are_clear_errors():
    with pytest.raises(ValueError, match="ranges"):
        behaviour_inputs(_frame(2), np.zeros((3, 8)), RANGE_MAX)
    with pytest.raises(ValueError, match="ranges"):
        search_inputs(np.zeros((2, 4)), RANGE_MAX)


def test_reactive_approach_hand_cases():
    policy = ReactiveApproach(ApproachConfig(spin_deg=25, arc_deg=6, slow_distance=0.6))
    d = DEFAULT_MAX_DISTANCE
    states = np.array(
        [
            [0.5 + 40 / 360, 1.0 / d],  # 40° left: spin left
            [0.5 - 40 / 360, 1.0 / d],  # 40° right: spin right
            [0.5 + 10 / 360, 1.0 / d],  # 10° left: arc left
            [0.5 - 10 / 360, 1.0 / d],  # arc right
            [0.5, 1.0 / d],  # ahead, far: forward
            [0.5, 0.3 / d],  # ahead, near: slow
        ]
    )
    names = ["spin_left", "spin_right", "arc_left", "arc_right", "forward", "forward_slow"]
    assert policy.act(states).tolist() == [command_index(n) for n in names]
    stopper = ReactiveApproach(ApproachConfig(stop_distance=0.45))
    assert stopper.act(np.array([[0.5, 0.4 / d]])).tolist() == [command_index("stop")]


def test_reactive_avoid_hand_cases():
    policy = ReactiveAvoid(AvoidConfig(turn_proximity=0.2, spin_proximity=0.45))
    states = np.array([[0.0, 0.0], [0.3, 0.1], [0.9, 0.5]])
    assert policy.act(states).tolist() == [
        command_index("forward"),
        command_index("arc_left"),
        command_index("spin_left"),
    ]


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: ApproachConfig(spin_deg=200), "spin_deg"),
        (lambda: ApproachConfig(arc_deg=30, spin_deg=20), "arc_deg"),
        (lambda: ApproachConfig(stop_distance=-1), "stop_distance"),
        (lambda: AvoidConfig(spin_proximity=1.5), "spin_proximity"),
        (lambda: AvoidConfig(turn_proximity=float("nan")), "turn_proximity"),
    ],
)
def test_reactive_config_rejects_bad_values(make, field):
    with pytest.raises(ValueError, match=field):
        make()


def test_commands_dispatch_each_robot_to_its_behaviour():
    policies = BehaviourPolicies.reactive()
    frame = _frame(4)
    frame.visible[:, LED] = True
    frame.bearing[:, LED] = math.radians(90)  # LED far to the left
    frame.distance[:, LED] = 1.0
    frame.visible[:, BATTERY] = True
    frame.bearing[:, BATTERY] = math.radians(-90)  # pack far to the right
    frame.distance[:, BATTERY] = 1.0
    ranges = np.tile(RANGE_MAX, (4, 1))  # nothing near
    inp = behaviour_inputs(frame, ranges, RANGE_MAX)
    out = policies.commands(np.array([MATE, FORAGE, SEARCH, MATE]), inp)
    assert out.dtype == np.int64
    assert out.tolist() == [
        command_index("spin_left"),
        command_index("spin_right"),
        command_index("forward"),
        command_index("spin_left"),
    ]
    assert ((out >= 0) & (out < N_COMMANDS)).all()
    buf = np.empty(4, dtype=np.int64)
    assert policies.commands(np.full(4, SEARCH), inp, out=buf) is buf
    assert buf.tolist() == [command_index("forward")] * 4


def test_commands_reject_bad_behaviour_indices():
    policies = BehaviourPolicies.reactive()
    inp = behaviour_inputs(_frame(2), np.tile(RANGE_MAX, (2, 1)), RANGE_MAX)
    with pytest.raises(ValueError, match=r"behaviour: indices must be in \[0, 3\)"):
        policies.commands(np.array([0, 3]), inp)
    with pytest.raises(ValueError, match="behaviour: expected shape"):
        policies.commands(np.array([0, 1, 2]), inp)
