"""The experiment tooling around evolution's science core: what a user runs and reads.

The core (``evolution``: genome, controllers, agents, schedulers, reproduction, kernels, the
runner) simulates one run; this package turns runs into experiments. It imports the core, never
the reverse:

- :mod:`~evolution.lab.api`: one run in one call (``run``), run directories and records;
- :mod:`~evolution.lab.experiment`: what ``evolve``, ``resume``, ``plot`` and ``render`` do;
- :mod:`~evolution.lab.sweep`, :mod:`~evolution.lab.grid`, :mod:`~evolution.lab.cells`: many
  runs over methods, seeds and a grid of settings, locally or on Ray, and how cells compare;
- :mod:`~evolution.lab.comparison`, :mod:`~evolution.lab.figures`,
  :mod:`~evolution.lab.learning_figures`: statistics and figures for a paper;
- :mod:`~evolution.lab.video`, :mod:`~evolution.lab.viewer`,
  :mod:`~evolution.lab.window_capture`: off-screen videos and the interactive viewer;
- :mod:`~evolution.lab.transfer`, :mod:`~evolution.lab.deploy`: the hardware-like colony and
  the bundle a real robot runs.

::

    from evolution.lab import run
    table = run(method="ee", generations=5, seed=0)
"""

from evolution.lab.api import make_config, run

__all__ = ["make_config", "run"]
