"""The Cyber Rodent's learned basic behaviours: Mate, Forage and Search (paper §3.4).

Each behaviour is a greedy policy over action values learned with Sarsa(λ), tile coding and
replacing traces in the physics world, choosing one of the discrete wheel commands of
:mod:`cyber_rodent.commands`. The trained values ship as package data (``behaviours/data``).

The evolution runner needs only this::

    from behaviours import MATE, FORAGE, SEARCH, BehaviourPolicies, behaviour_inputs
    policies = BehaviourPolicies.load_default()          # or .reactive() (hand-written)
    inputs = behaviour_inputs(frame, world.range_readings(), world.range_max)
    commands = policies.commands(chosen_behaviour, inputs)  # (n,) indices into WHEEL_COMMANDS

Training (:mod:`behaviours.training`, ``cyber-rodent train-behaviours``), evaluation in the
physics world (:mod:`behaviours.evaluation`, ``benchmarks/behaviours.py``) and the torch export
for robots (:mod:`behaviours.export`, ``python -m behaviours.export --out DIR``) are imported on
demand; importing this package never imports torch.
"""

from behaviours.definitions import SPECS, VALUES_VERSION, BehaviourSpec, load_values
from behaviours.inputs import (
    BEHAVIOUR_NAMES,
    FORAGE,
    MATE,
    N_BEHAVIOURS,
    SEARCH,
    BehaviourInputs,
    behaviour_index,
    behaviour_inputs,
)
from behaviours.policies import BehaviourPolicies

__all__ = [
    "BEHAVIOUR_NAMES",
    "FORAGE",
    "MATE",
    "N_BEHAVIOURS",
    "SEARCH",
    "SPECS",
    "VALUES_VERSION",
    "BehaviourInputs",
    "BehaviourPolicies",
    "BehaviourSpec",
    "behaviour_index",
    "behaviour_inputs",
    "load_values",
]
