"""Compiled (numba) scan of the contact list for charging-teeth-on-electrode contacts.

:class:`cyber_rodent.survival.SurvivalWorld` looks for captures after every control step
among all of the step's contacts (wheels and casters on the floor, bodies on walls, teeth on
electrodes). :func:`teeth_on_electrodes` does the scan in one compiled loop and returns only
the (robot, pack) pairs of robots that may dock (alive, not docked, not in their rotation
reflex); the alignment test and the docking itself stay in Python (rare).
"""

from __future__ import annotations

from cyber_rodent.compiled import AVAILABLE
from cyber_rodent.compiled import jit as _jit

__all__ = ["AVAILABLE"]


@_jit
def teeth_on_electrodes(
    geom, dock_code, teeth_owner, electrode_owner, alive, docked, in_reflex, reflex_steps_left, out
):
    """Fill ``out[:k]`` with (robot, pack) of each eligible teeth-electrode contact; return k.

    Args:
        geom: (ncon, 2) the contacts' geom pairs.
        dock_code: (ngeom,) 1 for teeth geoms, 2 for electrode geoms, 0 otherwise.
        teeth_owner, electrode_owner: (ngeom,) robot / pack of a teeth / electrode geom, -1.
        alive, docked: (n,) bool; in_reflex: (n,) bool, the robot started the step in its
            reflex; reflex_steps_left: (n,) int.
        out: (ncon, 2) int64 output.
    """
    k = 0
    for c in range(geom.shape[0]):
        g1 = geom[c, 0]
        g2 = geom[c, 1]
        if (dock_code[g1] | dock_code[g2]) != 3:
            continue
        i = teeth_owner[g1]
        if i >= 0:
            j = electrode_owner[g2]
        else:
            i = teeth_owner[g2]
            j = electrode_owner[g1]
        if alive[i] and not docked[i] and not in_reflex[i] and reflex_steps_left[i] == 0:
            out[k, 0] = i
            out[k, 1] = j
            k += 1
    return k
