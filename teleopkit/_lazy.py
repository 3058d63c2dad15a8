"""Package namespaces whose names load their module on first use (PEP 562).

``import teleopkit`` and ``teleopkit --help`` must not pay for numba, torch, cvxpy or matplotlib;
the packages therefore map each public name to the module that defines it and import that module
only when the name is first looked up.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_namespace(package: str, namespace: dict[str, Any], exports: Mapping[str, str],
                   ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a package that exports names lazily.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    namespace : dict
        The package's ``globals()``, where a loaded name is cached.
    exports : mapping of str to str
        Each public name and the submodule (relative to ``package``) that defines it.

    Returns
    -------
    getattr, dir : callable
        Functions to assign to the package's ``__getattr__`` and ``__dir__``.
    """
    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{module}"), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *exports})

    return __getattr__, __dir__
