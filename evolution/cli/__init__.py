"""The ``cyber-rodent`` command line: the top floor, the one place that ties the three packages
(``cyber_rodent``, ``behaviours``, ``evolution``) together; none of them imports it.

One module per sub-command (:mod:`~evolution.cli.snapshot`,
:mod:`~evolution.cli.train_behaviours`, :mod:`~evolution.cli.evolve`,
:mod:`~evolution.cli.resume`, :mod:`~evolution.cli.sweep`, :mod:`~evolution.cli.config`,
:mod:`~evolution.cli.plot`, :mod:`~evolution.cli.render`, :mod:`~evolution.cli.transfer`), each
holding ``add_arguments(parser)``, its description and options, beside ``run(args) -> int``.
The command table, :data:`evolution.cli.app.COMMANDS`, lists them with the sub-commands whose
module lives elsewhere (``view``, ``deploy``, ``export``: imported only when that command runs,
for they load OpenGL or torch). :mod:`~evolution.cli.options` holds the options several
commands share, :mod:`~evolution.cli.parsing` the parser, its errors and the option types. A
command module stays thin: it reads its options, checks what only the command line knows (the
flag a message names), calls the package code that does the work, and prints what it did.

Each command imports what it runs inside its ``run``, so ``--help`` loads only the
``evolution`` package's core. User errors (bad counts, missing assets, unwritable outputs,
malformed options) print one line, ``cyber-rodent COMMAND: error: ...``, and exit with status
2, never a traceback or a usage block; every input is checked before a file or directory is
created. ``--help`` shows every option's default.

``--plugin MODULE_OR_FILE`` (``evolve``, ``resume``, ``sweep``, ``config``) loads a user's code
that registers a controller, an input or a task (:mod:`cyber_rodent.plugins`) before any other
option is checked, so ``--set evolution.controller=NAME`` accepts the controller it registers.
"""

from evolution.cli.app import COMMANDS, build_parser, main

__all__ = ["COMMANDS", "build_parser", "main"]
