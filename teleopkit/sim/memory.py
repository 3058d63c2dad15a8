"""The machine's memory policy: a recorded run may take at most half the memory available."""

from __future__ import annotations

import os

__all__ = ["available_memory", "check_fits"]


def available_memory() -> int:
    """Bytes of memory available to this process now (physical pages not in use).

    Returns
    -------
    int
        The bytes; a very large number where the system does not say (not POSIX).
    """
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):  # not POSIX: no limit known
        return 2**62


def check_fits(need: int, what: str) -> None:
    """Refuse work whose memory would exceed half of what is available now.

    Parameters
    ----------
    need : int
        Bytes the work needs.
    what : str
        What needs them, for the message (for example ``"a run of 40 s of 16 scenario(s)"``).

    Raises
    ------
    ValueError
        One line with the need and the memory available.
    """
    free = available_memory()
    if need > free / 2:
        raise ValueError(f"{what} records {need / 1e9:.3g} GB, more than half the "
                         f"{free / 1e9:.3g} GB of memory available; simulate shorter runs "
                         "(Simulator.advance streams them)")
