"""``python -m teleopkit.cli``: the same as the ``teleopkit`` command."""

import sys

from teleopkit.cli import main

if __name__ == "__main__":  # LMI worker processes import this module again
    sys.exit(main())
