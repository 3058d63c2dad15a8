"""Communication delays: profiles, adversarial profiles, combinators and the channel history.

A delay profile is a frozen dataclass with a declared upper bound and a method ``sample(t)``
(:mod:`teleopkit.delays.profiles`; the paper's Fourier fit is in
:mod:`~teleopkit.delays.paper_fit`). :mod:`~teleopkit.delays.adversarial` holds the fast-switching
profiles of falsification searches, :mod:`~teleopkit.delays.combinators` scales and stacks
profiles into batches, :mod:`~teleopkit.delays.spec` reads the short text specs of the command
line, and :mod:`~teleopkit.delays.history` stores a sender's samples and reads them back at
``t - T(t)``.
"""

from teleopkit._lazy import lazy_namespace

_EXPORTS = {
    "PAPER_DELAY_MAX": "paper_fit",
    "ConstantDelay": "profiles",
    "DelayProfile": "profiles",
    "FourierDelay": "profiles",
    "SinusoidalDelay": "profiles",
    "SwitchingDelay": "profiles",
    "TraceDelay": "profiles",
    "PiecewiseDelay": "adversarial",
    "SquareWaveDelay": "adversarial",
    "ScaledDelay": "combinators",
    "StackedDelay": "combinators",
    "scale_delay": "combinators",
    "stack_delays": "combinators",
    "parse_delay": "spec",
    "ChannelHistory": "history",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _EXPORTS)
