"""``python -m teleopkit.cli``: the same as the ``teleopkit`` command."""

import sys

from teleopkit.cli import main

sys.exit(main())
