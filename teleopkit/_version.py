"""The version of teleopkit (one home: the package metadata reads it too)."""

__version__ = "0.1.0"
