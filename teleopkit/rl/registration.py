"""The Gymnasium id ``teleopkit/FlexTeleop-v0``, registered by string entry points.

``import teleopkit`` registers it without importing the environments themselves (nor numba,
torch or cvxpy); :func:`gymnasium.make` imports :mod:`teleopkit.rl.env` on first use.
"""

from __future__ import annotations

import gymnasium

__all__ = ["ENV_ID", "register"]

ENV_ID = "teleopkit/FlexTeleop-v0"
"""Gymnasium id of :class:`~teleopkit.rl.env.FlexTeleopEnv` (vector entry point
:class:`~teleopkit.rl.env.FlexTeleopVectorEnv`)."""


def register() -> None:
    """Register :data:`ENV_ID` with Gymnasium (once; later calls do nothing)."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(id=ENV_ID, entry_point="teleopkit.rl.env:FlexTeleopEnv",
                           vector_entry_point="teleopkit.rl.env:FlexTeleopVectorEnv")
