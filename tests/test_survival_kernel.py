"""The compiled contact scan for docking changes nothing: a run with it equals one without.

:func:`cyber_rodent.survival_kernel.teeth_on_electrodes` replaces the numpy scan of the contact
list in ``SurvivalWorld._detect_docking``. An evolution run with the shipped behaviours docks
hundreds of times; with the kernel switched off (the numpy path) the same seed must give the
same trajectory, the same events and the same statistics, bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

from behaviours import BehaviourPolicies
from cyber_rodent import survival_kernel
from evolution.runner import EvolutionRunner, RunConfig

pytestmark = pytest.mark.skipif(not survival_kernel.AVAILABLE, reason="numba is not installed")


def _run(steps: int) -> EvolutionRunner:
    runner = EvolutionRunner(RunConfig(), 3, BehaviourPolicies.load_default())
    for _ in range(steps):
        runner.step()
    return runner


def test_compiled_docking_scan_equals_numpy(monkeypatch) -> None:
    compiled = _run(1500)
    monkeypatch.setattr(survival_kernel, "AVAILABLE", False)
    reference = _run(1500)
    np.testing.assert_array_equal(compiled.world.data.qpos, reference.world.data.qpos)
    np.testing.assert_array_equal(compiled.survival.energy, reference.survival.energy)
    a, b = compiled.events.to_frame(), reference.events.to_frame()
    assert a.equals(b)
    assert (a["kind"] == "dock").sum() > 20  # docking happened often: not vacuous
