"""Test vectors of a deployment bundle: real simulator steps of the bundle's own agents.

:func:`record_decisions` steps an :class:`~evolution.runner.EvolutionRunner` and records, per
step and robot, the raw observations the step used and the decisions it took;
:func:`record_test_vectors` runs a short simulated colony whose robots carry the bundle's agents
(time sharing lets every agent act) and keeps the rows of those agents, which the bundle stores
as ``test_vectors.npz``. ``reference_step.py --check`` replays them (a port to another language
replays the same rows), and ``tests/test_deploy.py`` replays longer recordings the same way.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from evolution.runner.config import RunConfig

if TYPE_CHECKING:
    from behaviours.action_values import ActionValues

VECTORS_FILE = "test_vectors.npz"
#: Control steps recorded (x robots = rows, less the rows of agents born during the recording).
DEFAULT_STEPS = 100
#: Seed of the recording's colony (placement, reflexes).
RECORD_SEED = 0

#: The columns of ``test_vectors.npz``, one row per (step, robot) of the recording.
COLUMNS = {
    "step": "int64: control step of the recording (1 = the first)",
    "robot": "int64: robot of the recording's colony",
    "agent": "int64: row of controller_weights.npy that acted (ReferenceController.use_agent)",
    "ranges": "float64 (8,): the range readings, m (step argument)",
    "bearing": "float64 (3,): nearest LED, face, battery bearing, rad (ignored where not "
    "visible)",
    "distance": "float64 (3,): their distances, m (inf where not visible)",
    "visible": "bool (3,)",
    "energy": "float64: the agent's energy before the step",
    "led_previous": "bool: the LED lit during the previous step",
    "docked": "bool: docked and recharging before the step",
    "recharge_steps": "int64: consecutive recharge steps before the step",
    "inputs": "float64 (n_inputs,): the controller inputs the simulator computed",
    "behaviour": "int64: expected behaviour (0 Mate, 1 Forage, 2 Search)",
    "led": "bool: expected LED shown",
    "led_selection": "bool: expected selection LED output",
    "command": "int64: expected wheel command index",
    "wheels": "float64 (2,): expected wheel rim speeds, m/s (left, right)",
    "continue_recharge": "bool: expected recharge decision",
}


def record_decisions(runner: Any, steps: int) -> dict[str, np.ndarray]:
    """Step ``runner`` (an :class:`~evolution.runner.EvolutionRunner`) and record, per step and
    robot, the raw observations the step used and the decisions it took.

    Returns:
        Arrays with a leading (steps, n_robots) shape: observations ``ranges`` (8),
        ``bearing``/``distance``/``visible`` (3), ``energy``, ``led_previous``, ``docked``,
        ``recharge_steps``, ``weights`` (39; the active agent's genome); decisions
        ``behaviour``, ``led`` (shown), ``led_selection``, ``command``, ``wheels`` (2),
        ``continue_recharge`` and ``inputs`` (12; one per row of the input table).
    """
    survival, perception, action = runner.survival, runner.perception, runner.action
    keys = ("ranges", "bearing", "distance", "visible", "energy", "led_previous", "docked",
            "recharge_steps", "weights", "behaviour", "led", "led_selection", "command",
            "wheels", "continue_recharge", "inputs")  # fmt: skip
    rows: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    for _ in range(steps):
        controller = runner.controller
        before = {
            "energy": survival.energy.copy(),
            "led_previous": runner.world.led_on.copy(),
            "docked": survival.docked.copy(),
            "recharge_steps": survival.recharge_steps.copy(),
            "weights": controller.buffers.weights.copy(),
        }
        runner.step()
        for k, v in before.items():
            rows[k].append(v)
        nearest = perception.nearest
        rows["ranges"].append(perception.sensors.ranges.copy())
        rows["bearing"].append(nearest.bearing.copy())
        rows["distance"].append(nearest.distance.copy())
        rows["visible"].append(nearest.visible.copy())
        rows["behaviour"].append(controller.behaviour.copy())
        rows["led_selection"].append(controller.led.copy())
        rows["led"].append(action.led.copy())
        rows["command"].append(action.commands.copy())
        rows["wheels"].append(action.wheels.copy())
        rows["continue_recharge"].append(controller.continue_recharge.copy())
        rows["inputs"].append(controller.buffers.inputs.copy())
    return {k: np.stack(v) for k, v in rows.items()}


def recording_config(config: RunConfig, n_agents: int, steps: int) -> RunConfig:
    """``config`` with a colony that lets each of ``n_agents`` agents act within ``steps``.

    The run's robots, field, sensors and rules stay; only the agents per robot (enough for all
    the agents) and the time-sharing slot (so that every slot comes round) change.
    """
    evo = config.evolution
    robots = evo.n_robots
    per_robot = math.ceil(n_agents / robots)
    sharing = max(1, min(evo.lifetime_steps, steps // per_robot))
    evolution = dataclasses.replace(
        evo, population_size=robots * per_robot, time_sharing_steps=sharing
    )
    return config.replace(evolution=evolution)


def record_test_vectors(
    config: RunConfig,
    weights: np.ndarray,
    values: Mapping[str, ActionValues],
    *,
    steps: int = DEFAULT_STEPS,
    seed: int = RECORD_SEED,
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Record the bundle's test vectors (module docstring).

    Args:
        config: the run's resolved configuration.
        weights: (n_agents, genes) the bundle's agents.
        values: the behaviours' action values (Mate, Forage, Search), as bundled.
        steps: control steps to record.
        seed: the colony's seed.

    Returns:
        ``(columns, record)``: the arrays of :data:`COLUMNS` and the ``bundle.json``
        ``test_vectors`` entry describing how they were recorded.

    Raises:
        ValueError: a learning-mode config (a bundle carries the fixed behaviours).
    """
    from behaviours import BehaviourPolicies
    from behaviours.greedy_policy import GreedyPolicy
    from evolution.genome import Genome
    from evolution.runner import EvolutionRunner

    if config.evolution.learning.enabled:
        raise ValueError(
            "config: evolution.learning.enabled; a bundle carries fixed behaviours, not values "
            "learned in life"
        )
    n = len(weights)
    recording = recording_config(config, n, steps)
    robots = recording.evolution.n_robots
    per_robot = recording.evolution.subpopulation_size
    # Slot j of robot r holds agent (j * robots + r) mod n: the first slots hold distinct agents.
    slots = [(j * robots + r) % n for r in range(robots) for j in range(per_robot)]
    mate, forage, search = (GreedyPolicy(values[n]) for n in ("mate", "forage", "search"))
    policies = BehaviourPolicies(mate, forage, search, kind="learned")
    genomes = [Genome(weights[a].copy()) for a in slots]
    with EvolutionRunner(recording, seed, policies, genomes) as runner:
        raw = record_decisions(runner, steps)
    agent_of = {}
    for a in range(n - 1, -1, -1):  # a genome listed twice answers to its first row
        agent_of[weights[a].tobytes()] = a
    flat = {k: v.reshape(steps * robots, *v.shape[2:]) for k, v in raw.items()}
    agent = np.array([agent_of.get(w.tobytes(), -1) for w in flat["weights"]], dtype=np.int64)
    keep = agent >= 0  # not the agents born or brought in during the recording
    step, robot = np.divmod(np.arange(steps * robots), robots)
    columns = {
        "step": step[keep] + 1,
        "robot": robot[keep],
        "agent": agent[keep],
        **{k: flat[k][keep] for k in COLUMNS if k in flat},
    }
    for k in ("behaviour", "command", "recharge_steps"):
        columns[k] = columns[k].astype(np.int64)
    for k in ("visible", "led_previous", "docked", "led", "led_selection", "continue_recharge"):
        columns[k] = columns[k].astype(bool)
    record = {
        "file": VECTORS_FILE,
        "rows": int(keep.sum()),
        "agents": sorted({int(a) for a in columns["agent"]}),
        "recorded": f"control steps 1-{steps} of a simulated colony (seed {seed}) of the run's "
        f"{robots} robots and field, {per_robot} of the bundle's agents per robot taking turns "
        f"every {recording.evolution.time_sharing_steps} steps; one row per step and robot "
        "whose active agent is one of the bundle's",
        "seed": seed,
        "steps": steps,
        "robots": robots,
        "agents_per_robot": per_robot,
        "time_sharing_steps": recording.evolution.time_sharing_steps,
        "columns": COLUMNS,
        "check": "python reference_step.py --check",
    }
    return columns, record


__all__ = [
    "COLUMNS",
    "DEFAULT_STEPS",
    "RECORD_SEED",
    "VECTORS_FILE",
    "record_decisions",
    "record_test_vectors",
    "recording_config",
]
