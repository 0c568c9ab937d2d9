"""The compiled survival mechanics change nothing: a run with them equals one without.

:mod:`cyber_rodent.survival_kernel` replaces the numpy code of ``SurvivalWorld.begin_step``
(commands, LEDs, mating signals), ``end_step``'s energy rules (recharge, stopping rules,
decay, deaths) and the scan of the contact list in ``_detect_docking``. An evolution run with
the shipped behaviours docks, ends recharges, dies and mates many times; with the kernels
switched off (the numpy path) the same seed must give the same trajectory, the same events and
the same statistics, bit for bit.
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


def test_compiled_mechanics_equal_numpy(monkeypatch) -> None:
    compiled = _run(1500)
    monkeypatch.setattr(survival_kernel, "AVAILABLE", False)
    reference = _run(1500)
    np.testing.assert_array_equal(compiled.world.data.qpos, reference.world.data.qpos)
    np.testing.assert_array_equal(compiled.survival.energy, reference.survival.energy)
    a, b = compiled.events.to_frame(), reference.events.to_frame()
    assert a.equals(b)
    np.testing.assert_array_equal(compiled.survival.alive, reference.survival.alive)
    np.testing.assert_array_equal(compiled.world.model.geom_rgba, reference.world.model.geom_rgba)
    # Not vacuous: every rule the kernels implement fired many times.
    for kind in ("dock", "recharge_end", "death", "mate"):
        assert (a["kind"] == kind).sum() >= 10, kind


def test_invalid_wheels_change_nothing_with_the_kernel() -> None:
    """A NaN or out-of-range command raises the named error and leaves the state as it was."""
    from cyber_rodent.survival import SurvivalWorld

    sw = SurvivalWorld(rng=np.random.default_rng(0))
    n = sw.n_robots
    ok = np.zeros((n, 2))
    flags = np.zeros(n, dtype=bool)
    sw.step(ok, flags, flags, flags)
    ctrl = sw.world.data.ctrl.copy()
    events = sw.events.died.copy(), sw.events.any
    for bad, message in ((np.nan, "finite"), (2.0, "motor limit")):
        wheels = ok.copy()
        wheels[n - 1, 1] = bad
        with pytest.raises(ValueError, match=message):
            sw.step(wheels, flags, flags, flags)
        np.testing.assert_array_equal(sw.world.data.ctrl, ctrl)
        assert (sw.events.died.copy(), sw.events.any)[1] == events[1]
