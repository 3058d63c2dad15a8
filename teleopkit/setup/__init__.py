"""Setups: a user's plant, network, operator and start as one value, read from a file.

:class:`Setup` is what every entry point of the toolkit takes (``setup=`` in Python,
``--setup FILE`` on the command line); :meth:`Setup.paper` is the source paper's, shipped as
``paper_setup.yaml``.
"""

from teleopkit.setup.network import Channel, Network
from teleopkit.setup.operator import MotionSpec, OperatorSetup
from teleopkit.setup.reading import SetupError
from teleopkit.setup.setup import (
    PAPER_SETUP_FILE,
    SHIPPED_SETUPS,
    Setup,
    paper_setup_path,
    shipped_setup_path,
)
from teleopkit.setup.start import StartMix, StartSpec

__all__ = ["PAPER_SETUP_FILE", "SHIPPED_SETUPS", "Channel", "MotionSpec", "Network",
           "OperatorSetup", "Setup", "SetupError", "StartMix", "StartSpec", "paper_setup_path",
           "shipped_setup_path"]
