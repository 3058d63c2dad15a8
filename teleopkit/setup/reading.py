"""Checked reading of a setup document: every error is one line naming the key path.

A setup file is YAML (JSON is YAML too). :class:`Node` wraps one value of the document with its
key path (``plant.local_arm.masses``) and turns what it reads into the types the setup needs,
raising :class:`SetupError` (a :class:`ValueError`) with that path and the problem.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

__all__ = ["Node", "SetupError", "listed", "load_document", "read_once"]

_Read = TypeVar("_Read")


class SetupError(ValueError):
    """A setup that cannot be used: one line naming the key path and the problem."""


def load_document(path: str | Path) -> Any:
    """Read a YAML (or JSON) document.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    object
        The parsed document.

    Raises
    ------
    SetupError
        If the file cannot be read or is not valid YAML.
    """
    import yaml

    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as error:
        raise SetupError(f"cannot read the setup file {path}: {error.strerror or error}") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise SetupError(f"{path} is not valid YAML{where}: {problem}") from None


@dataclass(frozen=True)
class Node:
    """One value of a setup document and its key path.

    Parameters
    ----------
    value : object
        The value.
    path : str
        Its key path, for example ``plant.joints.stiffness`` (empty for the document).
    """

    value: Any
    path: str = ""

    def error(self, problem: str) -> SetupError:
        """An error naming this node's key path.

        Parameters
        ----------
        problem : str
            What is wrong.

        Returns
        -------
        SetupError
            ``"<path>: <problem>"``.
        """
        return SetupError(f"{self.path or 'the setup'}: {problem}")

    def child(self, key: str | int) -> Node:
        """The node under ``key``.

        Parameters
        ----------
        key : str or int
            A mapping key or a list index.

        Returns
        -------
        Node
            The value and its key path.
        """
        path = f"{self.path}[{key}]" if isinstance(key, int) else (
            f"{self.path}.{key}" if self.path else key)
        return Node(self.value[key], path)

    def fields(self, allowed: tuple[str, ...], required: tuple[str, ...] = ()
               ) -> dict[str, Node]:
        """The entries of a mapping, refusing unknown keys and requiring some.

        Parameters
        ----------
        allowed : tuple of str
            Keys it may have.
        required : tuple of str
            Keys it must have.

        Returns
        -------
        dict of str to Node
            The entries present.
        """
        if self.value is None and not required:
            return {}
        if not isinstance(self.value, Mapping):
            raise self.error(f"must be a mapping of {', '.join(allowed)}, got {_shown(self.value)}")
        unknown = [str(key) for key in self.value if key not in allowed]
        if unknown:
            raise self.error(f"unknown key {unknown[0]!r} (known: {', '.join(allowed)})")
        missing = [key for key in required if key not in self.value]
        if missing:
            raise self.error(f"missing key {missing[0]!r}")
        return {key: self.child(key) for key in allowed if key in self.value}

    def number(self, minimum: float = -math.inf, strict: bool = False,
               allow_inf: bool = False) -> float:
        """The value as a float.

        Parameters
        ----------
        minimum : float
            Smallest value allowed.
        strict : bool
            Whether ``minimum`` itself is refused.
        allow_inf : bool
            Whether ``inf`` (written ``.inf`` or ``inf``) is allowed.

        Returns
        -------
        float
            The number.
        """
        value = self.value
        if isinstance(value, bool) or not isinstance(value, int | float | str):
            raise self.error(f"must be a number, got {_shown(value)}")
        try:
            number = float(value)
        except ValueError:
            raise self.error(f"must be a number, got {_shown(value)}") from None
        if math.isnan(number) or (math.isinf(number) and not allow_inf):
            raise self.error(f"must be a finite number, got {_shown(value)}")
        if number < minimum or (strict and number == minimum):
            relation = "above" if strict else "at least"
            kind = {(0.0, True): "positive", (0.0, False): "non-negative"}.get(
                (minimum, strict), f"{relation} {minimum:g}")
            raise self.error(f"must be {kind}, got {number:g}")
        return number

    def numbers(self, length: int | None = None, minimum: float = -math.inf,
                strict: bool = False, allow_inf: bool = False) -> tuple[float, ...]:
        """The value as a tuple of floats (a single number is broadcast to ``length``).

        Parameters
        ----------
        length : int, optional
            Required length (one value per joint).
        minimum, strict, allow_inf
            As for :meth:`number`, for every entry.

        Returns
        -------
        tuple of float
            The numbers.
        """
        if isinstance(self.value, list | tuple):
            if not self.value:
                raise self.error("must not be empty")
            if length is not None and len(self.value) != length:
                raise self.error(f"needs {length} values (one per joint), got {len(self.value)}")
            return tuple(self.child(i).number(minimum, strict, allow_inf)
                         for i in range(len(self.value)))
        return (self.number(minimum, strict, allow_inf),) * (length or 1)

    def interval(self, minimum: float = -math.inf) -> tuple[float, float]:
        """A range ``[low, high]`` (a single number is the range of that one value).

        Parameters
        ----------
        minimum : float
            Smallest value allowed.

        Returns
        -------
        (float, float)
            ``low <= high``.
        """
        if not isinstance(self.value, list | tuple):
            value = self.number(minimum)
            return value, value
        if len(self.value) != 2:
            raise self.error(f"must be a range [low, high], got {_shown(self.value)}")
        low, high = self.numbers(2, minimum)
        if low > high:
            raise self.error(f"range [{low:g}, {high:g}] is inverted (low above high)")
        return low, high

    def text(self) -> str:
        """The value as a non-empty string."""
        if not isinstance(self.value, str) or not self.value.strip():
            raise self.error(f"must be a text, got {_shown(self.value)}")
        return self.value.strip()

    def items(self) -> Iterator[Node]:
        """The entries of a list."""
        if not isinstance(self.value, list) or not self.value:
            raise self.error(f"must be a non-empty list, got {_shown(self.value)}")
        return (self.child(i) for i in range(len(self.value)))


def listed(values: tuple[float, ...]) -> str:
    """Numbers as a short list for people, for example ``[0.38, 0.38]``.

    Parameters
    ----------
    values : tuple of float
        The numbers.

    Returns
    -------
    str
        Each in ``g`` format, in brackets.
    """
    return "[" + ", ".join(f"{v:g}" for v in values) + "]"


def _shown(value: Any) -> str:
    """A short text of ``value`` for a message."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def read_once(reader: Callable[[str], _Read], path: str | Path) -> _Read:
    """``reader(path)``, read again only when the file's size or modification time changes.

    A setup's recorded motions and delay traces are checked at every environment configured
    from it and drawn at every batch of scenarios; their files are read once.

    Parameters
    ----------
    reader : callable
        Reads the file (``RecordedMotion.from_csv``, ``TraceDelay.from_csv``).
    path : str or Path
        The file.

    Returns
    -------
    object
        What ``reader`` returns.
    """
    try:
        stat = Path(path).stat()
    except OSError:
        return reader(str(path))  # which names the problem in one line
    return _read(reader, str(path), stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=32)
def _read(reader: Callable[[str], Any], path: str, modified: int, size: int) -> Any:
    """``reader(path)``, cached by the reader and the file's path, modification time and size."""
    return reader(path)
