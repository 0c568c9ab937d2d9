"""``python -m evolution.cli``: the ``cyber-rodent`` command."""

import sys

from evolution.cli.app import main

sys.exit(main())
