"""Reference implementation of one Cyber Rodent control step, for a real robot's controller.

This file is copied into every deployment bundle and must stay standalone: it imports only the
Python standard library, numpy and torch (no MuJoCo, none of the simulator's packages), so a
robot's computer can run it, and a port to another language can be checked against it.

One step, for one robot (the simulator's ``EvolutionRunner.step`` for each robot):

1. proximity: the six proximity sensors (``proximity_sensors`` of the 8 range readings), as
   ``clip(1 - range / range_max, 0, 1)`` (larger = closer);
2. vision: per class (LED, face, battery) the nearest target's bearing (rad, robot frame, left
   positive), distance (m) and whether one is seen; normalised as ``clip((bearing + pi) / 2 pi,
   0, 1)`` (unseen: bearing 0) and ``clip(distance / max_distance, 0, 1)`` (unseen: 1);
3. controller inputs, one per entry of ``bundle.json`` ``controller.inputs`` in order, each
   computed from the observation it names (``energy``: energy / max_energy; ``proximity``: one
   of the six proximities; ``distance``: one class's normalised distance; ``constant``: its
   value; ``led_previous``: own LED at the previous step, 0 or 1); activations ``W (3 x n) @ x``;
   the available behaviour (Mate needs a face or LED in view, Forage a battery, Search always)
   with the largest activation wins, ties to the lower index; LED on iff activation(Mate) >
   activation(Forage);
4. recharge decision (used while docked): ``w0 energy / max_energy + w1 steps / max_recharge_steps
   + w2 <= 0`` means keep recharging; a robot that keeps recharging shows a dark LED;
5. the chosen behaviour's exported greedy policy maps its two inputs (Mate: the nearest LED if
   one is seen, else the nearest face, as (bearing, distance); Forage: the battery; Search: the
   largest and second largest proximity) to a wheel command index; ``commands`` gives the wheel
   rim speeds in m/s.

The survival bookkeeping around this step (energy, recharging, the rotation reflex, time
sharing between the agents, the IR mating exchange) is the robot's own; the bundle's
``README.md`` gives it as pseudo-code with the run's numbers (``bundle.json`` ``survival``).

Usage::

    from reference_step import ReferenceController
    robot = ReferenceController("bundle_dir", agent=0)
    decision = robot.step(ranges=..., bearing=..., distance=..., visible=..., energy=...,
                          led_previous=..., docked=..., recharge_steps=...)
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

#: Bundle format this file reads.
BUNDLE_FORMAT = 2
MATE, FORAGE, SEARCH = 0, 1, 2
LED, FACE, BATTERY = 0, 1, 2
#: What a controller input may be computed from (``bundle.json`` ``controller.inputs``).
OBSERVATIONS = ("energy", "proximity", "distance", "constant", "led_previous")


@dataclass(frozen=True)
class Decision:
    """What one control step decides for one robot.

    Attributes:
        behaviour: 0 Mate, 1 Forage, 2 Search.
        led: the LED the robot shows (dark while it keeps recharging).
        led_selection: the selection part's LED output (activation(Mate) > activation(Forage)).
        command: wheel command index.
        wheels: (left, right) wheel rim speeds, m/s.
        continue_recharge: the recharge part's decision (meaningful while docked).
        inputs: the controller inputs (``controller.input_order``).
        behaviour_input: the chosen behaviour's 2 inputs.
    """

    behaviour: int
    led: bool
    led_selection: bool
    command: int
    wheels: tuple[float, float]
    continue_recharge: bool
    inputs: np.ndarray
    behaviour_input: np.ndarray


class ReferenceController:
    """Loads a deployment bundle and runs the control step of one robot's agent.

    Args:
        bundle_dir: the bundle directory (``bundle.json``, ``controller_weights.npy``, the
            behaviours' ``.pt2`` programs).
        agent: row of ``controller_weights.npy`` to run (the bundle lists the individuals).
    """

    def __init__(self, bundle_dir: str | Path, agent: int = 0) -> None:
        root = Path(bundle_dir)
        self.spec = json.loads((root / "bundle.json").read_text())
        if self.spec.get("format") != BUNDLE_FORMAT:
            raise ValueError(
                f"bundle format {self.spec.get('format')!r} is not supported (this file reads "
                f"{BUNDLE_FORMAT})"
            )
        self.all_weights = np.asarray(
            np.load(root / self.spec["controller"]["file"]), dtype=np.float64
        )
        norm = self.spec["normalisation"]
        self.max_energy = float(norm["max_energy"])
        self.max_recharge_steps = float(norm["max_recharge_steps"])
        self.max_distance = float(norm["max_distance"])
        self.proximity_sensors = np.asarray(norm["proximity_sensors"], dtype=np.intp)
        self.range_max = np.asarray(norm["range_max"], dtype=np.float64)
        self.commands = np.asarray(self.spec["commands"]["speeds"], dtype=np.float64)
        self.inputs = [
            (row["observation"], row["arg"], row["high"])
            for row in self.spec["controller"]["inputs"]
        ]
        for observation, _, _ in self.inputs:
            if observation not in OBSERVATIONS:
                raise ValueError(f"controller input observation {observation!r} is not known")
        self.use_agent(agent)
        self.policies = []
        for name in self.spec["behaviours"]["order"]:
            program = torch.export.load(root / self.spec["behaviours"]["files"][name])
            self.policies.append(program.module())

    def use_agent(self, agent: int) -> None:
        """Run the agent in row ``agent`` of the bundle's weights (time sharing)."""
        n = len(self.all_weights)
        if isinstance(agent, bool) or not isinstance(agent, int) or not 0 <= agent < n:
            raise ValueError(f"agent must be an integer in [0, {n - 1}], got {agent!r}")
        self.agent = agent
        self.weights = self.all_weights[agent]
        recharge = self.spec["controller"]["recharge_weights"]
        selection = self.spec["controller"]["selection_weights"]
        self.w_recharge = self.weights[recharge[0] : recharge[1]]
        self.w_select = self.weights[selection[0] : selection[1]].reshape(3, len(self.inputs))

    def step(
        self,
        ranges: np.ndarray,
        bearing: np.ndarray,
        distance: np.ndarray,
        visible: np.ndarray,
        energy: float,
        led_previous: bool,
        docked: bool = False,
        recharge_steps: int = 0,
    ) -> Decision:
        """One control step (see the module docstring).

        Args:
            ranges: the 8 range readings, m (sensor order of ``bundle.json``).
            bearing: (3,) rad, nearest LED, face, battery (ignored where not visible).
            distance: (3,) m.
            visible: (3,) bool.
            energy: the agent's energy.
            led_previous: the LED as it was lit during the previous step.
            docked: the robot is docked and recharging.
            recharge_steps: consecutive steps recharged so far.
        """
        ranges = np.asarray(ranges, dtype=np.float64)
        visible = np.asarray(visible, dtype=bool)
        proximity = np.clip(1.0 - ranges[self.proximity_sensors] / self.range_max, 0.0, 1.0)
        seen_bearing = np.where(visible, np.asarray(bearing, dtype=np.float64), 0.0)
        seen_distance = np.where(visible, np.asarray(distance, dtype=np.float64), np.inf)
        nb = np.clip((seen_bearing + math.pi) / (2 * math.pi), 0.0, 1.0)
        nd = np.clip(seen_distance / self.max_distance, 0.0, 1.0)
        x = np.empty(len(self.inputs))
        for column, (observation, arg, value) in enumerate(self.inputs):
            if observation == "energy":
                x[column] = energy / self.max_energy
            elif observation == "proximity":
                x[column] = proximity[arg]
            elif observation == "distance":
                x[column] = nd[arg]
            elif observation == "constant":
                x[column] = value
            else:  # led_previous
                x[column] = float(bool(led_previous))
        activation = self.w_select @ x
        masked = activation.copy()
        if not (visible[LED] or visible[FACE]):
            masked[MATE] = -np.inf
        if not visible[BATTERY]:
            masked[FORAGE] = -np.inf
        behaviour = int(np.argmax(masked))
        led_selection = bool(activation[MATE] > activation[FORAGE])
        w = self.w_recharge
        out = energy / self.max_energy * w[0]
        out += w[1] * (float(recharge_steps) / self.max_recharge_steps)
        out += w[2]
        continue_recharge = bool(out <= 0.0)
        led = led_selection and not (docked and continue_recharge)
        if behaviour == MATE:
            target = LED if visible[LED] else FACE
            state = np.array([nb[target], nd[target]])
        elif behaviour == FORAGE:
            state = np.array([nb[BATTERY], nd[BATTERY]])
        else:
            ordered = np.sort(proximity)
            state = np.array([ordered[-1], ordered[-2]])
        with torch.no_grad():
            command = int(self.policies[behaviour](torch.from_numpy(state[None, :]))[0])
        left, right = self.commands[command]
        return Decision(
            behaviour=behaviour,
            led=led,
            led_selection=led_selection,
            command=command,
            wheels=(float(left), float(right)),
            continue_recharge=continue_recharge,
            inputs=x,
            behaviour_input=state,
        )
