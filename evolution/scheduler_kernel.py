"""Compiled (numba) bookkeeping of :meth:`evolution.scheduler.TimeSharingScheduler.on_step`.

Every control step the scheduler ages each robot's active agent, counts its time slice, copies
its energy and counts its captures, then asks whether anything ends a slot (a mating, a death,
the end of a time slice or of a lifetime). In numpy that is ten calls on (n,)-arrays; almost
every step the answer is "nothing", so :func:`tick` does the bookkeeping and the question in
one compiled loop and the scheduler runs its Python path only when something happened. The
numpy code in ``scheduler.py`` is the reference (used without numba);
``tests/test_evolution_scheduler.py`` checks both on the same event streams.
"""

from __future__ import annotations

from cyber_rodent.compiled import AVAILABLE
from cyber_rodent.compiled import jit as _jit

__all__ = ["AVAILABLE", "tick"]


@_jit
def tick(
    active, age, time_slice, active_energy, energy, batteries, captured, mated_with, died,
    switched, time_sharing_steps, lifetime_steps,
):  # fmt: skip
    """One step of bookkeeping; True if a slot may end this step (the slow path must run).

    For active robots: age and slice +1, energy copied, a capture counted. ``switched`` is
    cleared.
    """
    something = False
    for i in range(active.shape[0]):
        switched[i] = False
        if active[i]:
            age[i] += 1
            time_slice[i] += 1
            active_energy[i] = energy[i]
            if captured[i]:
                batteries[i] += 1
        if (
            mated_with[i] >= 0
            or died[i]
            or time_slice[i] >= time_sharing_steps
            or age[i] >= lifetime_steps
        ):
            something = True
    return something
