"""The survival world's backend switch: bad commands refused alike, unknown backends refused.

:mod:`cyber_rodent.survival.kernels` holds the per-step rules of ``SurvivalWorld`` twice: the
compiled kernels (``backend="numba"``) and their numpy references (``backend="numpy"``). Their
parity, kernel by kernel and over whole scripted worlds, is checked in
``tests/test_kernel_parity.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from cyber_rodent.backend import Backend
from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.world import WorldConfig


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_invalid_wheels_change_nothing(backend: Backend) -> None:
    """A NaN or out-of-range command raises the named error and leaves the state as it was."""
    sw = SurvivalWorld(rng=np.random.default_rng(0), backend=backend)
    n = sw.n_robots
    ok = np.zeros((n, 2))
    flags = np.zeros(n, dtype=bool)
    sw.step(ok, flags, flags, flags)
    ctrl = sw.world.data.ctrl.copy()
    state = sw.state()
    for bad, message in ((np.nan, "finite"), (2.0, "motor limit")):
        wheels = ok.copy()
        wheels[n - 1, 1] = bad
        with pytest.raises(ValueError, match=message):
            sw.step(wheels, ~flags, flags, flags)
        np.testing.assert_array_equal(sw.world.data.ctrl, ctrl)
        after = sw.state()
        assert after["events"]["any"] == state["events"]["any"]
        for name in ("energy", "led_on", "recharging", "mate_signal", "step_count"):
            np.testing.assert_array_equal(after[name], state[name], err_msg=name)


def test_unknown_backend_is_refused() -> None:
    with pytest.raises(ValueError, match="backend must be one of numba, numpy"):
        SurvivalWorld(WorldConfig(n_robots=1, n_packs=0), backend="fortran")  # type: ignore[arg-type]
