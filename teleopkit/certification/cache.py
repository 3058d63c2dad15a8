"""Certificates kept on disk by the question they answer, re-verified whenever they are reused.

Two-joint LMI certificates take minutes; asking the same question again should not. A question
(:class:`~teleopkit.certification.question.Question`: the plant's fingerprint, the gain box, the
delay bounds and minimum delays, the gain class) and the method name a JSON file by their
SHA-256 (:meth:`~teleopkit.certification.question.Question.key`)
in the cache directory (``$TELEOPKIT_CACHE``, else ``~/.cache/teleopkit``). A file read back
goes through :func:`~teleopkit.certification.verification.load_certificate`, which re-checks
every proof against the plant, so an edited or stale file is never trusted: it is
recomputed and overwritten.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.verification import load_certificate
from teleopkit.files import atomic_write

__all__ = ["cache_directory", "cached"]


def cache_directory() -> Path:
    """Where certificates are kept: ``$TELEOPKIT_CACHE``, else ``~/.cache/teleopkit``.

    Returns
    -------
    pathlib.Path
        The directory (not created until a certificate is written).
    """
    root = os.environ.get("TELEOPKIT_CACHE")
    return Path(root) if root else Path.home() / ".cache" / "teleopkit"


def cached(key: str, compute: Callable[[], GainCertificate],
           directory: Path | None = None) -> tuple[GainCertificate, bool]:
    """The certificate stored under ``key`` (re-verified), else ``compute()`` stored there.

    Parameters
    ----------
    key : str
        :func:`question_key` of the question.
    compute : callable
        Computes the certificate when none is stored or the stored one does not verify.
    directory : pathlib.Path, optional
        Cache directory; :func:`cache_directory` by default.

    Returns
    -------
    certificate : GainCertificate
        The certificate.
    reused : bool
        Whether it came from the cache.
    """
    path = (directory if directory is not None else cache_directory()) / f"{key}.json"
    try:
        return load_certificate(path.read_text()), True
    except (OSError, ValueError):  # absent, unreadable, edited or stale: recompute
        pass
    certificate = compute()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda tmp: tmp.write_text(certificate.to_json()))
    except OSError:  # a read-only home: the answer stands, it is just not kept
        pass
    return certificate, False
